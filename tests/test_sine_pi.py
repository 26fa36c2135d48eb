"""sin(πx) and cos(πx) of mimarble/texture/sine_pi.py against float64 NumPy: relative
error near their zeros as well as absolute error elsewhere (the prefilter's integrals
divide by intervals as short as float32 resolves)."""

import numpy as np
import pytest

import mimarble
from mimarble.texture import sine_pi

dr, mi = mimarble.dr, mimarble.mi


def arguments():
    rng = np.random.default_rng(11)
    tiny = 10.0 ** rng.uniform(-9, -1, 2000) * rng.choice([-1, 1], 2000)
    wide = rng.uniform(-4, 4, 4000)
    near_integers = np.round(wide) + tiny[:4000 // 2].repeat(2)[:4000]
    return np.concatenate([tiny, wide, near_integers, [0.0, 0.5, 1.0, -1.5, 2.0]]).astype(np.float32)


def exact(function, x):
    x64 = x.astype(np.float64)
    if function == "sin":
        # sin(πx) near integers n: (−1)^n sin(π(x − n)), exact reduction in float64
        n = np.round(x64)
        return np.where(n % 2 == 0, 1, -1) * np.sin(np.pi * (x64 - n))
    n = np.round(x64 - 0.5) + 0.5
    return np.where(np.round(n - 0.5) % 2 == 0, -1, 1) * np.sin(np.pi * (x64 - n))


def check(values, function, x, ulps, relative):
    """|error| ≤ ulps·ε·|exact| where ``relative`` (a mask), ≤ ulps·ε elsewhere."""
    expected = exact(function, x)
    error = np.abs(np.asarray(values, dtype=np.float64) - expected)
    scale = np.where(relative, np.maximum(np.abs(expected), 2.0 ** -126), 1.0)
    bound = ulps * np.finfo(np.float32).eps * scale
    worst = np.argmax(error / bound)
    assert (error <= bound).all(), (function, float(x[worst]), float(expected[worst]),
                                    float(np.asarray(values)[worst]))


def distance_to_integer(x):
    return np.abs(x.astype(np.float64) - np.round(x.astype(np.float64)))


def test_the_sine_series_has_a_small_relative_error_everywhere(jit_variant):
    x = arguments()
    check(sine_pi.sin_pi_series(mi.Float(x)), "sin", x, ulps=8, relative=True)


def test_the_cosine_series_is_relatively_exact_off_its_zeros_and_absolutely_near_them(
        jit_variant):
    x = arguments()
    check(sine_pi.cos_pi_series(mi.Float(x)), "cos", x, ulps=8,
          relative=distance_to_integer(x) <= 0.25)


def test_the_sine_the_texture_uses_is_relatively_exact_near_zero_on_every_backend(
        jit_variant):
    """Near 0 (the half-interval sines of the prefilter's integrals) relatively; elsewhere
    to a few ulp absolutely. A GPU's sin.approx (absolute error ~2⁻²¹) fails near 0."""
    x = arguments()
    check(sine_pi.sin_pi(mi.Float(x)), "sin", x, ulps=8, relative=np.abs(x) <= 0.25)


def test_the_cosine_the_texture_uses_is_absolutely_exact_on_every_backend(jit_variant):
    x = arguments()
    check(sine_pi.cos_pi(mi.Float(x)), "cos", x, ulps=8, relative=False)


def test_arguments_without_a_fraction_have_the_sign_of_their_parity(jit_variant):
    """Every float32 past 2²⁴ is an even integer: sin(πx) = 0, cos(πx) = 1, up to the
    largest float32 (an int32 parity would saturate on a GPU past 2³¹ and say odd)."""
    x = [2.0 ** 23 + 1, 2.0 ** 24 - 1, 2.0 ** 24, 2.0 ** 31 - 128, 2.0 ** 31, 3e9, -3e9,
         1e30, -1e30, float(np.finfo(np.float32).max)]
    x32 = np.array(x, dtype=np.float32)
    parity = [int(v) % 2 for v in x32.astype(np.float64)]      # exact, in Python integers
    assert parity[:2] == [1, 1] and not any(parity[2:])
    cosine = np.asarray(sine_pi.cos_pi_series(mi.Float(x32)))
    sine = np.asarray(sine_pi.sin_pi_series(mi.Float(x32)))
    np.testing.assert_array_equal(cosine, [(-1.0) ** p for p in parity])
    np.testing.assert_array_equal(np.abs(sine), 0.0)
