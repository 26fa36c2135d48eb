"""Exact gradients of the improved noise and of its fractal sum, beside their values.

Perlin's noise is a trilinear interpolation, with weights u = fade(x), v = fade(y),
w = fade(z), of the eight corner values d_c = G_c · (p − corner_c), G_c the corner's
gradient vector. So, with L(u, v, w; values) the nested lerps of
:func:`mimarble.noise.trilinear`:

    N   = L(u, v, w; d)
    ∂N/∂x = L(u, v, w; G_x) + fade′(x) · ∂L/∂u,    fade′(t) = 30 t² (t − 1)²
    ∂L/∂u = lerp(w, lerp(v, d₁ − d₀, d₃ − d₂), lerp(v, d₅ − d₄, d₇ − d₆))

and likewise for y and z (each corner value is linear in p, so its own gradient
is G_c). ``G_c`` is read off :func:`mimarble.noise.grad` by its linearity:
G = (grad(h, 1, 0, 0), grad(h, 0, 1, 0), grad(h, 0, 0, 1)), exactly.

The fractal sum F(p) = Σ N(2^i p)/2^i has ∇F = Σ ∇N(2^i p) (the 2^i of the chain
rule cancels the weight); turbulence's |N| contributes sign(N)·∇N (0 where N = 0).
One pass computes the value and the gradient; the value is bit for bit
:func:`mimarble.noise.noise3` / :func:`mimarble.noise.fractal3`.
The float64 twin is :mod:`mimarble.reference.noise_gradient`.
"""

from __future__ import annotations

from . import environment
from .noise import (corner_dots, corner_hashes, fade, grad, lerp, octaves_evaluated,
                    trilinear, wrap_large_point)

dr, mi = environment.import_drjit_and_mitsuba()


def fade_derivative(t):
    """d/dt of 6t⁵ − 15t⁴ + 10t³ = 30 t² (t − 1)²."""
    s = t * (t - 1.0)
    return 30.0 * s * s


def noise3_gradient(p):
    """(N(p), ∇N(p)) at a Dr.Jit 3-vector ``p``; ∇N has the type of ``p``."""
    fractions, hashes = corner_hashes(p)
    x, y, z = fractions
    u, v, w = fade(x), fade(y), fade(z)
    d = corner_dots(fractions, hashes)
    one, zero = 1.0, 0.0
    gx = [grad(h, one, zero, zero) for h in hashes]
    gy = [grad(h, zero, one, zero) for h in hashes]
    gz = [grad(h, zero, zero, one) for h in hashes]

    d_du = lerp(w, lerp(v, d[1] - d[0], d[3] - d[2]), lerp(v, d[5] - d[4], d[7] - d[6]))
    d_dv = lerp(w, lerp(u, d[2] - d[0], d[3] - d[1]), lerp(u, d[6] - d[4], d[7] - d[5]))
    d_dw = (lerp(v, lerp(u, d[4], d[5]), lerp(u, d[6], d[7]))
            - lerp(v, lerp(u, d[0], d[1]), lerp(u, d[2], d[3])))
    gradient = type(p)(trilinear(u, v, w, gx) + fade_derivative(x) * d_du,
                       trilinear(u, v, w, gy) + fade_derivative(y) * d_dv,
                       trilinear(u, v, w, gz) + fade_derivative(z) * d_dw)
    return trilinear(u, v, w, d), gradient


def fractal3_gradient(p, octaves: int, turbulence: bool = False):
    """(F(p), ∇F(p)), F = Σ_{i<K} N(2^i p)/2^i (|N| with ``turbulence``), as
    :func:`mimarble.noise.fractal3` evaluates it (the same octaves, the same wrap)."""
    n_eval = octaves_evaluated(octaves)
    float_type = type(p.x)
    jit = dr.is_jit_v(float_type)
    total = dr.zeros(float_type, dr.width(p)) if jit else 0.0
    gradient = dr.zeros(type(p), dr.width(p)) if jit else type(p)(0.0)
    if n_eval == 0:
        return total, gradient
    q = wrap_large_point(p)
    for i in range(n_eval):
        n, g = noise3_gradient(q * float(2.0 ** i))
        if turbulence:
            g = g * dr.sign(n) * dr.select(n == 0.0, 0.0, 1.0)
            n = dr.abs(n)
        total += n * float(2.0 ** -i)
        gradient += g
    return total, gradient
