"""Exact noise gradients (issue 13): against central differences in float64, and Dr.Jit
against the independent float64 reference (written from the ω-kernel form of the noise)."""

import numpy as np
import pytest

import mimarble
from mimarble.texture import noise
from mimarble.reference import noise as reference_noise
from mimarble.reference import noise_gradient as reference_gradient

dr, mi = mimarble.dr, mimarble.mi


def random_points(n=4000, magnitude=6.0, seed=11):
    return np.random.default_rng(seed).uniform(-magnitude, magnitude, (n, 3))


def central_difference(f, pts, h=1e-6):
    """∇f by central differences in float64, f: (N, 3) -> (N,)."""
    out = np.empty_like(pts)
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = h
        out[:, axis] = (f(pts + step) - f(pts - step)) / (2 * h)
    return out


def off_the_lattice(pts, margin=1e-4, octaves=1):
    """Points whose scaled coordinates stay ``margin`` away from integer planes, where
    the noise is C² but a difference quotient straddles cells (the gradient is exact
    there too; this keeps the finite-difference check clean)."""
    keep = np.ones(len(pts), bool)
    for i in range(octaves):
        frac = np.abs((pts * 2.0 ** i) - np.round(pts * 2.0 ** i))
        keep &= (frac > margin * 2.0 ** i).all(axis=1)
    return pts[keep]


def test_reference_noise_gradient_matches_central_differences():
    pts = off_the_lattice(random_points())
    analytic = reference_gradient.noise_gradient(pts[:, 0], pts[:, 1], pts[:, 2])
    numeric = central_difference(reference_noise.noise3, pts)
    assert np.abs(analytic - numeric).max() < 1e-7


@pytest.mark.parametrize("turbulence", [False, True])
def test_reference_fractal_gradient_matches_central_differences(turbulence):
    pts = off_the_lattice(random_points(2000, 3.0), octaves=8)
    analytic = reference_gradient.fractal_gradient(pts, 8, turbulence)
    numeric = central_difference(lambda q: reference_noise.fractal3(q, 8, turbulence), pts, 1e-7)
    if turbulence:   # |N| has a kink where N = 0: leave out points whose octaves come near it
        near_zero = np.zeros(len(pts), bool)
        for i in range(8):
            near_zero |= np.abs(reference_noise.noise3(pts * 2.0 ** i)) < 1e-4
        analytic, numeric = analytic[~near_zero], numeric[~near_zero]
    assert np.abs(analytic - numeric).max() < 1e-5


def float64_drjit(pts):
    return dr.llvm.ad.Array3f64(*(dr.llvm.ad.Float64(np.ascontiguousarray(pts[:, a])) for a in range(3)))


def float32_drjit(pts):
    return mi.Point3f(*(mi.Float(np.ascontiguousarray(pts[:, a], dtype=np.float32)) for a in range(3)))


def test_drjit_noise_gradient_in_float64_is_the_reference(llvm):
    pts = random_points()
    value, gradient = noise.noise3_gradient(float64_drjit(pts))
    expected = reference_gradient.noise_gradient(pts[:, 0], pts[:, 1], pts[:, 2])
    assert np.abs(np.array(gradient).T - expected).max() < 1e-12
    assert np.abs(np.array(value) - reference_noise.noise3(pts)).max() < 1e-12


def test_drjit_noise_value_is_noise3_bit_for_bit(llvm):
    p = float32_drjit(random_points())
    value, _ = noise.noise3_gradient(p)
    assert np.array_equal(np.array(value), np.array(noise.noise3(p)))


@pytest.mark.parametrize("octaves", [1, 8, 32])
@pytest.mark.parametrize("turbulence", [False, True])
def test_drjit_fractal_gradient_in_float32_is_near_the_reference(llvm, octaves, turbulence):
    pts = random_points(4000, 3.0).astype(np.float32).astype(np.float64)
    value, gradient = noise.fractal_gradient(float32_drjit(pts), octaves, turbulence)[:2]
    assert np.array_equal(np.array(value), np.array(noise.fractal3(float32_drjit(pts), octaves,
                                                                   turbulence)))
    evaluated = noise.octaves_evaluated(octaves)
    expected = reference_gradient.fractal_gradient(pts, evaluated, turbulence)
    error = np.abs(np.array(gradient).T - expected)
    if turbulence:   # sign(N) may differ where float32's N rounds across 0
        agree = np.ones(len(pts), bool)
        for i in range(evaluated):
            agree &= np.abs(reference_noise.noise3(pts * 2.0 ** i)) > 1e-5
        error = error[agree]
    # The float32 points scale exactly by 2^i and their cell fractions are exact, so
    # only float32 arithmetic remains: measured ≤ 7e-6 at 1 to 25 octaves (|∇F| up to 14).
    assert error.max() < 2e-5


def test_the_gradient_is_traced_in_one_pass_with_the_value(llvm):
    """Value and gradient come from one kernel (no second noise evaluation)."""
    p = float32_drjit(random_points(256))
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        value, gradient = noise.fractal_gradient(p, 4)[:2]
        dr.eval(value, gradient)
        kernels = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    assert len(kernels) == 1


@pytest.mark.parametrize("turbulence", [False, True])
def test_float32_gradient_is_within_1e_3_relative_of_float64_central_differences(llvm, turbulence):
    # Issue 13's target, where |∇F| > 0.1: measured 1.1e-5 (1.4e-5 turbulent) at 8 octaves.
    pts = off_the_lattice(random_points(4000, 3.0), octaves=8).astype(np.float32).astype(np.float64)
    _, gradient = noise.fractal_gradient(float32_drjit(pts), 8, turbulence)[:2]
    numeric = central_difference(lambda q: reference_noise.fractal3(q, 8, turbulence), pts, 1e-7)
    keep = np.linalg.norm(numeric, axis=1) > 0.1
    if turbulence:   # |N|'s kink: points whose octaves come near N = 0 are left out
        for i in range(8):
            keep &= np.abs(reference_noise.noise3(pts * 2.0 ** i)) > 1e-4
    error = np.linalg.norm(np.array(gradient).T - numeric, axis=1) / np.linalg.norm(numeric, axis=1)
    assert keep.sum() > 3000 and error[keep].max() < 1e-3
