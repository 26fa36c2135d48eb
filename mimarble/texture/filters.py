"""How the marble fills a pixel: ``filter none | bandlimit | prefilter``, one strategy each.

The texture (mimarble/mitsuba/plugins/marble.py) reads the formula in order — map, noise,
phase, colour — and asks its filter at the two steps where a pixel differs from a point::

    noise(point, octaves)      F at the point, or over the pixel's footprint
    colour(phase, point)       ramp(t(φ)) at the phase, or its mean over the pixel

    none:       ramp(t(φ(v)))                     F with every octave the budget keeps
    bandlimit:  ramp(t(φ(v)))                     F without the octaves finer than the
                                                  pixel (pbrt-v4's FBm clamp at octave
                                                  frequencies λ^i), the last faded
    prefilter:  mean of ramp∘t over the pixel's   F and ∇F without the octaves finer than
                interval of phase                 the pixel; their spread widens the interval

A filter is handed values only — the point and its footprint (:class:`TexturePoint`), the
octaves to sum (:class:`Octaves`), the phase the texture computed from its noise
(:class:`Phase`) — and holds the marble's stripe and ramp, never the texture: a texture
is freed with its last reference, not by Python's cycle collector at some later moment.

Each also gives a second estimate of the pixel's colour (:meth:`PixelFilter.colour_and_alternate`),
for adaptive sampling (mimarble/mitsuba/rendering/adaptive.py): the point sample's and the band
limit's is the prefiltered mean over the pixel, the prefilter's the colour at the point
(every octave). The two differ where the colour varies across the footprint, which is where
one sample, or one interval of phase, can be wrong — and agree where the pixel is smooth
enough for either.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from mimarble.runtime import environment
from .fbm import Spectrum, band_limit, fractal3, fractal_band, fractal_over_pixel, left_out
from .prefilter import PhaseAverage

dr, mi = environment.import_drjit_and_mitsuba()

#: Octaves the prefilter keeps past pbrt's Nyquist cut (fbm.band_limit), and the
#: weight of the left-out octaves' phase variance in the squared box width (12: a box of
#: that variance). Chosen by measurement: docs/benchmarks.md, "Prefiltered marble".
PREFILTER_MARGIN = 2.0
PHASE_SPREAD_WIDENING = 12.0
#: Two-point Gauss–Legendre on [−½, ½] (nodes ±1/(2√3), weights ½), across the pixel's
#: short side: on fig11a with 2 octaves, unlit, 1 spp interior RMSE 0.0013 against 0.0019
#: for one box of the same variance (√(a² + b²)); equal with 8 octaves.
GAUSS_NODE = 0.5 / math.sqrt(3.0)


class Octaves(NamedTuple):
    """The octave sum the texture asks for: K' octaves, |N| or N, its gain and lacunarity."""

    count: int
    turbulence: bool
    spectrum: Spectrum


class Noise(NamedTuple):
    """F as a filter takes it. ``value`` None: no noise (distortion 0). Over the pixel
    (``over_pixel``): ∇F and the variance σ² of F the gradient does not describe (the
    octaves left out, |N|'s folds), and ``at_point``, F at the point with every octave
    (for the alternate estimate; None unless asked for)."""

    value: object
    over_pixel: bool = False
    gradient: object = None
    spread: object = 0.0
    at_point: object = None


class Phase(NamedTuple):
    """φ as the texture computed it from a :class:`Noise`; over the pixel also ∇_v φ and
    the variance σ²_φ = distortion²·σ² of the phase the gradient does not describe."""

    value: object
    gradient: object = None
    spread: object = 0.0


class PixelFilter:
    """What every filter is: made for one marble's stripe and ramp, told when the ramp's
    colours change.

    ``DRJIT_STRUCT`` names the Dr.Jit state a filter holds (the phase-average tables, or
    None), so that Dr.Jit's traversal (``dr.freeze``) sees it through the texture."""

    DRJIT_STRUCT: dict = {"average": object}
    needs_footprint = False
    margin = PREFILTER_MARGIN      # the band of the prefiltered estimate

    def __init__(self, stripe, ramp):
        self.stripe, self.ramp = stripe, ramp
        self.average = None      # the phase-average tables, when needed (prefilter, estimates)

    def changed(self) -> None:
        """The ramp's colours changed (a ``mi.traverse`` edit; not their number)."""
        if self.average is not None:
            self.average.update()

    def prepare_alternate(self) -> None:
        """Make the tables :meth:`colour_and_alternate` reads, once, before a kernel that
        asks for it is traced (Dr.Jit evaluates them: not inside a symbolic operation)."""
        if self.average is None:
            self.average = PhaseAverage(self.stripe, self.ramp)

    def at_phase(self, phase: Phase):
        """ramp(t(φ)): the colour at the point."""
        return self.ramp(self.stripe.t(phase.value))

    def over_pixel(self, point, octaves: Octaves | None, with_point: bool) -> Noise:
        """F and ∇F without the octaves finer than the footprint (past :attr:`margin`),
        plus the mean and the variance of those left out; with ``with_point`` also F
        with every octave, from the same loop."""
        if octaves is None:
            return Noise(None, True)
        K, turbulence, spectrum = octaves
        band = band_limit(point.footprint, K, self.margin, spectrum)
        F = fractal_over_pixel(point.v, K, band, (point.dv_dx, point.dv_dy), turbulence,
                               spectrum, with_point)
        mean, variance = left_out(band, K, turbulence, spectrum)
        value = (F.value + mean) if turbulence else F.value
        return Noise(value, True, F.gradient, variance + F.spread, F.point)

    def prefiltered(self, phase: Phase, point):
        """The mean of ramp∘t over the pixel (see :class:`Prefilter`)."""
        grad_phase = phase.gradient
        a, b = dr.abs(dr.dot(grad_phase, point.dv_dx)), dr.abs(dr.dot(grad_phase, point.dv_dy))
        long, short = dr.maximum(a, b), dr.minimum(a, b)
        width = dr.sqrt(dr.square(long) + PHASE_SPREAD_WIDENING * phase.spread)
        below, below_defined = self.average(phase.value - GAUSS_NODE * short, width)
        above, above_defined = self.average(phase.value + GAUSS_NODE * short, width)
        return dr.select(below_defined & above_defined, 0.5 * (below + above),
                         self.at_phase(phase))

    def noise_and_alternate(self, point, octaves: Octaves | None):
        """(the :class:`Noise` of :meth:`colour`, that of the alternate estimate; None: the
        colour is its own alternate)."""
        raise NotImplementedError

    def colour_and_alternate(self, phase: Phase, alternate: Phase | None, point):
        """(the filter's colour, a second estimate of the pixel's colour): see the module
        docstring. ``point`` carries the footprint."""
        raise NotImplementedError


class PointSample(PixelFilter):
    """``none``: the colour at the point."""

    def noise(self, point, octaves: Octaves | None) -> Noise:
        return Noise(None if octaves is None else fractal3(point.v, *octaves))

    def colour(self, phase: Phase, point):
        return self.at_phase(phase)

    def noise_and_alternate(self, point, octaves):
        """F at the point (every octave) and over the pixel, from one octave loop."""
        over_pixel = self.over_pixel(point, octaves, True)
        return Noise(over_pixel.at_point), over_pixel

    def colour_and_alternate(self, phase, alternate, point):
        """The colour at the point, and the prefiltered mean over the pixel."""
        return self.colour(phase, point), self.prefiltered(alternate, point)


class BandLimit(PointSample):
    """``bandlimit``: the octaves finer than the pixel left out of F."""

    needs_footprint = True

    def noise(self, point, octaves: Octaves | None) -> Noise:
        if octaves is None:
            return Noise(None)
        K, turbulence, spectrum = octaves
        band = band_limit(point.footprint, K, spectrum=spectrum)
        return Noise(fractal_band(point.v, K, band, turbulence, spectrum))

    def noise_and_alternate(self, point, octaves):
        """The band-limited F, and F over the pixel for the prefiltered mean."""
        return self.noise(point, octaves), self.over_pixel(point, octaves, False)


class Prefilter(PixelFilter):
    """``prefilter``: the colour averaged over the pixel.

    Across the pixel's box (x, y ∈ [−½, ½]) the phase is, to first order,
    φ + a·x + b·y with a = ∇φ·∂v/∂x, b = ∇φ·∂v/∂y, ∇φ = period·e_a + distortion·∇F.
    Along the longer of the two it is a box of phase of width max(|a|, |b|), averaged
    exactly (mimarble/texture/prefilter.py); across the shorter, two-point Gauss–Legendre. The
    octaves finer than the footprint (past :data:`PREFILTER_MARGIN`) are left out of F;
    their spread of phase, variance distortion²·σ², widens the box by
    :data:`PHASE_SPREAD_WIDENING`·σ² in the square. Where the box is below float32's
    resolution of the phase, the colour at the point.
    """

    needs_footprint = True

    def __init__(self, stripe, ramp):
        super().__init__(stripe, ramp)
        self.prepare_alternate()

    def noise(self, point, octaves: Octaves | None) -> Noise:
        return self.over_pixel(point, octaves, False)

    def colour(self, phase: Phase, point):
        return self.prefiltered(phase, point)

    def noise_and_alternate(self, point, octaves):
        """F over the pixel and F at the point (every octave), from one octave loop.
        Without noise the phase is linear across the pixel, where the prefilter is exact:
        then no alternate (the colour twice: no doubt)."""
        if octaves is None:
            return self.over_pixel(point, None, False), None
        over_pixel = self.over_pixel(point, octaves, True)
        return over_pixel, Noise(over_pixel.at_point)

    def colour_and_alternate(self, phase, alternate, point):
        """The prefiltered colour, and the colour at the point."""
        colour = self.colour(phase, point)
        return colour, (colour if alternate is None else self.at_phase(alternate))


def choose(name: str, stripe, ramp) -> PixelFilter:
    """The filter ``name`` for a marble's ``stripe`` and ``ramp``: every filter needs the
    integrator's ray differentials, which only the JIT variants carry into a texture; the
    scalar variant takes the colour at the point."""
    if not dr.is_jit_v(mi.Float) or ramp.size == 1:   # (one colour: a constant)
        return PointSample(stripe, ramp)
    return {"none": PointSample, "bandlimit": BandLimit, "prefilter": Prefilter}[name](
        stripe, ramp)
