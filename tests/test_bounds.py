"""Every gather in bounds, by construction, whatever the input (issue 11).

Dr.Jit's bounds checks (``JitFlag.Debug``) are switched on inside each test
here, so these run checked even in a plain ``./go test``; the conftest hook
(tests/jit_reports.py) catches any report, and so does ``stderr_reports`` below.
"""

import math

import numpy as np
import pytest

import mimarble
from jit_reports import stderr_reports

dr, mi = mimarble.dr, mimarble.mi
NAN, INF = math.nan, math.inf
BAD_POINTS = [(NAN, 0.3, 0.5), (INF, 0.5, 0.5), (0.5, -INF, 0.5), (0.5, 0.5, NAN)]


def test_an_out_of_bounds_gather_is_reported(llvm):
    """The detector itself: a planted out-of-bounds read is seen (and masked to 0)."""
    with dr.scoped_set_flag(dr.JitFlag.Debug, True), stderr_reports(dr, echo=False) as captured:
        values = dr.gather(mi.Float, mi.Float([1.0, 2.0, 3.0]), mi.UInt32([0, 2147483649]))
        dr.eval(values)
    assert list(values) == [1.0, 0.0]
    assert any("out-of-bounds read from position 2147483649" in r for r in captured.reports())


def eval_points(texture, points):
    if dr.is_jit_v(mi.Float):
        si = dr.zeros(mi.SurfaceInteraction3f, len(points))
        si.p = mi.Point3f(*(mi.Float([p[a] for p in points]) for a in range(3)))
        return np.array(texture.eval(si), dtype=np.float64).T.reshape(len(points), 3)
    rows = []
    for p in points:
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.p = mi.Point3f(*p)
        rows.append([float(c) for c in texture.eval(si)])
    return np.array(rows)


@pytest.mark.parametrize("function", ["abs_sine", "sine", "cosine"])
@pytest.mark.parametrize("count", [1, 2, 17])
def test_non_finite_points_give_nan_in_bounds_for_one_point_or_many(variant, function, count):
    """The NaN policy holds the same way in every variant, for one point or many."""
    texture = mi.load_dict({"type": "marble", "function": function, "octaves": 4})
    for bad in BAD_POINTS:
        points = [bad] + [(0.1 * k, 0.3, 0.5) for k in range(1, count)]
        with dr.scoped_set_flag(dr.JitFlag.Debug, True), \
                stderr_reports(dr, echo=False) as captured:
            colours = eval_points(texture, points)
        assert captured.reports() == []
        assert np.isnan(colours[0]).all(), (bad, colours[0])
        assert np.isfinite(colours[1:]).all()


@pytest.mark.parametrize("ramp", ["1 0 0, 0 1 0", "1 0 0, 0 1 0, 0 0 1, 1 1 1, 0 0 0"])
def test_ramp_index_stays_in_bounds_for_every_phase(jit_variant, ramp):
    """t outside [0, 1] or NaN cannot move the ramp index off the table."""
    texture = mi.load_dict({"type": "marble", "ramp": ramp})
    t = mi.Float([NAN, -INF, -1.0, -0.0, 0.0, 0.5, 1.0 - 2 ** -24, 1.0, 2.0, INF])
    with dr.scoped_set_flag(dr.JitFlag.Debug, True), stderr_reports(dr, echo=False) as captured:
        colours = np.array(texture.ramp(t), dtype=np.float64).T
    assert captured.reports() == []
    assert np.isnan(colours[0]).all()
    assert np.isfinite(colours[1:]).all()


@pytest.mark.parametrize("octaves", [1, 8])
def test_noise_lattice_index_stays_in_bounds_for_any_coordinate(jit_variant, octaves):
    coordinates = [NAN, INF, -INF, 3.0e38, -3.0e38, 2.0 ** 24 + 2, -(2.0 ** 31), 1e-45, -0.0, 255.999]
    points = np.array([(c, 0.5, -0.25) for c in coordinates] + [(0.5, c, c) for c in coordinates],
                      dtype=np.float32)
    with dr.scoped_set_flag(dr.JitFlag.Debug, True), stderr_reports(dr, echo=False) as captured:
        values = mimarble.texture.noise.fractal(points, octaves)
    assert captured.reports() == []
    finite = np.isfinite(points).all(axis=1)
    assert np.isnan(values[~finite]).all()
    assert np.isfinite(values[finite]).all()


def test_bounds_checked_renders_equal_plain_ones(tmp_path):
    """MIMARBLE_JIT_DEBUG=1 checks without changing the image.

    It would not on its own: Dr.Jit 1.5's check of packet scatters (Mitsuba's
    image block) drops good writes, hence packet ops off (environment.enable_bounds_checks).
    """
    import os
    import subprocess
    import sys
    scene = tmp_path / "small.scene"
    scene.write_text('image { width 24 height 16 samples 4 }\n'
                     'camera { eye < 0 0 5 > lookat < 0 0 0 > up < 0 1 0 > fov 30 }\n'
                     'light { position < 5 5 5 > color < 1 1 1 > }\n'
                     'material "m" { diffuse { marble { octaves 3 } } }\n'
                     'sphere { center < 0 0 0 > radius 1 material "m" }\n')
    code = ("import sys, numpy as np, mimarble; "
            f"np.save(sys.argv[1], mimarble.render({str(scene)!r}))")
    images = []
    for debug in ("0", "1"):
        out = tmp_path / f"image{debug}.npy"
        env = dict(os.environ, MIMARBLE_JIT_DEBUG=debug, MIMARBLE_VARIANT="llvm_ad_rgb")
        result = subprocess.run([sys.executable, "-c", code, str(out)], env=env,
                                capture_output=True, text=True, timeout=300)
        sys.stderr.write(result.stderr)
        assert result.returncode == 0, result.stderr
        images.append(np.load(out))
    assert images[0].mean() > 0.05
    np.testing.assert_allclose(images[1], images[0], atol=1e-6)
