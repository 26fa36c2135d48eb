"""The error budget: the octaves of the marble's noise that no output can show.

With φ the marble's phase, linear in distortion·F, and t(φ) its stripe, whose slope
|dt/dφ| is at most S (π for abs_sine, ½ for sine and cosine: each stripe function's
``slope_bound``, mimarble/texture/stripes.py), the colour is ramp(t), piecewise linear
between K colours at keys k/(K−1), so each component moves by at most R = (K−1)·max_k |c_{k+1} − c_k| (over k and the
three components) per unit of t. The fractal sum F = Σ_{i<K'} N(2^i v)/2^i (or
|N|, turbulence) has |N| ≤ B = 1.0364, so leaving out octaves k…K'−1 moves F by
at most T(k) = B·Σ_{i=k}^{K'−1} 2^−i (K' = min(octaves, 25): float32 evaluates no
more, ``noise.MAX_OCTAVES_EVALUATED``), the phase by |distortion|·T(k), and every
colour component by at most

    E(k) = S · R · |distortion| · T(k),        S = π (abs_sine) or ½ (sine, cosine).

The same with the knobs POV-Ray has (issue 30): at gain ω the octaves weigh ω^i, so
T(k) = B·Σ_{i=k}^{K'−1} ω^i, K' = min(octaves, ``noise.max_octaves_evaluated(ω)``); the
lacunarity λ moves no bound (|N(λ^i v)| ≤ B whatever the frequency). At positions
p_0 ≤ … ≤ p_{K−1} the ramp's slope is R = max_k |c_{k+1} − c_k|/(p_{k+1} − p_k), infinite
at a hard step (two equal positions, two colours): no octave can be left out then.
The triangle wave has S = 2; the sawtooth S = 1 and a jump from t = 1 to 0 once a
period, by ramp(1) − ramp(0): unless the ramp's ends are equal, no finite bound, and
every octave is kept.

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

from .noise import NOISE_BOUND, octaves_evaluated
from .stripes import STRIPES

#: A linear change that moves an 8-bit sRGB value, before quantisation, by at most half a code.
HALF_CODE_VALUE = 0.5 / (255 * 12.92)

#: The ``marble`` plugin's default tolerance (lighting Λ = 1).
DEFAULT_TOLERANCE = HALF_CODE_VALUE

def ramp_lipschitz(colours, positions=None) -> float:
    """R: the largest change of a colour component per unit of t (0 for one colour):
    (K−1)·max |c_{k+1} − c_k| at even keys, max |c_{k+1} − c_k|/(p_{k+1} − p_k) at
    ``positions`` (inf at a step: equal positions, different colours)."""
    colours = [tuple(float(x) for x in c) for c in colours]
    if len(colours) < 2:
        return 0.0
    if positions is None:
        steps = max(abs(b[j] - a[j]) for a, b in zip(colours, colours[1:]) for j in range(3))
        return (len(colours) - 1) * steps
    slope = 0.0
    for k in range(len(colours) - 1):
        step = max(abs(colours[k + 1][j] - colours[k][j]) for j in range(3))
        width = float(positions[k + 1]) - float(positions[k])
        if step > 0.0:
            slope = max(slope, step / width if width > 0.0 else math.inf)
    return slope


def tail_bound(first: int, last: int, gain: float = 0.5) -> float:
    """T: how far octaves first…last−1 can move F (B·Σ ω^i; the paper's ω = ½: 2^−i)."""
    return NOISE_BOUND * sum(gain ** i for i in range(first, last))


def phase_lipschitz(colours, function: str, positions=None) -> float:
    """S·R: how far a colour component can move per unit of phase; inf where the stripe
    jumps (the sawtooth) between different end colours of the ramp."""
    stripe = STRIPES[function]
    colours = [tuple(float(x) for x in c) for c in colours]
    if stripe.jumps and len(colours) > 1 and colours[0] != colours[-1]:
        return math.inf
    return stripe.slope_bound * ramp_lipschitz(colours, positions)


def _factor(distortion, colours, function, positions) -> float:
    """S·R·|distortion|, 0 where either is 0 (no octave can move the colour)."""
    slope, distortion = phase_lipschitz(colours, function, positions), abs(float(distortion))
    return 0.0 if slope == 0.0 or distortion == 0.0 else slope * distortion


def colour_change_bound(first: int, last: int, distortion: float, colours, function: str,
                        gain: float = 0.5, positions=None) -> float:
    """How far octaves first…last−1 can move any colour component: S·R·|distortion|·T."""
    if first >= last:
        return 0.0
    factor = _factor(distortion, colours, function, positions)
    return factor * tail_bound(first, last, gain) if factor else 0.0


def evaluated(octaves: int, gain: float = 0.5) -> int:
    """K': the octaves float32 evaluates of ``octaves`` at ``gain`` (25 at the paper's)."""
    return octaves_evaluated(int(octaves), gain)


def colour_bound(first: int, octaves: int, distortion: float, colours, function: str,
                 gain: float = 0.5, positions=None) -> float:
    """E(first): how far the colour can move when only the first ``first`` of the
    octaves float32 evaluates (K', 25 at the paper's gain) are summed."""
    return colour_change_bound(first, evaluated(octaves, gain), distortion, colours, function,
                               gain, positions)


def octaves_needed(tolerance: float, octaves: int, distortion: float, colours,
                   function: str, gain: float = 0.5, positions=None) -> int:
    """The fewest leading octaves whose colour is within ``tolerance`` of all of them.

    At most K' (min(octaves, 25) at the paper's gain); ``tolerance`` 0 keeps them all.
    """
    last = evaluated(octaves, gain)
    if tolerance <= 0:
        return last
    # colour_bound(k, …) for each k, its factors S·R·|distortion| computed once.
    factor = _factor(distortion, colours, function, positions)
    for k in range(last + 1):
        if (factor * tail_bound(k, last, gain) if k < last and factor else 0.0) <= tolerance:
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
    from mimarble.scene import model
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


def mean_bound(channel) -> float:
    """An upper bound of the mean of a channel's three components (a subsurface's density
    is that mean): a colour's own, a marble's largest over its ramp's colours (the ramp
    interpolates each component linearly, so their mean too: its largest is at a key), a sum's
    the sum of its operands'; :func:`channel_bound` for the rest."""
    from mimarble.scene import model
    if isinstance(channel, model.ColorChannel):
        return sum(channel.rgb) / 3.0
    if isinstance(channel, model.MarbleChannel):
        return max(sum(c) / 3.0 for c in channel.ramp)
    if isinstance(channel, model.Add):
        return sum(mean_bound(c) for c in channel.operands)
    return channel_bound(channel)


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
    from mimarble.scene import model
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
