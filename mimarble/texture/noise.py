"""The noise's public face: Perlin's improved noise and its fractal sums, and NumPy entry points.

The Dr.Jit functions live in :mod:`mimarble.texture.perlin` (N and ∇N) and
:mod:`mimarble.texture.fbm` (the octave sums); this module gives them their one
documented name, ``mimarble.noise`` (docs/design.md), and adds the NumPy entry points.

    noise3(p)            N(p), improved noise, |N| ≤ 1.0364 (not 1)
    noise3_gradient(p)   (N(p), ∇N(p)) in one pass, N bit for bit noise3's
    fractal3(p, K)       F = Σ_{i<K} N(2^i p) / 2^i     the paper's Fractal3 (Fig. 6)
    fractal3(p, K, True)     Σ_{i<K} |N(2^i p)| / 2^i   Perlin's turbulence
    fractal_band, fractal_gradient, fractal_over_pixel
                         the same sum band-limited to a pixel's footprint, with ∇F,
                         with |N| folded in the pixel (:mod:`mimarble.texture.fbm`)
    Spectrum(ω, λ)       another gain ω and lacunarity λ (POV-Ray's omega and lambda):
                         F = Σ_{i<K} ω^i N(λ^i p); the paper's are ω = ½, λ = 2

``perlin(points)`` and ``fractal(points, K)`` are the NumPy entry points: (N, 3)
in, (N,) out, through the very same Dr.Jit code.
"""

from __future__ import annotations

import numpy as np

from mimarble.runtime import environment
from .fbm import (  # noqa: F401  (the documented names)
    ABS_NOISE_MEAN, ABS_NOISE_VARIANCE, BAND_LIMIT_MARGIN, MAX_OCTAVES_EVALUATED,
    NOISE_VARIANCE, PAPER_SPECTRUM, SKIPPED_OCTAVES_BOUND, FractalSum, Spectrum, band_limit,
    fractal3, fractal_band, fractal_gradient, fractal_over_pixel, fractal_sum, left_out,
    max_octaves_evaluated, octaves_evaluated)
from .perlin import (  # noqa: F401
    NOISE_BOUND, PERMUTATION, corner_dots, corner_hashes, fade, fade_derivative, grad,
    lattice_tables, lerp, noise3, noise3_gradient, trilinear, wrap_large_point)

dr, mi = environment.import_drjit_and_mitsuba()

# ---------------------------------------------------------------------------
# NumPy entry points, through the very same Dr.Jit code

def _array_types():
    """(Array3f, Float) of the backend the NumPy entry points run on.

    The current variant's JIT backend; for the scalar variant, Dr.Jit's LLVM
    backend when usable, else None (then the points go one by one).
    """
    variant = mi.variant() or ""
    if variant.startswith("cuda_"):
        return dr.cuda.Array3f, dr.cuda.Float
    if variant.startswith("llvm_") or environment.variant_problem("llvm_ad_rgb") is None:
        return dr.llvm.Array3f, dr.llvm.Float
    return None, None


def _evaluate(points, fn) -> np.ndarray:
    pts = np.ascontiguousarray(np.asarray(points, dtype=np.float32))
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {pts.shape}")
    array3f, float_type = _array_types()
    if array3f is None:
        return np.array([fn(dr.scalar.Array3f(*map(float, row))) for row in pts], np.float32)
    p = array3f(float_type(pts[:, 0]), float_type(pts[:, 1]), float_type(pts[:, 2]))
    return np.asarray(fn(p), dtype=np.float32).reshape(len(pts))


def perlin(points) -> np.ndarray:
    """Improved noise at NumPy points (N, 3) → float32 (N,)."""
    return _evaluate(points, noise3)


def fractal(points, octaves: int, turbulence: bool = False, gain: float = 0.5,
            lacunarity: float = 2.0) -> np.ndarray:
    """F at NumPy points (N, 3) → float32 (N,); ``turbulence`` sums |N| instead; ``gain``
    ω and ``lacunarity`` λ: Σ ω^i N(λ^i p)."""
    octaves_evaluated(octaves)   # validate before any work
    spectrum = Spectrum(gain, lacunarity)
    return _evaluate(points, lambda p: fractal3(p, octaves, turbulence, spectrum))
