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
from .noise import (band_limit, corner_dots, corner_hashes, fade, grad, lerp, octaves_evaluated,
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


#: Var N(p) of the improved noise over uniformly spread points, and Var |N(p)|
#: (turbulence): measured in float64 on the reference noise over 2·10⁶ points uniform in
#: [−100, 100]³ (N: 0.0731, mean 1e-4; |N|: 0.0245, mean 0.220); tests/test_prefilter.py
#: measures them again. Octaves are near independent, so leaving out octaves i ≥ n of
#: F moves it by a spread of variance V·Σ_{i≥n} 4^−i.
NOISE_VARIANCE = 0.0731
ABS_NOISE_VARIANCE = 0.0245
#: E|N(p)| (the mean of a turbulence octave; E N = 0), measured with the variances.
ABS_NOISE_MEAN = 0.2204


def fractal3_band_limited_gradient(p, octaves: int, footprint, margin: float,
                                   turbulence: bool = False, differentials=None):
    """(F, ∇F, σ²): the octaves up to ``footprint`` (:func:`mimarble.noise.band_limit`
    with ``margin``), their gradient, and the variance σ² of F across the pixel that the
    gradient does not describe: the octaves left out (turbulent ones also add their mean
    E|N| to F), and, for turbulence with the pixel's ``differentials`` (∂p/∂x, ∂p/∂y),
    the octaves folded inside the pixel.

    |N| folds where N crosses 0: across a pixel where N runs linearly over
    [n − W/2, n + W/2] (W from ∇N and the differentials; |n| < W/2) the mean of |N|
    is n²/W + W/4, not |n|, and it spreads with variance n² + W²/12 − mean² about that
    mean, with no slope: such an octave adds its mean to F and its spread to σ², not
    its gradient. Without differentials the octave is |N| at the point.

    A symbolic loop (each lane stops after its own last octave), unrolled when ``p``
    carries gradients (reverse mode cannot go through a symbolic loop)."""
    whole, last = band_limit(footprint, octaves, margin)
    most = octaves_evaluated(octaves)
    float_type = type(p.x)
    uint_type = dr.uint32_array_t(float_type)
    q = wrap_large_point(p)
    width = dr.width(p)
    folds = turbulence and differentials is not None

    def octave(i, frequency, amplitude, total, gradient, spread):
        n, g = noise3_gradient(q * frequency)
        weight = dr.select(float_type(i) < whole, 1.0, dr.select(float_type(i) == whole, last, 0.0))
        if turbulence:
            g = g * dr.sign(n) * dr.select(n == 0.0, 0.0, 1.0)
            n = dr.abs(n)
        if folds:
            # N across the pixel, in N's units: ∇N(2^i p)·2^i·(∂p/∂x, ∂p/∂y).
            across = frequency * dr.sqrt(dr.square(dr.dot(g, differentials[0]))
                                         + dr.square(dr.dot(g, differentials[1])))
            folded = n < 0.5 * across
            mean = dr.select(folded, dr.square(n) / across + 0.25 * across, n)
            variance = dr.select(folded, dr.square(n) + dr.square(across) / 12.0
                                 - dr.square(mean), 0.0)
            n, g = mean, dr.select(folded, 0.0, g)
            spread = spread + dr.maximum(variance, 0.0) * dr.square(amplitude * weight)
        return (i + 1, frequency * 2.0, amplitude * 0.5,
                total + n * (amplitude * weight), gradient + g * weight, spread)

    state = (dr.zeros(uint_type, width), dr.full(float_type, 1.0, width),
             dr.full(float_type, 1.0, width), dr.zeros(float_type, width),
             dr.zeros(type(p), width), dr.zeros(float_type, width))
    if dr.grad_enabled(p):
        for _ in range(most):
            state = octave(*state)
    else:
        count = uint_type(whole) + dr.select(last > 0.0, 1, 0)
        state = dr.while_loop(state, lambda i, *rest: i < count, octave)
    total, gradient, folded_spread = state[3], state[4], state[5]

    # Left out: (1 − last) of octave `whole`, and all of whole+1 … most−1. They add their
    # spread to σ², and, turbulent, their mean to F (|N| averages E|N| over a pixel).
    left_out = whole < float(most)
    variance = ABS_NOISE_VARIANCE if turbulence else NOISE_VARIANCE
    power = dr.exp2(-2.0 * whole)                      # 4^−whole
    dropped = dr.square(1.0 - last) * power + (power * 0.25 - 4.0 ** -most) * (4.0 / 3.0)
    dropped = dr.select(left_out, variance * dr.maximum(dropped, 0.0), 0.0)
    if turbulence:
        half = dr.exp2(-whole)                         # 2^−whole
        weights = (1.0 - last) * half + dr.maximum(half - 2.0 ** (1 - most), 0.0)
        total = total + dr.select(left_out, ABS_NOISE_MEAN * weights, 0.0)
    return total, gradient, dropped + folded_spread
