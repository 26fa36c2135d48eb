"""The error budget (issue 12): octaves no output can show are skipped, within a proven bound.

The bound is checked against the float64 reference tracer's full sum
(``mimarble.reference.marble``), never against the code under test.
"""

import dataclasses
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import mimarble
from mimarble.texture import error_budget
from mimarble.tools import stress
from mimarble.texture.stripes import STRIPES
from mimarble.texture.noise import MAX_OCTAVES_EVALUATED
from mimarble.reference import marble as reference_marble
from mimarble.scene import MarbleChannel

mi = mimarble.mi
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FUNCTIONS = ("abs_sine", "sine", "cosine")


def random_ramp(n, seed):
    return tuple(map(tuple, np.random.default_rng(seed).uniform(0, 1, (n, 3))))


def points(n=4096, magnitude=3.0, seed=3):
    return np.random.default_rng(seed).uniform(-magnitude, magnitude, (n, 3))


@pytest.mark.parametrize("function", FUNCTIONS)
@pytest.mark.parametrize("colours", [1, 2, 8, 256])
@pytest.mark.parametrize("distortion", [0.5, -3.0, 40.0, 1e4])
@pytest.mark.parametrize("turbulence", [False, True])
@pytest.mark.parametrize("tolerance", [1e-2, 1e-4])
def test_the_leading_octaves_are_within_the_tolerance_of_the_full_sum(
        function, colours, distortion, turbulence, tolerance):
    """In float64, no float32 involved: the reference's colour with the octaves the
    budget keeps against the reference's colour with every octave float32 could add."""
    channel = MarbleChannel(octaves=MAX_OCTAVES_EVALUATED, distortion=distortion, period=1.3,
                            function=function, turbulence=turbulence,
                            ramp=random_ramp(colours, seed=colours))
    k = error_budget.octaves_needed(tolerance, channel.octaves, distortion, channel.ramp, function)
    p = points()
    full = reference_marble.marble_color(p, channel)
    cut = reference_marble.marble_color(p, dataclasses.replace(channel, octaves=k))
    assert np.abs(cut - full).max() <= tolerance * (1 + 1e-9)
    if colours in (2, 8) and abs(distortion) <= 3.0:
        assert k < MAX_OCTAVES_EVALUATED     # the budget does skip octaves here


@pytest.mark.parametrize("function", FUNCTIONS)
@pytest.mark.parametrize("octaves", [8, 12, 32])
@pytest.mark.parametrize("tolerance", [0.0, error_budget.DEFAULT_TOLERANCE, 1e-3, 3e-2])
def test_the_texture_is_within_tolerance_and_float32_of_the_float64_full_sum(
        function, octaves, tolerance):
    """The ``marble`` texture (float32, Dr.Jit) at its tolerance, against the float64
    reference with all ``octaves``: within the tolerance, plus float32's own proven
    error (docs/numerical-stability.md), plus what octaves past 25 can add."""
    channel = dataclasses.replace(stress.PAPER_MARBLE, octaves=octaves, function=function)
    r = stress.tolerance_error(channel, tolerance, points=1 << 14)
    assert r["max_error"] <= r["tolerance"] + r["float32_bound"] + r["skipped_bound"]
    expected = error_budget.octaves_needed(tolerance, octaves, channel.distortion, channel.ramp,
                                           function)
    assert r["octaves_evaluated"] == expected


def test_a_larger_tolerance_never_keeps_more_octaves():
    ramp = random_ramp(8, 1)
    counts = [error_budget.octaves_needed(t, 32, 3.0, ramp, "abs_sine")
              for t in (0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0, 1e4)]
    assert counts == sorted(counts, reverse=True)
    assert counts[0] == MAX_OCTAVES_EVALUATED and counts[-1] == 0


@pytest.mark.parametrize("colours, distortion", [(((0.3, 0.2, 0.1),), 3.0),
                                                 (random_ramp(8, 2), 0.0),
                                                 (((0.5, 0.5, 0.5),) * 4, 5.0)])
def test_what_cannot_change_the_colour_needs_no_octave(colours, distortion):
    """A constant (or flat) ramp, or no distortion: no octave can move the colour."""
    assert error_budget.octaves_needed(1e-9, 32, distortion, colours, "abs_sine") == 0


def test_the_slope_of_each_function_is_its_largest():
    """|dt/dφ| ≤ S: measured by finite differences on the reference stripe in float64."""
    phase = np.linspace(-3, 3, 200_001)
    for function, t in (("abs_sine", np.abs(np.sin(np.pi * phase))),
                        ("sine", 0.5 * (np.sin(phase) + 1)),
                        ("cosine", 0.5 * (np.cos(phase) + 1))):
        slope = np.abs(np.diff(t)).max() / (phase[1] - phase[0])
        assert slope <= STRIPES[function].slope_bound * (1 + 1e-6)
        assert slope >= STRIPES[function].slope_bound * (1 - 1e-3)


def test_the_default_is_half_an_srgb_code_value_at_black():
    """½ code value of 8-bit sRGB before quantisation, where the curve is steepest."""
    def srgb(x):
        return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.maximum(x, 0.0031308),
                                                                     1 / 2.4) - 0.055)
    x = np.linspace(0, 1, 1_000_001)
    moved = np.abs(srgb(x + error_budget.HALF_CODE_VALUE) - srgb(x)).max() * 255
    assert 0.499 <= moved <= 0.5 + 1e-9


def test_a_scene_divides_the_default_by_its_lighting():
    scene = mimarble.scene.load(os.path.join(ROOT, "scenes", "fig11b.scene"))
    light = max(scene.ambient) + sum(max(l.color) for l in scene.lights)
    d = mimarble.to_mitsuba(scene)
    marbles = [v for v in d.values() if isinstance(v, dict) and v.get("type") == "marble"]
    assert marbles and all(m["tolerance"] == pytest.approx(error_budget.HALF_CODE_VALUE / light)
                           for m in marbles)
    assert all(m["tolerance"] == 0.0 for m in mimarble.to_mitsuba(scene, tolerance=0.0).values()
               if isinstance(m, dict) and m.get("type") == "marble")


def test_the_scene_language_takes_a_tolerance(tmp_path):
    text = 'material "m" { diffuse { marble { octaves 32 tolerance 0.001 } } }\n' \
           'sphere { material "m" }\n'
    scene = mimarble.scene.parse(text)
    (channel,) = scene.materials["m"].channels().values()
    assert channel.tolerance == 0.001
    (marble,) = [v for v in mimarble.to_mitsuba(scene).values()
                 if isinstance(v, dict) and v.get("type") == "marble"]
    assert marble["tolerance"] == 0.001
    with pytest.raises(mimarble.scene.SceneError, match=r":1:56: tolerance must be ≥ 0"):
        mimarble.scene.parse(text.replace("0.001", "-1"))


def test_the_plugin_counts_octaves_from_its_parameters():
    tex = mi.load_dict({"type": "marble", "octaves": 32, "distortion": 3.0})
    assert tex.octaves_evaluated == error_budget.octaves_needed(
        error_budget.DEFAULT_TOLERANCE, 32, 3.0, mimarble.scene.model.FIG5_RAMP, "abs_sine") < 25
    params = mi.traverse(tex)
    params["distortion"] = 300.0
    params.update()
    assert tex.octaves_evaluated > error_budget.octaves_needed(
        error_budget.DEFAULT_TOLERANCE, 32, 3.0, mimarble.scene.model.FIG5_RAMP, "abs_sine")
    assert mi.load_dict({"type": "marble", "octaves": 32, "tolerance": 0.0}).octaves_evaluated == 25
    with pytest.raises(Exception, match="tolerance must be ≥ 0, found -1.0"):
        mi.load_dict({"type": "marble", "tolerance": -1.0})


def test_the_budget_evaluates_exactly_the_octaves_it_keeps(llvm):
    """A tolerance that keeps k of 32 octaves gives, bit for bit, the colour of a marble of
    k octaves: the rest are not evaluated (the octave loop runs k times)."""
    dr = mimarble.dr
    si = dr.zeros(mi.SurfaceInteraction3f, 256)
    si.p = mi.Point3f(dr.linspace(mi.Float, -2, 2, 256), 0.5, 0.25)
    for tolerance in (1e-2, error_budget.DEFAULT_TOLERANCE):
        tex = mi.load_dict({"type": "marble", "octaves": 32, "distortion": 3.0,
                            "tolerance": tolerance})
        kept = tex.octaves_evaluated
        assert 0 < kept < 25
        alone = mi.load_dict({"type": "marble", "octaves": kept, "distortion": 3.0,
                              "tolerance": 0.0})
        assert np.array_equal(np.array(tex.eval(si)), np.array(alone.eval(si)))
        everything = mi.load_dict({"type": "marble", "octaves": kept + 1, "distortion": 3.0,
                                   "tolerance": 0.0})
        assert not np.array_equal(np.array(tex.eval(si)), np.array(everything.eval(si)))


def test_the_command_line_takes_a_tolerance(tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [ROOT, os.environ.get("PYTHONPATH")])))

    def run(*args):
        return subprocess.run([sys.executable, "-m", "mimarble", *map(str, args)], cwd=ROOT,
                              env=env, capture_output=True, text=True, timeout=300)
    out = tmp_path / "a.exr"
    assert run("render", "scenes/fig11b.scene", "--width", "24", "--height", "24", "--spp", "1",
               "--tolerance", "0", "-o", out).returncode == 0
    bad = run("render", "scenes/fig11b.scene", "--tolerance", "-1", "-o", tmp_path / "b.png")
    assert bad.returncode == 2 and "--tolerance" in bad.stderr and "≥ 0" in bad.stderr
    assert not (tmp_path / "b.png").exists()
    assert math.isfinite(float(np.array(mi.Bitmap(str(out))).mean()))


def test_expression_gain_is_what_an_expression_can_multiply_a_marble_error_by():
    from mimarble import scene as S
    marble = S.MarbleChannel()                                  # Fig. 5 ramp: bound 1
    other = S.MarbleChannel(octaves=3, ramp=((0, 0, 0), (0.5, 0.5, 0.5)))
    half = S.ColorChannel((0.5, 0.25, 0.1))
    assert error_budget.expression_gain(marble) == 1.0
    assert error_budget.expression_gain(S.Multiply((half, marble))) == 0.5
    assert error_budget.expression_gain(S.Add((marble, marble))) == 2.0
    assert error_budget.marble_gains(S.Multiply((marble, other))) == {marble: 0.5, other: 1.0}
    # mix: a by |1 − w|, b by |w|, the weight's error by max(a, b).
    assert error_budget.marble_gains(S.Mix(marble, half, 0.25)) == {marble: 0.75}
    assert error_budget.marble_gains(S.Mix(half, half, other)) == {other: 0.5}


def test_a_marble_in_an_expression_gets_the_scene_budget_over_the_gain():
    from mimarble import scene as S
    from mimarble.mitsuba.translate.scene_dict import to_mitsuba
    marble = S.MarbleChannel()
    scene = S.Scene(lights=(S.Light((5, 5, 5)),), spheres=(S.Sphere("m"),),
                    materials={"m": S.Material("m", diffuse=S.Add((marble, marble)))})
    alone = S.Scene(lights=(S.Light((5, 5, 5)),), spheres=(S.Sphere("m"),),
                    materials={"m": S.Material("m", diffuse=marble)})
    tolerance = [v["tolerance"] for v in to_mitsuba(scene).values()
                 if isinstance(v, dict) and v.get("type") == "marble"]
    single = [v["tolerance"] for v in to_mitsuba(alone).values()
              if isinstance(v, dict) and v.get("type") == "marble"]
    assert len(tolerance) == 1 and tolerance[0] == pytest.approx(single[0] / 2)
