"""Octave sums of the improved noise: F = Σ_{i<K} ω^i N(λ^i p), and what filters need of them.

    fractal3(p, K)               F = Σ_{i<K} N(2^i p) / 2^i   the paper's Fractal3 (Fig. 6)
    fractal3(p, K, True)         Σ_{i<K} |N(2^i p)| / 2^i     Perlin's turbulence
    fractal_band(p, K, band)     F without the octaves finer than a pixel, the last faded
    fractal_gradient(p, K)       (F, ∇F) in one pass
    fractal_over_pixel(p, K, …)  band, ∇F, |N| folded in the pixel, and F at the point:
                                 the prefilter's one loop
    band_limit, left_out         the band of a footprint, and the statistics of the
                                 octaves it leaves out
    Spectrum(ω, λ)               another gain ω and lacunarity λ (POV-Ray's omega and
                                 lambda); the paper's are ω = ½, λ = 2

Every sum is one driver, :func:`_octaves` (the loop: unrolled or symbolic), handed
one octave's terms. Each adds the same terms in the same order as the others where
they share them, so F is bit for bit the same wherever two of them compute it.

Numerical safety:

* Octaves that float32 cannot add are not evaluated: the tail Σ_{i≥K} holds at
  most 1.0364·2^(1−K), so octaves from ``MAX_OCTAVES_EVALUATED`` = 25 on change
  F by at most ``SKIPPED_OCTAVES_BOUND`` = 1.0364·2^−24 ≈ 6.2e-8, below the float32
  rounding error of the octaves that are summed. 32 or 64 octaves cost what 25 do.
  At gain ω the tail is 1.0364·ω^K/(1−ω): octaves from the first K where it is at most
  the same 1.0364·2^−24 are left out (:func:`max_octaves_evaluated`; 25 at ½, all 64
  from ω ≈ 0.755 on).
* At lacunarity λ ≤ 3 (the parameter's range) the finest octave's point λ^63·|q| stays
  below 2^124 for |q| < 2^24: no overflow. A coordinate of 2^24 or more is wrapped
  mod 256 once as at λ = 2 (where that is exact); at another λ the point is beyond
  float32's resolution there anyway, and the result finite and deterministic.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from mimarble.contract import MAX_OCTAVES_EVALUATED, SKIPPED_OCTAVES_BOUND
from mimarble.runtime import environment
from mimarble.parameters import BY_NAME, MAX_OCTAVES
from .perlin import NOISE_BOUND, noise3, noise3_gradient, wrap_large_point

dr, mi = environment.import_drjit_and_mitsuba()



def max_octaves_evaluated(gain: float = 0.5) -> int:
    """The octaves float32 can add at gain ω: the first k whose tail, at most
    NOISE_BOUND·ω^k/(1−ω), is at most SKIPPED_OCTAVES_BOUND = NOISE_BOUND·2^−24 (25 at
    the paper's ½, where the tail is 2^(1−k)), and at most MAX_OCTAVES."""
    gain = float(gain)
    for k in range(MAX_OCTAVES + 1):
        if gain ** k / (1.0 - gain) <= 2.0 ** -24:
            return k
    return MAX_OCTAVES


def octaves_evaluated(octaves: int, gain: float = 0.5) -> int:
    """How many octaves a K-octave sum actually evaluates (see SKIPPED_OCTAVES_BOUND)."""
    if not 0 <= octaves <= MAX_OCTAVES:
        raise ValueError(f"octaves must be an integer in 0..{MAX_OCTAVES}, got {octaves}")
    return min(octaves, MAX_OCTAVES_EVALUATED if gain == 0.5 else max_octaves_evaluated(gain))


class Spectrum:
    """The octaves' gain ω and lacunarity λ: octave i has amplitude ω^i and frequency λ^i.

    ``gain`` and ``lacunarity`` are what the kernel reads: Python floats (literals, as the
    paper's ½ and 2 by default) or opaque Dr.Jit values (the texture's, so that a new
    value reuses the compiled kernel and carries derivatives). ``gain_value`` is the
    number that decides how many octaves float32 can add (structural). The constants the
    filters derive from them (1/log₂λ, log₂ω, ω², 1/(1−ω), 1/(1−ω²), and ω^K', ω^2K' for
    the ``octaves`` K' a texture evaluates) are computed here in double precision and held
    like the two (``opaque``: as opaque Dr.Jit values); the filters' cut-offs and estimates
    carry no derivative to ω or λ, the sum does. ``DRJIT_STRUCT``: Dr.Jit's traversal
    (``dr.freeze``) sees them through the texture."""

    DRJIT_STRUCT = {"gain": object, "lacunarity": object, "inverse_log_lacunarity": object,
                    "log_gain": object, "gain_squared": object, "inverse_tail": object,
                    "inverse_tail_squared": object, "gain_power": object,
                    "gain_power_squared": object}

    def __init__(self, gain_value: float = 0.5, lacunarity_value: float = 2.0, gain=None,
                 lacunarity=None, opaque: bool = False, octaves: int | None = None):
        # The table's ranges (a ParameterError, a ValueError, outside them). A value None:
        # held on the device only (an edit the host never read, mimarble/mitsuba/plugins/marble.py); its
        # constants are then derived there, in single precision, from ``gain`` or
        # ``lacunarity`` (no read back), and every octave is evaluated.
        self.gain_value = None if gain_value is None else BY_NAME["gain"].check(float(gain_value))
        self.lacunarity_value = None if lacunarity_value is None else \
            BY_NAME["lacunarity"].check(float(lacunarity_value))
        self.gain = self.gain_value if gain is None else gain
        self.lacunarity = self.lacunarity_value if lacunarity is None else lacunarity
        self.octaves = octaves
        g = self.gain_value if self.gain_value is not None else dr.detach(self.gain)
        lacunarity_held = self.lacunarity_value if self.lacunarity_value is not None \
            else dr.detach(self.lacunarity)

        def log2(x):
            return math.log2(x) if isinstance(x, float) else dr.log2(x)
        derived = {"inverse_log_lacunarity": 1.0 / log2(lacunarity_held),
                   "log_gain": log2(g),
                   "gain_squared": g * g,
                   "inverse_tail": 1.0 / (1.0 - g),
                   "inverse_tail_squared": 1.0 / (1.0 - g * g),
                   "gain_power": g ** (octaves or 0),
                   "gain_power_squared": g ** (2 * (octaves or 0))}
        for name, value in derived.items():
            if opaque:
                value = mi.Float(value)
                dr.make_opaque(value)
            setattr(self, name, value)

    @property
    def paper(self) -> bool:
        """The paper's ω = ½ and λ = 2."""
        return self.gain_value == 0.5 and self.lacunarity_value == 2.0   # (None: not known)

    def differentiated(self) -> bool:
        return dr.grad_enabled(self.gain) or dr.grad_enabled(self.lacunarity)

    def most(self, octaves: int) -> int:
        """The octaves of a K-octave sum evaluated at this gain (a gain on the device:
        every one)."""
        if self.gain_value is None:
            return octaves
        return octaves_evaluated(octaves, self.gain_value)

    def power(self, k: int, squared: bool = False):
        """ω^k (ω^2k): the held value for the spectrum's own ``octaves``, else a literal."""
        if k == self.octaves:
            return self.gain_power_squared if squared else self.gain_power
        held = self.gain_value if self.gain_value is not None else dr.detach(self.gain)
        return held ** (2 * k if squared else k)


#: The paper's octaves: ω = ½, λ = 2, as literals.
PAPER_SPECTRUM = Spectrum()


class FractalSum(NamedTuple):
    """What :func:`fractal_gradient` and :func:`fractal_over_pixel` return: F, ∇F, the
    variance σ² of F across the pixel that ∇F does not describe (0 unless folding), and
    with ``point``, F at the point with every octave (None unless asked for)."""

    value: object
    gradient: object
    spread: object
    point: object = None


def fractal3(p, octaves: int, turbulence: bool = False, spectrum: Spectrum = PAPER_SPECTRUM):
    """F(p) = Σ_{i<K'} ω^i N(λ^i p) (paper Fig. 6 at ω = ½, λ = 2; K' = min(K, 25) there,
    :func:`octaves_evaluated`); with ``turbulence``, |N| in the sum: pbrt's FBm without
    its clamp."""
    def octave(q, i, frequency, amplitude, state):
        n, _ = _octave_noise(q, frequency, turbulence, False)
        return {"total": state["total"] + n * amplitude}
    return _octaves(p, octaves, spectrum, _zeros(p, ("total",)), octave)["total"]


def fractal_band(p, octaves: int, band, turbulence: bool = False,
                 spectrum: Spectrum = PAPER_SPECTRUM):
    """F with octave weights w_i from ``band`` = (whole, last) of :func:`band_limit`:
    octaves i < whole have weight 1, octave ``whole`` weight ``last``, the rest are left
    out; each lane stops after its own last octave (fewer noise evaluations where the
    footprint is large)."""
    def octave(q, i, frequency, amplitude, state):
        n, _ = _octave_noise(q, frequency, turbulence, False)
        weighted = amplitude * _band_weight(band, i, type(q.x))
        return {"total": state["total"] + n * weighted}
    return _octaves(p, octaves, spectrum, _zeros(p, ("total",)), octave, band)["total"]


def fractal_gradient(p, octaves: int, turbulence: bool = False,
                     spectrum: Spectrum = PAPER_SPECTRUM, band=None) -> FractalSum:
    """(F, ∇F) in one pass: ∇F = Σ w_i (ωλ)^i ∇N(λ^i p) (at the paper's ω, λ the 2^i of the
    chain rule cancels the amplitude: (ωλ)^i = 1 exactly); turbulence's |N| contributes
    sign(N)·∇N (0 where N = 0). With a ``band``, its weights, as :func:`fractal_band`."""
    def octave(q, i, frequency, amplitude, state):
        n, g = _octave_noise(q, frequency, turbulence, True)
        weight = None if band is None else _band_weight(band, i, type(q.x))
        weighted = amplitude if weight is None else amplitude * weight
        return {"total": state["total"] + n * weighted,
                "gradient": state["gradient"] + _chained(g, frequency, amplitude, weight)}
    state = _octaves(p, octaves, spectrum, _zeros(p, ("total", "gradient")), octave, band)
    return FractalSum(state["total"], state["gradient"], 0.0)


def fractal_over_pixel(p, octaves: int, band, differentials, turbulence: bool = False,
                       spectrum: Spectrum = PAPER_SPECTRUM, point: bool = False) -> FractalSum:
    """The prefilter's one octave loop: F and ∇F with the ``band``'s weights, and

    * with ``turbulence``, |N| folded where N crosses 0 inside the pixel (``differentials``
      = (∂p/∂x, ∂p/∂y)). Where N runs linearly over [n − W/2, n + W/2] across it (W from
      ∇N and the differentials, |n| < W/2), the mean of |N| is n²/W + W/4, not |n|, and
      it spreads with variance n² + W²/12 − mean² about that mean, with no slope: such an
      octave adds its mean to F and its spread to σ², not its gradient.
    * with ``point``, also F with every octave, unweighted and unfolded, bit for bit
      :func:`fractal3`'s (the same terms in the same order): the band's octaves share
      their noise with it, the rest are plain N (a second loop from each lane's last
      octave), so the point sample costs only the octaves past the band.
    """
    folds = turbulence and differentials is not None
    keys = ("total", "gradient") + (("spread",) if folds else ()) + (("point",) if point else ())

    def octave(q, i, frequency, amplitude, state):
        n, g = _octave_noise(q, frequency, turbulence, True)
        state = dict(state)
        if point:
            state["point"] = state["point"] + n * amplitude
        weight = None if band is None else _band_weight(band, i, type(q.x))
        weighted = amplitude if weight is None else amplitude * weight
        if folds:
            n, g, variance = _folded(n, g, frequency, differentials)
            state["spread"] = state["spread"] + dr.maximum(variance, 0.0) * dr.square(weighted)
        state["total"] = state["total"] + n * weighted
        state["gradient"] = state["gradient"] + _chained(g, frequency, amplitude, weight)
        return state

    def rest(q, i, frequency, amplitude, total):
        """The point's octaves past the band: plain N (|N|), weight 1."""
        n, _ = _octave_noise(q, frequency, turbulence, False)
        return total + n * amplitude

    state = _octaves(p, octaves, spectrum, _zeros(p, keys), octave, band,
                     ("point", rest) if point else None)
    return FractalSum(state["total"], state["gradient"], state.get("spread", 0.0),
                      state.get("point"))


def fractal_sum(p, octaves: int, turbulence: bool = False, *, band=None, gradient: bool = False,
                differentials=None, spectrum: Spectrum = PAPER_SPECTRUM,
                point: bool = False) -> FractalSum:
    """Deprecated: the one-function form of the sums above, dispatched to them (the
    options name the variant: ``band``, ``gradient``, ``differentials``, ``point``)."""
    if differentials is not None or point:
        return fractal_over_pixel(p, octaves, band, differentials, turbulence, spectrum, point)
    if gradient:
        return fractal_gradient(p, octaves, turbulence, spectrum, band)
    if band is not None:
        return FractalSum(fractal_band(p, octaves, band, turbulence, spectrum), None, 0.0)
    return FractalSum(fractal3(p, octaves, turbulence, spectrum), None, 0.0)


# ---------------------------------------------------------------------------
# One octave's terms, and the loop over them

def _zeros(p, keys) -> dict:
    """The sums' starting state: 0 for each of ``keys`` (a 3-vector for "gradient")."""
    float_type, width = type(p.x), dr.width(p)
    jit = dr.is_jit_v(float_type)
    state = {}
    for key in keys:
        if key == "gradient":
            state[key] = dr.zeros(type(p), width) if jit else type(p)(0.0)
        elif key == "spread":
            state[key] = dr.zeros(float_type, width)
        else:
            state[key] = dr.zeros(float_type, width) if jit else 0.0
    return state


def _octave_noise(q, frequency, turbulence: bool, with_gradient: bool):
    """N(λ^i q) and ∇N (None unless asked for); with ``turbulence`` |N| and sign(N)·∇N
    (0 where N = 0)."""
    if with_gradient:
        n, g = noise3_gradient(q * frequency)
    else:
        n, g = noise3(q * frequency), None
    if turbulence:
        if g is not None:
            g = g * dr.sign(n) * dr.select(n == 0.0, 0.0, 1.0)
        n = dr.abs(n)
    return n, g


def _band_weight(band, i, float_type):
    """w_i of a band (whole, last): 1 below ``whole``, ``last`` at it, 0 past it."""
    whole, last = band
    i_float = float_type(i)
    return dr.select(i_float < whole, 1.0, dr.select(i_float == whole, last, 0.0))


def _chained(g, frequency, amplitude, weight):
    """An octave's term of ∇F: w_i (ωλ)^i ∇N (the chain rule's λ^i times the amplitude)."""
    chain = amplitude * frequency     # (ωλ)^i: 1, exactly, at the paper's ω and λ
    return g * chain if weight is None else g * (chain * weight)


def _folded(n, g, frequency, differentials):
    """(mean of |N| over the pixel, its gradient, its variance) where N crosses 0 in it
    (see :func:`fractal_over_pixel`); |N| itself, ∇|N| and 0 elsewhere."""
    # N across the pixel, in N's units: ∇N(2^i p)·2^i·(∂p/∂x, ∂p/∂y).
    across = frequency * dr.sqrt(dr.square(dr.dot(g, differentials[0]))
                                 + dr.square(dr.dot(g, differentials[1])))
    folded = n < 0.5 * across
    mean = dr.select(folded, dr.square(n) / across + 0.25 * across, n)
    variance = dr.select(folded, dr.square(n) + dr.square(across) / 12.0
                         - dr.square(mean), 0.0)
    return mean, dr.select(folded, 0.0, g), variance


def _octaves(p, octaves: int, spectrum: Spectrum, state: dict, octave, band=None, rest=None):
    """The loop every sum runs: ``state = octave(q, i, λ^i, ω^i, state)`` for i < K'
    (:meth:`Spectrum.most`), q the point wrapped once (:func:`wrap_large_point`).

    With a ``band``, each lane stops after its own last octave; ``rest`` = (key,
    term): then ``state[key]`` goes on with ``term`` up to K' (a second loop).

    In JIT variants the octaves are a symbolic loop (``dr.while_loop``): one noise
    evaluation's code, however many octaves. Unrolled, a kernel holds every octave's
    code, and LLVM compiles a long straight-line kernel in more than linear time (a
    product of many marbles; docs/benchmarks.md, "Compile time"), while the loop
    renders as fast. The loop is unrolled where it must be: in the scalar variant, and
    when ``p``, ω or λ carries derivatives (reverse mode cannot go through a symbolic
    loop); unrolled, every octave runs ``octave`` (the band's weights are 0 past it, and
    ``rest``'s key sums every octave there). The frequencies and amplitudes λ^i and ω^i
    are products of i factors either way (2^i and 2^−i: exact), so both forms give the
    same bits.
    """
    most = spectrum.most(octaves)
    float_type = type(p.x)
    width = dr.width(p)
    if most == 0:
        return state
    q = wrap_large_point(p)
    gain, lacunarity = spectrum.gain, spectrum.lacunarity
    if not dr.is_jit_v(float_type) or dr.grad_enabled(p) or spectrum.differentiated():
        frequency, amplitude = 1.0, 1.0
        for i in range(most):
            state = octave(q, i, frequency, amplitude, state)
            frequency, amplitude = frequency * lacunarity, amplitude * gain
        return state

    uint_type = dr.uint32_array_t(float_type)
    if band is None:
        count = dr.full(uint_type, most, width)
    else:
        whole, last = band
        count = uint_type(whole) + dr.select(last > 0.0, 1, 0)

    def body(i, frequency, amplitude, state):
        return (i + 1, frequency * lacunarity, amplitude * gain,
                octave(q, i, frequency, amplitude, state))

    loop = (dr.zeros(uint_type, width), dr.full(float_type, 1.0, width),
            dr.full(float_type, 1.0, width), state)
    # Nested in another symbolic operation (an integrator's symbolic `if`, loop or call)
    # the loop can only be symbolic, and is said to be so: left to choose by
    # JitFlag.SymbolicLoops, which Mitsuba turns off to differentiate a render
    # (Integrator::render_backward), Dr.Jit makes it symbolic anyway with a warning per
    # trace (`ad_loop("unnamed"): forcing conditional statement to symbolic mode`).
    # Nothing differentiable enters it (a differentiated p is unrolled above). Outside
    # one, the flag decides, as before.
    mode = "symbolic" if dr.flag(dr.JitFlag.SymbolicScope) else None
    i, frequency, amplitude, state = dr.while_loop(loop, lambda i, *rest: i < count, body,
                                                   mode=mode)
    if rest is not None:
        key, term = rest

        def more(i, frequency, amplitude, total):
            return (i + 1, frequency * lacunarity, amplitude * gain,
                    term(q, i, frequency, amplitude, total))

        state = dict(state)
        state[key] = dr.while_loop((i, frequency, amplitude, state[key]),
                                   lambda i, *_: i < most, more, mode=mode)[3]
    return state


def _smoothstep(a, b, x):
    t = dr.clip((x - a) / (b - a), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


# Octaves kept past pbrt's Nyquist cut: two, the margin with the least 1-spp error on
# fig11a against a float64 reference (pbrt's cut alone, one and three were worse; plain
# supersampling about level). The marble's colour is a nonlinear function of the phase,
# so octaves near the pixel size still shift the pixel's mean. The errors per margin:
# docs/benchmarks.md, "Figures moved out of the code"; docs/design-decisions.md.
BAND_LIMIT_MARGIN = 2


def band_limit(footprint, octaves: int, margin: float = BAND_LIMIT_MARGIN,
               spectrum: Spectrum = PAPER_SPECTRUM):
    """(whole octaves, weight of the next one) for a footprint in noise-space units.

    pbrt-v4's FBm clamp, n = clamp(−1 − log2(footprint), 0, K), moved up by
    ``margin`` octaves (:data:`BAND_LIMIT_MARGIN` unless given); the octave ⌊n⌋ fades
    in with smoothstep(0.3, 0.7) of the fraction, so the count changes without seams.
    At lacunarity λ octave i's frequency is λ^i, below the footprint's Nyquist rate while
    λ^i·footprint < ½: n = margin + (−1 − log2 footprint)/log2 λ, written
    (margin − 1/log2 λ) − log2(footprint)/log2 λ so that λ = 2 gives the bits it did.
    A zero footprint (no ray differentials) keeps every octave, and so does a NaN one.
    """
    most = float(spectrum.most(octaves))
    if spectrum.paper and isinstance(spectrum.lacunarity, float):
        n = margin - 1.0 - dr.log2(footprint)
    else:
        scale = spectrum.inverse_log_lacunarity
        n = (margin - scale) - dr.log2(footprint) * scale
    # NaN (a lane without a valid footprint) and +inf both fail `n < most`: all octaves.
    # The loop count must never come from a NaN: its integer conversion is unbounded.
    n = dr.maximum(dr.select(n < most, n, most), 0.0)
    whole = dr.floor(n)
    return whole, _smoothstep(0.3, 0.7, n - whole)


#: Var N(p) of the improved noise over uniformly spread points, and Var |N(p)|
#: (turbulence): measured in float64 on the reference noise over 2·10⁶ points uniform in
#: [−100, 100]³ (N: 0.0731, mean 1e-4; |N|: 0.0245, mean 0.220); tests/test_prefilter.py
#: measures them again. Octaves are near independent, so leaving out octaves i ≥ n of
#: F moves it by a spread of variance V·Σ_{i≥n} 4^−i.
NOISE_VARIANCE = 0.0731
ABS_NOISE_VARIANCE = 0.0245
#: E|N(p)| (the mean of a turbulence octave; E N = 0), measured with the variances.
ABS_NOISE_MEAN = 0.2204


def left_out(band, octaves: int, turbulence: bool = False,
             spectrum: Spectrum = PAPER_SPECTRUM):
    """(mean, variance) that the octaves a ``band`` leaves out would add to F: (1 − last)
    of octave ``whole`` and all of whole+1 … K'−1. Their variance is V·Σ w²ω^2i; their
    mean is 0, or E|N|·Σ w ω^i for turbulence (|N| averages E|N| over a pixel). At the
    paper's ω = ½: V·Σ w²4^−i and E|N|·Σ w 2^−i, written as before (the same bits)."""
    whole, last = band
    most = spectrum.most(octaves)
    outside = whole < float(most)
    variance = ABS_NOISE_VARIANCE if turbulence else NOISE_VARIANCE
    if spectrum.paper and isinstance(spectrum.gain, float):
        power = dr.exp2(-2.0 * whole)                      # 4^−whole
        dropped = dr.square(1.0 - last) * power + (power * 0.25 - 4.0 ** -most) * (4.0 / 3.0)
    else:                                                  # ω^2·whole, Σ_{whole<i<K'} ω^2i
        g = spectrum
        power = dr.exp2((2.0 * g.log_gain) * whole)
        dropped = dr.square(1.0 - last) * power + (power * g.gain_squared - g.power(
            most, squared=True)) * g.inverse_tail_squared
    dropped = dr.select(outside, variance * dr.maximum(dropped, 0.0), 0.0)
    mean = 0.0
    if turbulence:
        if spectrum.paper and isinstance(spectrum.gain, float):
            half = dr.exp2(-whole)                         # 2^−whole
            weights = (1.0 - last) * half + dr.maximum(half - 2.0 ** (1 - most), 0.0)
        else:                                              # ω^whole, Σ_{whole<i<K'} ω^i
            g = spectrum
            half = dr.exp2(g.log_gain * whole)
            weights = (1.0 - last) * half + dr.maximum(
                half * g.gain - g.power(most), 0.0) * g.inverse_tail
        mean = dr.select(outside, ABS_NOISE_MEAN * weights, 0.0)
    return mean, dropped
