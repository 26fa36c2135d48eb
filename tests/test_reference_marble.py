"""The reference tracer's own marble (mimarble.reference.marble) against the formulas written out."""

import math

import numpy as np
import pytest

from mimarble.reference import marble as rm
from mimarble.reference import noise as rn
from mimarble.scene import FIG5_RAMP, MarbleChannel

PTS = np.array([[0.3, -1.2, 0.7], [1.7, 0.25, -0.4], [-0.9, 0.55, 1.3], [0.0, 0.0, 2.0]])


def F(v, octaves, turbulence=False):
    """Fractal3 written out point by point with the scalar noise."""
    out = []
    for x, y, z in v:
        s = 0.0
        for i in range(octaves):
            n = float(rn.noise(x * 2**i, y * 2**i, z * 2**i))
            s += (abs(n) if turbulence else n) / 2**i
        out.append(s)
    return np.array(out)


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_abs_sine_without_distortion_is_exact_stripes(axis):
    a = "xyz".index(axis)
    m = MarbleChannel(scale=1.7, period=2.3, distortion=0.0, octaves=12, axis=axis)
    t = rm.stripe(PTS, m)
    np.testing.assert_array_equal(t, np.abs(np.sin(np.pi * (2.3 * (PTS[:, a] * 1.7)))))


@pytest.mark.parametrize("axis", ["x", "y", "z"])
@pytest.mark.parametrize("function", ["abs_sine", "sine", "cosine"])
@pytest.mark.parametrize("turbulence", [False, True])
def test_functions_match_direct_formulas(function, axis, turbulence):
    a = "xyz".index(axis)
    scale, period, distortion, octaves = 1.3, 1.6, 2.5, 6
    m = MarbleChannel(scale=scale, period=period, distortion=distortion, octaves=octaves,
                      function=function, axis=axis, turbulence=turbulence)
    v = PTS * scale
    phase = distortion * F(v, octaves, turbulence)
    if function == "abs_sine":
        expected = [abs(math.sin(math.pi * (period * v[k, a] + phase[k]))) for k in range(len(v))]
    elif function == "sine":
        expected = [0.5 * (math.sin(period * v[k, a] + phase[k]) + 1) for k in range(len(v))]
    else:   # cosine: period unused
        expected = [0.5 * (math.cos(v[k, a] + phase[k]) + 1) for k in range(len(v))]
    np.testing.assert_allclose(rm.stripe(PTS, m), expected, rtol=0, atol=1e-12)


def test_cosine_ignores_period():
    m1 = MarbleChannel(function="cosine", period=1.0, distortion=0.7)
    m2 = MarbleChannel(function="cosine", period=17.0, distortion=0.7)
    np.testing.assert_array_equal(rm.stripe(PTS, m1), rm.stripe(PTS, m2))


def test_distortion_zero_skips_noise(monkeypatch):
    def boom(*a, **k):
        raise AssertionError("noise evaluated with distortion 0")
    monkeypatch.setattr(rm, "fractal", boom)
    rm.stripe(PTS, MarbleChannel(distortion=0.0))
    with pytest.raises(AssertionError):
        rm.stripe(PTS, MarbleChannel(distortion=1.0))


def test_ramp_keys_and_linear_interpolation():
    c = ((0.0, 0.0, 0.0), (1.0, 0.5, 0.0), (0.0, 1.0, 3.0))     # keys 0, 0.5, 1
    t = np.array([0.0, 0.5, 1.0, 0.25, 0.75, -0.3, 1.7])
    expected = np.array([
        c[0], c[1], c[2],
        [0.5, 0.25, 0.0],            # halfway between c0 and c1
        [0.5, 0.75, 1.5],            # halfway between c1 and c2
        c[0], c[2],                  # clamped
    ])
    np.testing.assert_allclose(rm.ramp(t, c), expected, rtol=0, atol=1e-15)


def test_fig5_ramp_at_known_t():
    # 8 colours at keys k/7: t = 3/7 -> colour 3 = <1 0.375 0>; t = 1 -> <1 0.875 0>
    out = rm.ramp(np.array([3 / 7, 1.0, 0.0, 0.5 / 7]), FIG5_RAMP)
    np.testing.assert_allclose(out, [[1, 0.375, 0], [1, 0.875, 0], [1, 0, 0], [1, 0.0625, 0]],
                               rtol=0, atol=1e-14)


def test_single_colour_ramp_is_constant():
    out = rm.ramp(np.array([0.0, 0.3, 2.0]), ((0.2, 0.4, 0.6),))
    np.testing.assert_array_equal(out, np.tile([0.2, 0.4, 0.6], (3, 1)))


def test_marble_color_is_ramp_of_stripe():
    m = MarbleChannel(scale=1.0, period=1.3, distortion=3.0, octaves=12)
    t = rm.stripe(PTS, m)
    np.testing.assert_array_equal(rm.marble_color(PTS, m), rm.ramp(t, FIG5_RAMP))
    assert np.all((t >= 0) & (t <= 1))
