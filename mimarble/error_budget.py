"""The error budget: the octaves of the marble's noise that no output can show.

With φ the marble's phase, linear in distortion·F, and t(φ) its stripe, whose slope
|dt/dφ| is at most S (π for abs_sine, ½ for sine and cosine: each stripe function's
``slope_bound``, mimarble/stripes.py), the colour is ramp(t), piecewise linear
between K colours at keys k/(K−1), so each component moves by at most R = (K−1)·max_k |c_{k+1} − c_k| (over k and the
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
from .stripes import STRIPES

#: A linear change that moves an 8-bit sRGB value, before quantisation, by at most half a code.
HALF_CODE_VALUE = 0.5 / (255 * 12.92)

#: The ``marble`` plugin's default tolerance (lighting Λ = 1).
DEFAULT_TOLERANCE = HALF_CODE_VALUE

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
    return (STRIPES[function].slope_bound * ramp_lipschitz(colours) * abs(float(distortion))
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
    # colour_bound(k, …) for each k, its factors S·R·|distortion| computed once.
    gain = STRIPES[function].slope_bound * ramp_lipschitz(colours) * abs(float(distortion))
    for k in range(last + 1):
        if (gain * tail_bound(k, last) if k < last else 0.0) <= tolerance:
            return k
    return last


def lighting_scale(ambient, light_colours) -> float:
    """Λ: how much a texture's colour can be scaled on its way into a whitted image."""
    return max(ambient, default=0.0) + sum(max(c) for c in light_colours)


def scene_tolerance(ambient, light_colours) -> float:
    """A scene's default tolerance: half an 8-bit sRGB code value through its lighting."""
    scale = lighting_scale(ambient, light_colours)
    return HALF_CODE_VALUE / scale if scale > 0 else DEFAULT_TOLERANCE


# ---------------------------------------------------------------------------
# Marbles inside channel expressions (add, multiply, mix)

def channel_bound(channel) -> float:
    """An upper bound of |every colour component| of a channel (parsed colours are ≥ 0;
    built in Python they need not be)."""
    from .scene import model
    if isinstance(channel, model.ColorChannel):
        return max(map(abs, channel.rgb))
    if isinstance(channel, model.MarbleChannel):
        return max(abs(x) for c in channel.ramp for x in c)
    if isinstance(channel, model.ImageChannel):
        return 1.0                                   # an 8-bit sRGB texel decodes to ≤ 1
    if isinstance(channel, model.Add):
        return sum(channel_bound(c) for c in channel.operands)
    if isinstance(channel, model.Multiply):
        return math.prod(channel_bound(c) for c in channel.operands)
    a, b = channel_bound(channel.a), channel_bound(channel.b)
    keep, take = _mix_weights(channel.weight)
    return keep * a + take * b


def _mix_weights(weight) -> tuple[float, float]:
    """Bounds of |1 − w| and |w| for a mix weight (a number, or a channel with |w| ≤ W)."""
    if isinstance(weight, float):
        return abs(1.0 - weight), abs(weight)
    w = channel_bound(weight)
    return 1.0 + w, w


def marble_gains(channel, factor: float = 1.0, gains: dict | None = None) -> dict:
    """For each marble in ``channel``: the most an error in its colour can be multiplied
    by on its way to the channel's colour, summed over its occurrences.

    A sum passes errors on unchanged; a product multiplies an operand's by the
    others' bounds; a mix multiplies a's by |1 − w|, b's by |w| and the weight's by
    max(a, b) (|∂/∂w| = |b − a|). So the channel's error is at most Σ gain·error.
    """
    from .scene import model
    gains = {} if gains is None else gains
    if isinstance(channel, model.MarbleChannel):
        gains[channel] = gains.get(channel, 0.0) + factor
    elif isinstance(channel, model.Add):
        for operand in channel.operands:
            marble_gains(operand, factor, gains)
    elif isinstance(channel, model.Multiply):
        bounds = [channel_bound(c) for c in channel.operands]
        for k, operand in enumerate(channel.operands):
            marble_gains(operand, factor * math.prod(bounds[:k] + bounds[k + 1:]), gains)
    elif isinstance(channel, model.Mix):
        keep, take = _mix_weights(channel.weight)
        marble_gains(channel.a, factor * keep, gains)
        marble_gains(channel.b, factor * take, gains)
        if not isinstance(channel.weight, float):
            marble_gains(channel.weight, factor * max(channel_bound(channel.a),
                                                      channel_bound(channel.b)), gains)
    return gains


def expression_gain(channel) -> float:
    """Σ of :func:`marble_gains`: a channel's error per unit of error of its marbles
    (1 for a lone marble). Each of its marbles then gets tolerance / gain."""
    return sum(marble_gains(channel).values())
