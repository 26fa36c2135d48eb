"""sin(πx) and cos(πx) accurate on a GPU too: the sine relatively so near its zeros.

Dr.Jit evaluates float32 ``dr.sin`` and ``dr.cos`` on a CUDA GPU with PTX's
``sin.approx`` / ``cos.approx`` (drjit src/extra/math.cpp, ``jit_var_sin``): their
*absolute* error is about 2⁻²¹, so sin of a small angle has no correct digit left. The
prefilter integrates the stripe over intervals as short as float32 resolves, as
products of sines of half the interval (mimarble/texture/stripes.py, ``integral``):
there the relative error is what counts (docs/benchmarks.md, "The CUDA variant", gives
what the approximations did to the phase averages).

On a GPU these functions reduce x to r = x − round(x) ∈ [−½, ½] (exact in floating
point) and evaluate the Taylor series of sin(πr) (to r¹³) and cos(πr) (to r¹⁴), whose
first left-out terms are below 2⁻²⁴ for |πr| ≤ π/2; the sign is that of (−1)^round(x).
Elsewhere they are ``dr.sin(dr.pi·x)`` and ``dr.cos(dr.pi·x)``, as before (Dr.Jit's
Cephes polynomials on the CPU are accurate to a few ulp), so CPU images are unchanged.
"""

from __future__ import annotations

import math

from mimarble.runtime import environment

dr, mi = environment.import_drjit_and_mitsuba()

#: Taylor coefficients of sin(πr) = Σ S_k r^(2k+1) and cos(πr) = Σ C_k r^(2k).
_SIN = tuple((-1) ** k * math.pi ** (2 * k + 1) / math.factorial(2 * k + 1) for k in range(7))
_COS = tuple((-1) ** k * math.pi ** (2 * k) / math.factorial(2 * k) for k in range(8))


def _on_gpu(x) -> bool:
    return dr.is_jit_v(x) and dr.backend_v(x) == dr.JitBackend.CUDA


def _series(coefficients, z):
    """Σ coefficients[k]·z^k by Horner's rule."""
    total = coefficients[-1]
    for c in reversed(coefficients[:-1]):
        total = dr.fma(total, z, c)
    return total


def _reduced(x):
    """(r, odd): x = n + r with n = round(x), r ∈ [−½, ½]; odd where n is odd.

    The parity is read in floating point (n/2 not an integer; both steps exact), not
    from an int32 conversion: past 2³¹ that conversion saturates on a GPU (PTX's
    float-to-integer ``cvt`` clamps, to 2³¹ − 1: odd) where every float32 is even."""
    n = dr.round(x)
    half = 0.5 * n
    return x - n, dr.floor(half) != half


def sin_pi(x):
    """sin(πx): :func:`sin_pi_series` on a GPU, else ``dr.sin(dr.pi·x)``."""
    return sin_pi_series(x) if _on_gpu(x) else dr.sin(dr.pi * x)


def cos_pi(x):
    """cos(πx): :func:`cos_pi_series` on a GPU, else ``dr.cos(dr.pi·x)``."""
    return cos_pi_series(x) if _on_gpu(x) else dr.cos(dr.pi * x)


def sin_pi_series(x):
    """sin(πx) from the reduced argument's Taylor series, on any JIT backend."""
    r, odd = _reduced(x)
    s = r * _series(_SIN, r * r)
    return dr.select(odd, -s, s)


def cos_pi_series(x):
    """cos(πx) from the reduced argument's Taylor series, on any JIT backend."""
    r, odd = _reduced(x)
    c = _series(_COS, r * r)
    return dr.select(odd, -c, c)
