"""mimarble.texture.noise against Perlin's published algorithm and an independent float64 form."""

import numpy as np
import pytest

import mimarble
from mimarble.texture import noise
import perlin64

dr, mi = mimarble.dr, mimarble.mi

KNOWN = [  # float64 values of Perlin's reference implementation (docs/design.md)
    ((3.14, 42, 7), 0.13691995878400012),
    ((-4.2, 10, 6), 0.14208000000000043),
    ((0.1, 0.1, 0.1), 0.1861607143544832),
    ((0.5, 0.5, 0.5), -0.25),
]

# Float32 error of the lerp form, measured against float64: each of the seven
# lerps a + t(b − a) works on values up to 2 in magnitude and cancels, costing up
# to ~1.5 ulp(2) = 3.6e-7 per level; with the gradient sums the worst seen in
# 10^6 points is 1.9e-6. 4e-6 (about 17 ulp of 2) bounds it with margin; a wrong
# hash, gradient or fade shows up as errors of 1e-2 and more.
FLOAT32_NOISE_TOL = 4e-6


def random_points(n, lo, hi, seed=0):
    return np.random.default_rng(seed).uniform(lo, hi, (n, 3)).astype(np.float32)


def scalar_noise(points, fn):
    return np.array([fn(dr.scalar.Array3f(*map(float, p))) for p in points])


def test_permutation_is_perlins_table_of_all_256_bytes():
    assert sorted(noise.PERMUTATION) == list(range(256))
    assert noise.PERMUTATION == tuple(int(x) for x in perlin64.P)


@pytest.mark.parametrize("point, expected", KNOWN)
def test_known_answers(variant, point, expected):
    if variant.startswith("scalar"):
        value = scalar_noise([point], noise.noise3)[0]
    else:
        value = noise.perlin(np.array([point]))[0]
    assert abs(value - expected) <= 1e-6


def test_bit_identical_to_published_algorithm_in_float32(jit_variant):
    pts = np.concatenate([random_points(50_000, -3, 3), random_points(50_000, -1e4, 1e4, 1)])
    ours = noise.perlin(pts)
    published = perlin64.noise_float32_lerp_form(pts)
    if jit_variant.startswith("llvm"):
        np.testing.assert_array_equal(ours, published)
    else:
        # On a GPU ptxas fuses a multiply and an add into one FMA (Dr.Jit emits mul.ftz,
        # not mul.rn), rounding once where the published algorithm rounds twice: the
        # values differ from it by more than an ulp (seen on an H200), so
        # each is held to the exact noise instead — no farther from it than the
        # published float32 algorithm gets anywhere.
        exact = perlin64.noise(pts.astype(np.float64))
        assert np.abs(ours - exact).max() <= np.abs(published - exact).max()


@pytest.mark.parametrize("lo, hi", [(-2, 2), (-300, 300), (-1e5, 1e5)])
def test_agrees_with_float64_sum_of_omega_form(jit_variant, lo, hi):
    pts = random_points(40_000, lo, hi, seed=int(hi))
    error = np.abs(noise.perlin(pts) - perlin64.noise(pts.astype(np.float64)))
    assert error.max() <= FLOAT32_NOISE_TOL


def test_scalar_variant_computes_in_double_and_agrees_to_1e12(variant):
    if not variant.startswith("scalar"):
        pytest.skip("scalar variant only")
    pts = random_points(300, -50, 50)
    error = np.abs(scalar_noise(pts, noise.noise3) - perlin64.noise(pts.astype(np.float64)))
    assert error.max() <= 1e-12


def test_zero_at_every_lattice_point(jit_variant):
    rng = np.random.default_rng(3)
    pts = np.concatenate([
        rng.integers(-10**6, 10**6, (5000, 3)),
        [[0, 0, 0], [-1, -1, -1], [255, 256, 257], [2**30, -2**31, 2**24]],
    ]).astype(np.float32)
    pts = np.concatenate([pts, np.float32([[1e20, -1e20, 3e38], [-3e38, 1e30, 2**100]])])
    assert np.all(noise.perlin(pts) == 0.0)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_continuous_across_cell_borders(jit_variant, axis):
    rng = np.random.default_rng(4)
    base = rng.uniform(-100, 100, (20_000, 3))
    base[:, axis] = rng.integers(-100, 100, 20_000)       # on a cell border
    eps = 1e-3
    below, above = base.copy(), base.copy()
    below[:, axis] -= eps
    above[:, axis] += eps
    jump = np.abs(noise.perlin(above) - noise.perlin(below))
    # |∂N/∂x| stays below ~3 (gradients of length √2, fade slope ≤ 1.875): a
    # continuous function moves at most ~6e-3 over 2·eps; a wrong corner jumps by ~0.1+.
    assert jump.max() < 6 * eps + FLOAT32_NOISE_TOL


def test_range_within_theoretical_bound(jit_variant):
    values = noise.perlin(random_points(1_000_000, -64, 64, seed=5))
    assert np.abs(values).max() <= noise.NOISE_BOUND
    assert np.abs(values).max() > 0.8          # and the test points do reach the tails


@pytest.mark.parametrize("octaves", [1, 2, 8, 12, 24, 32, 64])
@pytest.mark.parametrize("turbulence", [False, True])
def test_fractal_agrees_with_float64_sum(jit_variant, octaves, turbulence):
    pts = random_points(20_000, -20, 20, seed=octaves)
    ours = noise.fractal(pts, octaves, turbulence)
    ref = perlin64.fractal(pts.astype(np.float64), octaves, turbulence)
    # Σ 2^-i · (per-octave float32 error) ≤ 2 · FLOAT32_NOISE_TOL, plus the skipped tail.
    tol = 2 * FLOAT32_NOISE_TOL + noise.SKIPPED_OCTAVES_BOUND + 2e-7 * octaves
    assert np.abs(ours - ref).max() <= tol


def test_octaves_past_float32_resolution_are_skipped_within_the_stated_bound(jit_variant):
    pts = random_points(20_000, -20, 20, seed=7)
    f25 = noise.fractal(pts, 25)
    for octaves in (26, 32, 64):
        np.testing.assert_array_equal(noise.fractal(pts, octaves), f25)
    # The bound itself, checked in float64 where nothing is skipped.
    tail = perlin64.fractal(pts.astype(np.float64), 40) - perlin64.fractal(pts.astype(np.float64), 25)
    assert np.abs(tail).max() <= noise.SKIPPED_OCTAVES_BOUND
    assert noise.octaves_evaluated(64) == noise.MAX_OCTAVES_EVALUATED


EXTREME = np.float32([
    [1e-30, -1e-30, 1e-38], [1e-45, -1e-45, 0.0], [1e20, -1e20, 1e19],
    [3.4e38, -3.4e38, 1.0], [2**24 + 2, -(2**24) - 2, 0.5], [12345.678, -9876.5, 1e7],
    [-0.5, 1e-7, -1e-7], [np.finfo(np.float32).max, np.finfo(np.float32).tiny, -1.0],
])


@pytest.mark.parametrize("octaves", [0, 1, 8, 25, 31, 32, 63, 64])
def test_finite_and_bounded_for_extreme_finite_inputs(jit_variant, octaves):
    values = noise.fractal(EXTREME, octaves)
    assert np.all(np.isfinite(values))
    assert np.all(np.abs(values) <= 2 * noise.NOISE_BOUND)


@pytest.mark.parametrize("octaves", [8, 64])
def test_huge_coordinates_wrap_exactly_like_float64(jit_variant, octaves):
    rng = np.random.default_rng(8)
    mags = 10.0 ** rng.uniform(6, 30, (2000, 3))
    pts = (mags * rng.choice([-1, 1], (2000, 3))).astype(np.float32)
    ours = noise.fractal(pts, octaves)
    ref = perlin64.fractal(pts.astype(np.float64), octaves)
    assert np.abs(ours - ref).max() <= 2 * FLOAT32_NOISE_TOL + noise.SKIPPED_OCTAVES_BOUND


def test_non_finite_input_gives_nan_not_an_error(jit_variant):
    pts = np.float32([[np.nan, 0, 0], [np.inf, 1, 2], [0.5, -np.inf, 0.1], [0.3, 0.2, 0.1]])
    for values in (noise.perlin(pts), noise.fractal(pts, 8)):
        assert np.all(np.isnan(values[:3]))
        assert np.isfinite(values[3])


def test_numpy_entry_points_check_their_arguments():
    with pytest.raises(ValueError, match="shape"):
        noise.perlin(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="octaves"):
        noise.fractal(np.zeros((4, 3)), 65)
    with pytest.raises(ValueError, match="octaves"):
        noise.fractal(np.zeros((4, 3)), -1)


def test_scalar_variant_fractal_agrees_with_float64(variant):
    if not variant.startswith("scalar"):
        pytest.skip("scalar variant only")
    pts = random_points(100, -10, 10, seed=9)
    ours = scalar_noise(pts, lambda p: noise.fractal3(p, 12))
    assert np.abs(ours - perlin64.fractal(pts.astype(np.float64), 12)).max() <= 1e-12
