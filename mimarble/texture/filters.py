"""How the marble fills a pixel: ``filter none | bandlimit | prefilter``, one class each.

Each turns a texture point (mimarble/texture/mapping.py) into a colour through the
marble's phase, stripe and ramp — at the point, or over the pixel's footprint::

    none:       ramp(t(φ(v)))                     F with every octave the budget keeps
    bandlimit:  ramp(t(φ(v)))                     F without the octaves finer than the
                                                  pixel (pbrt-v4's FBm clamp at octave
                                                  frequencies λ^i), the last faded
    prefilter:  mean of ramp∘t over the pixel's   F and ∇F without the octaves finer than
                interval of phase                 the pixel; their spread widens the interval

Each also gives a second estimate of the pixel's colour (:meth:`PixelFilter.colour_and_alternate`),
for adaptive sampling (mimarble/mitsuba/rendering/adaptive.py): the point sample's and the band
limit's is the prefiltered mean over the pixel, the prefilter's the colour at the point
(every octave). The two differ where the colour varies across the footprint, which is where
one sample, or one interval of phase, can be wrong — and agree where the pixel is smooth
enough for either.

The texture chooses one when its parameters change (:func:`choose`) and hands itself to
it at every evaluation (``marble``, mimarble/mitsuba/plugins/marble.py), read for its parameters as they
are now: a filter holds no reference to its texture, so a texture is freed with its last
reference, not by Python's cycle collector at some later moment.
"""

from __future__ import annotations

import math

from mimarble.runtime import environment
from .fbm import band_limit, fractal3, fractal_band, fractal_over_pixel, left_out
from .prefilter import PhaseAverage

dr, mi = environment.import_drjit_and_mitsuba()

#: Octaves the prefilter keeps past pbrt's Nyquist cut (noise.band_limit), and the
#: weight of the left-out octaves' phase variance in the squared box width (12: a box of
#: that variance). Chosen by measurement: docs/benchmarks.md, "Prefiltered marble".
PREFILTER_MARGIN = 2.0
PHASE_SPREAD_WIDENING = 12.0
#: Two-point Gauss–Legendre on [−½, ½] (nodes ±1/(2√3), weights ½), across the pixel's
#: short side: on fig11a with 2 octaves, unlit, 1 spp interior RMSE 0.0013 against 0.0019
#: for one box of the same variance (√(a² + b²)); equal with 8 octaves.
GAUSS_NODE = 0.5 / math.sqrt(3.0)


class PixelFilter:
    """What every filter is: made for one marble's stripe and ramp, told when the ramp's
    colours change.

    ``DRJIT_STRUCT`` names the Dr.Jit state a filter holds (the phase-average tables, or
    None), so that Dr.Jit's traversal (``dr.freeze``) sees it through the texture."""

    DRJIT_STRUCT: dict = {"average": object}
    needs_footprint = False

    def __init__(self, marble):
        self.stripe, self.ramp = marble.stripe, marble.ramp
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

    def colour_and_alternate(self, m, point):
        """(the filter's colour, a second estimate of the pixel's colour): see the module
        docstring. ``point`` carries the footprint."""
        raise NotImplementedError


class PointSample(PixelFilter):
    """``none``: the colour at the point."""

    def noise(self, m, point):
        return fractal3(point.v, m.octaves_evaluated, m.turbulence, m.spectrum)

    def colour(self, m, point):
        return at_point(m, point, self.noise(m, point) if m.needs_noise else None)

    def colour_and_alternate(self, m, point):
        """The colour at the point, and the prefiltered mean over the pixel (one octave
        loop: :func:`prefiltered_and_at_point`)."""
        mean, colour = prefiltered_and_at_point(self.average, m, point)
        return colour, mean


class BandLimit(PointSample):
    """``bandlimit``: the octaves finer than the pixel left out of F."""

    needs_footprint = True

    def colour_and_alternate(self, m, point):
        """The band-limited colour at the point, and the prefiltered mean over the pixel."""
        return self.colour(m, point), prefiltered(self.average, m, point)

    def noise(self, m, point):
        band = band_limit(point.footprint, m.octaves_evaluated, spectrum=m.spectrum)
        return fractal_band(point.v, m.octaves_evaluated, band, m.turbulence, m.spectrum)


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

    def __init__(self, marble):
        super().__init__(marble)
        self.prepare_alternate()

    def colour(self, m, point):
        return prefiltered(self.average, m, point)

    def colour_and_alternate(self, m, point):
        """The prefiltered colour, and the colour at the point (every octave; one octave
        loop: :func:`prefiltered_and_at_point`). Without noise the phase is linear across
        the pixel, where the prefilter is exact: then the colour twice (no doubt)."""
        if not m.needs_noise:
            colour = self.colour(m, point)
            return colour, colour
        return prefiltered_and_at_point(self.average, m, point)


def at_point(m, point, noise):
    """ramp(t(φ)) at the texture point, φ from the noise ``noise`` (None: none)."""
    return m.ramp(m.stripe.t(m.phase(point.v, noise)))


def prefiltered(average: PhaseAverage, m, point):
    """The prefilter's colour (:class:`Prefilter`), from the phase-average tables."""
    return _prefiltered(average, m, point, False)[0]


def prefiltered_and_at_point(average: PhaseAverage, m, point):
    """(the prefilter's colour, the point sample's — every octave, as :class:`PointSample`
    gives it bit for bit), from one octave loop (``fractal_over_pixel(point=True)``)."""
    return _prefiltered(average, m, point, True)


def _prefiltered(average, m, point, with_point: bool):
    v = point.v
    noise_at_point = None
    if m.needs_noise:
        octaves = m.octaves_evaluated
        band = band_limit(point.footprint, octaves, PREFILTER_MARGIN, m.spectrum)
        F = fractal_over_pixel(v, octaves, band, (point.dv_dx, point.dv_dy), m.turbulence,
                               m.spectrum, with_point)
        mean, variance = left_out(band, octaves, m.turbulence, m.spectrum)
        value = (F.value + mean) if m.turbulence else F.value
        phase = m.phase(v, value)
        grad_phase = m.phase_gradient(F.gradient * m.distortion)
        spread = dr.square(m.distortion) * (variance + F.spread)
        noise_at_point = F.point
    else:
        phase, grad_phase, spread = m.phase(v, None), m.phase_gradient(None), 0.0
    colour_at_point = at_point(m, point, noise_at_point) if with_point else None
    a, b = dr.abs(dr.dot(grad_phase, point.dv_dx)), dr.abs(dr.dot(grad_phase, point.dv_dy))
    long, short = dr.maximum(a, b), dr.minimum(a, b)
    width = dr.sqrt(dr.square(long) + PHASE_SPREAD_WIDENING * spread)
    below, below_defined = average(phase - GAUSS_NODE * short, width)
    above, above_defined = average(phase + GAUSS_NODE * short, width)
    mean = dr.select(below_defined & above_defined, 0.5 * (below + above),
                     m.ramp(m.stripe.t(phase)))
    return mean, colour_at_point


def choose(marble, name: str):
    """The filter ``name`` for ``marble``: every filter needs the integrator's ray
    differentials, which only the JIT variants carry into a texture; the scalar variant
    takes the colour at the point."""
    if not dr.is_jit_v(mi.Float) or marble.ramp.size == 1:   # (one colour: a constant)
        return PointSample(marble)
    return {"none": PointSample, "bandlimit": BandLimit, "prefilter": Prefilter}[name](marble)

