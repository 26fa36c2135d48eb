"""The reference tracer's own noise (mimarble.reference.noise): sum-of-ω form vs Perlin's lerp form."""

import math

import numpy as np
import pytest

import perlin64  # the tests' independently typed permutation (tests/perlin64.py)
from mimarble.reference import noise as rn

KNOWN = [
    ((3.14, 42.0, 7.0), 0.13691995878400012),
    ((-4.2, 10.0, 6.0), 0.14208000000000043),
    ((0.1, 0.1, 0.1), 0.1861607143544832),
    ((0.5, 0.5, 0.5), -0.25),
]


# --- Perlin's ImprovedNoise.java (2002), transcribed as scalar float64 Python -------------
_p = [int(v) for v in perlin64.P] * 2


def _fade(t):
    return t * t * t * (t * (t * 6 - 15) + 10)


def _lerp(t, a, b):
    return a + t * (b - a)


def _grad(h, x, y, z):
    h &= 15
    u = x if h < 8 else y
    v = y if h < 4 else (x if h in (12, 14) else z)
    return (u if (h & 1) == 0 else -u) + (v if (h & 2) == 0 else -v)


def lerp_noise(x, y, z):
    fx, fy, fz = math.floor(x), math.floor(y), math.floor(z)
    X, Y, Z = int(fx) & 255, int(fy) & 255, int(fz) & 255
    x, y, z = x - fx, y - fy, z - fz
    u, v, w = _fade(x), _fade(y), _fade(z)
    p = _p
    A = p[X] + Y; AA = p[A] + Z; AB = p[A + 1] + Z          # noqa: E702
    B = p[X + 1] + Y; BA = p[B] + Z; BB = p[B + 1] + Z      # noqa: E702
    return _lerp(w, _lerp(v, _lerp(u, _grad(p[AA], x, y, z), _grad(p[BA], x - 1, y, z)),
                             _lerp(u, _grad(p[AB], x, y - 1, z), _grad(p[BB], x - 1, y - 1, z))),
                    _lerp(v, _lerp(u, _grad(p[AA + 1], x, y, z - 1), _grad(p[BA + 1], x - 1, y, z - 1)),
                             _lerp(u, _grad(p[AB + 1], x, y - 1, z - 1), _grad(p[BB + 1], x - 1, y - 1, z - 1))))
# -------------------------------------------------------------------------------------------


def test_permutation_is_a_permutation_of_0_255():
    assert sorted(rn.P.tolist()) == list(range(256))
    assert rn.P[:6].tolist() == [151, 160, 137, 91, 90, 15]


def test_permutation_matches_independently_typed_copy():
    np.testing.assert_array_equal(rn.P, perlin64.P)


def test_gradients_are_perlins_grad_function_in_hash_order():
    for h in range(16):
        for d in [(0.3, -0.7, 1.9), (1.0, 2.0, 3.0)]:
            assert rn.G[h] @ np.array(d) == _grad(h, *d)


@pytest.mark.parametrize("point,expected", KNOWN)
def test_known_answers(point, expected):
    assert abs(float(rn.noise(*point)) - expected) < 1e-12
    assert abs(lerp_noise(*point) - expected) < 1e-12     # the transcription itself


@pytest.mark.parametrize("point", [(0, 0, 0), (1, 2, 3), (-5, -17, 300), (-1, 0, 255),
                                   (1e20, -1e20, 3), (2.0**60, -7, 2.0**53 + 2), (1e300, 1e300, -1e300)])
def test_zero_at_lattice_points(point):
    assert float(rn.noise(*point)) == 0.0


def test_sum_of_omega_equals_lerp_form():
    rng = np.random.default_rng(20041216)
    pts = np.concatenate([
        rng.uniform(-4, 4, (1500, 3)),
        rng.uniform(-1000, 1000, (1500, 3)),
        rng.integers(-300, 300, (500, 3)) + rng.choice([0.0, 0.5, 0.25, 1e-9], (500, 3)),
    ])
    ours = rn.noise3(pts)
    theirs = np.array([lerp_noise(*p) for p in pts])
    assert np.max(np.abs(ours - theirs)) < 1e-12
    assert np.std(theirs) > 0.1        # the comparison is not vacuous


def test_huge_coordinates_hash_exactly():
    # 2^40 + frac: the lattice coordinate reduced mod 256 exactly, so the value is
    # the same as at the congruent small coordinate (2^40 ≡ 0 mod 256).
    big = 2.0**40
    for f in [(0.25, 0.5, 0.75), (0.125, 0.875, 0.3)]:  # x fractions exact at 2^40
        small = float(rn.noise(3 + f[0], 7 + f[1], -2 + f[2]))
        for b in (big, -big):
            assert float(rn.noise(b + 3 + f[0], 7 + f[1], -2 + f[2])) == pytest.approx(small, abs=1e-15)
            assert abs(lerp_noise(b + 3 + f[0], 7 + f[1], -2 + f[2]) - small) < 1e-15


def test_bounded_by_1_0364():
    rng = np.random.default_rng(7)
    vals = rn.noise3(rng.uniform(-50, 50, (200_000, 3)))
    assert np.all(np.abs(vals) <= rn.NOISE_BOUND)
    assert np.max(np.abs(vals)) > 0.8


def test_omega_is_the_fixed_quintic():
    t = np.array([0.0, 0.25, -0.5, 0.75, 1.0, -1.0, 1.5])
    a = np.abs(t)
    expected = np.where(a < 1, -6 * a**5 + 15 * a**4 - 10 * a**3 + 1, 0.0)
    np.testing.assert_allclose(rn.omega(t), expected, rtol=0, atol=1e-15)
    assert rn.omega(0.5) == 0.5


def test_fractal_is_the_octave_sum():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-3, 3, (300, 3))
    for K in (0, 1, 5, 12):
        expected = sum(rn.noise3(pts * 2.0**i) / 2.0**i for i in range(K)) if K else np.zeros(300)
        np.testing.assert_allclose(rn.fractal3(pts, K), expected, rtol=0, atol=1e-14)
        expected_t = sum(np.abs(rn.noise3(pts * 2.0**i)) / 2.0**i for i in range(K)) if K else np.zeros(300)
        np.testing.assert_allclose(rn.fractal3(pts, K, turbulence=True), expected_t, rtol=0, atol=1e-14)


def test_fractal_evaluates_all_64_octaves_finitely():
    pts = np.array([[0.3, 0.7, 1.1], [1e6 + 0.5, -3.25, 2.0]])
    f = rn.fractal3(pts, 64)
    assert np.all(np.isfinite(f))
    with pytest.raises(ValueError):
        rn.fractal3(pts, 65)
