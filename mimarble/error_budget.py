"""The error budget: the octaves of the marble's noise that no output can show.

With φ the marble's phase and t(φ) its stripe (``mimarble/marble.py``)::

    abs_sine:  t = |sin(π φ)|,      φ = period·v_a + distortion·F(v)    |dt/dφ| ≤ π
    sine:      t = ½(sin φ + 1),    φ = period·v_a + distortion·F(v)    |dt/dφ| ≤ ½
    cosine:    t = ½(cos φ + 1),    φ = v_a + distortion·F(v)           |dt/dφ| ≤ ½

the colour is ramp(t), piecewise linear between K colours at keys k/(K−1), so
each component moves by at most R = (K−1)·max_k |c_{k+1} − c_k| (over k and the
three components) per unit of t. The fractal sum F = Σ_{i<K'} N(2^i v)/2^i (or
|N|, turbulence) has |N| ≤ B = 1.0364, so leaving out octaves k…K'−1 moves F by
at most T(k) = B·Σ_{i=k}^{K'−1} 2^−i (K' = min(octaves, 25): float32 evaluates no
more, ``noise.MAX_OCTAVES_EVALUATED``), the phase by |distortion|·T(k), and every
colour component by at most

    E(k) = S · R · |distortion| · T(k),        S = π (abs_sine) or ½ (sine, cosine).

Given a tolerance τ (colour units), the texture evaluates the first k octaves,
k the smallest with E(k) ≤ τ: its colour is then within τ of the one with every
octave, at every point, whatever the noise does there (a bound, not an estimate;
docs/numerical-stability.md has the proof, tests/test_error_budget.py checks it
against the float64 reference's full sum). τ = 0 keeps every octave.

The default: an image's value moves the 8-bit sRGB output before quantisation by
at most half a code value. The sRGB curve is steepest at black (slope 12.92), so a
linear change of ½/(255·12.92) = 1.52e-4 is half a code value anywhere; a
texture's colour reaches the image scaled by its lighting, at most
Λ = max(ambient) + Σ_lights max(intensity) in the paper's whitted model
(ambient·k_a + Σ I·cos·k_d + Σ I·(n·h)^s·k_s, each factor ≤ its light). So a
scene's marbles get τ = 1.52e-4/Λ (:func:`scene_tolerance`); the plugin alone,
not knowing its lighting, takes Λ = 1.
"""

from __future__ import annotations

import math

from .noise import MAX_OCTAVES_EVALUATED, NOISE_BOUND

#: A linear change that moves an 8-bit sRGB value, before quantisation, by at most half a code.
HALF_CODE_VALUE = 0.5 / (255 * 12.92)

#: The ``marble`` plugin's default tolerance (lighting Λ = 1).
DEFAULT_TOLERANCE = HALF_CODE_VALUE

#: S: the largest |dt/dφ| of each stripe function.
PHASE_SLOPE = {"abs_sine": math.pi, "sine": 0.5, "cosine": 0.5}


def ramp_lipschitz(colours) -> float:
    """R: the largest change of a colour component per unit of t (0 for one colour)."""
    colours = [tuple(float(x) for x in c) for c in colours]
    if len(colours) < 2:
        return 0.0
    steps = max(abs(b[j] - a[j]) for a, b in zip(colours, colours[1:]) for j in range(3))
    return (len(colours) - 1) * steps


def tail_bound(first: int, last: int) -> float:
    """T: how far octaves first…last−1 can move F (B·Σ 2^−i)."""
    return NOISE_BOUND * sum(2.0 ** -i for i in range(first, last))


def colour_change_bound(first: int, last: int, distortion: float, colours, function: str) -> float:
    """How far octaves first…last−1 can move any colour component: S·R·|distortion|·T."""
    if first >= last:
        return 0.0
    return (PHASE_SLOPE[function] * ramp_lipschitz(colours) * abs(float(distortion))
            * tail_bound(first, last))


def colour_bound(first: int, octaves: int, distortion: float, colours, function: str) -> float:
    """E(first): how far the colour can move when only the first ``first`` of the
    octaves float32 evaluates (min(octaves, 25)) are summed."""
    return colour_change_bound(first, min(int(octaves), MAX_OCTAVES_EVALUATED), distortion,
                               colours, function)


def octaves_needed(tolerance: float, octaves: int, distortion: float, colours,
                   function: str) -> int:
    """The fewest leading octaves whose colour is within ``tolerance`` of all of them.

    At most min(octaves, 25); ``tolerance`` 0 keeps them all.
    """
    last = min(int(octaves), MAX_OCTAVES_EVALUATED)
    if tolerance <= 0:
        return last
    for k in range(last + 1):
        if colour_bound(k, octaves, distortion, colours, function) <= tolerance:
            return k
    return last


def lighting_scale(ambient, light_colours) -> float:
    """Λ: how much a texture's colour can be scaled on its way into a whitted image."""
    return max(ambient, default=0.0) + sum(max(c) for c in light_colours)


def scene_tolerance(ambient, light_colours) -> float:
    """A scene's default tolerance: half an 8-bit sRGB code value through its lighting."""
    scale = lighting_scale(ambient, light_colours)
    return HALF_CODE_VALUE / scale if scale > 0 else DEFAULT_TOLERANCE
