"""The ``marble`` texture: the paper's ChannelMarble as a Mitsuba 3 texture.

    v = scale · to_world⁻¹ · p                          (mimarble/texture/mapping.py)
    F(v) = Σ_{i<K} ω^i N(λ^i v)   (the paper: ω = ½, λ = 2)   (mimarble/texture/noise.py)
    φ = period·v_a + distortion·F(v),   t = t(φ)         (mimarble/texture/stripes.py)
    colour = ramp(t)   (evenly spaced, or at positions)  (mimarble/texture/ramp.py)

filtered over the pixel's footprint as ``filter`` says (mimarble/texture/filters.py), with
the octaves the error budget keeps (mimarble/texture/error_budget.py). The class is the
formula; its values, their edits and what they decide are its base's
(mimarble/mitsuba/plugins/marble_update.py). The parameters — names,
defaults, ranges, roles — are the table of mimarble/parameters.py, also printed
in ``help(Marble)``. What the texture does not need it does not compute: no noise when
``distortion`` is 0 (and not being differentiated), no transform when ``to_world`` is
not given, a constant when the ramp has one colour.
"""

from __future__ import annotations

import warnings

from mimarble.runtime import environment
from mimarble.texture import srgb_model
from mimarble.texture.filters import Noise, Octaves, Phase
from mimarble.texture.finite_arithmetic import finite_product
from mimarble.parameters import ParameterError, parameter_table
from mimarble.texture.fbm import fractal_gradient
from mimarble.mitsuba.plugins.registration import RGBTexture, plugin
from mimarble.mitsuba.plugins.marble_update import MarbleUpdates
from mimarble.texture.mapping import (NoFootprintWarning, footprints_omitted,
    no_footprint_message, without_footprint)

dr, mi = environment.import_drjit_and_mitsuba()


@plugin("texture", "marble")
class Marble(MarbleUpdates, RGBTexture):
    __doc__ = ("Marble solid texture (Park & Park 2004): see mimarble/mitsuba/plugins/marble.py.\n\n"
               + parameter_table() + "\n\nAlso ``to_world`` (transform, identity): places the "
               "texture in the world; must be invertible; always in ``mi.traverse``, not "
               "differentiable.")

    def __init__(self, props):
        mi.Texture.__init__(self, props)
        variant_problem = srgb_model.variant_problem("marble")
        if variant_problem:
            raise ParameterError(variant_problem)
        # Spectral variants: the model that turns the colour into a spectrum, held (see
        # RGBTexture.eval and mimarble/texture/srgb_model.py); None elsewhere.
        self.srgb_table = srgb_model.model_table()
        self._read_properties(props)

    def is_spatially_varying(self):
        return self.ramp.size > 1

    def mean(self):
        """The mean luminance where the phase is spread uniformly (mimarble/texture/ramp.py);
        differentiable with respect to the ramp. Spectral variants: ``srgb_model_mean`` (the
        sRGB model's spectrum averaged over 16 wavelengths evenly spaced over 360–830 nm) of
        the one spectrum of that mean colour — what ``srgb`` answers for that colour, but not
        what ``bitmap`` answers (the mean of its texels' spectral means): the model is not
        linear, so a red–blue ramp gives 0.661 where its two colours' spectral means average
        0.544."""
        if mi.is_spectral:
            return srgb_model.mean(self.srgb_table, self.ramp.mean(self.stripe))
        return mi.luminance(self.ramp.mean(self.stripe))

    # -- Evaluation ------------------------------------------------------------

    def phase(self, v, F=None):
        """φ = period·v_a + distortion·F (cosine: v_a + distortion·F); F None: no noise."""
        noise = 0.0 if F is None else finite_product(self.distortion, F)
        return self.stripe.phase(v, self.axis_index, self.period, noise)

    def phase_gradient(self, v, noise_gradient=None):
        """∇_v φ, given distortion·∇F (None: no noise)."""
        return self.stripe.phase_gradient(v, self.axis_index, self.period, noise_gradient)

    def eval_3(self, si, active=True):
        """The colour at ``si``; 0 where ``active`` is False, as Mitsuba's ``bitmap``
        gives (every lookup is in bounds by construction, so none needs the mask).
        ``eval`` is this colour, or in spectral variants its spectrum (RGBTexture.eval).
        The formula, in order; the filter decides how a pixel differs from a point."""
        if self.ramp.size == 1:            # a constant: no noise, no ramp interpolation
            return self._kept_attached(dr.select(active, dr.select(
                self._defined(True), self.ramp.constant(dr.width(si.p)), dr.nan), 0.0))
        self._warn_without_footprint(si)
        point = self.mapping.map(si, self.pixel_filter.needs_footprint)  # v = scale·M⁻¹·p
        noise = self.pixel_filter.noise(point, self._octaves())           # F(v)
        phase = self._phase(point.v, noise)                   # φ = period·v_a + distortion·F
        colour = self.pixel_filter.colour(phase, point)       # ramp(t(φ)), or its pixel mean
        return self._shown(colour, point, active)

    def _octaves(self) -> Octaves | None:
        """The octave sum F the filter computes (None: no noise needed)."""
        return Octaves(self.octaves_evaluated, self.turbulence, self.spectrum) \
            if self.needs_noise else None

    def _phase(self, v, noise: Noise) -> Phase:
        """φ from the filter's noise; over the pixel also ∇φ and σ²_φ = distortion²·σ²."""
        value = self.phase(v, noise.value)
        if not noise.over_pixel:
            return Phase(value)
        if noise.value is None:
            return Phase(value, self.phase_gradient(v), 0.0)
        return Phase(value, self.phase_gradient(v, noise.gradient * self.distortion),
                     dr.square(self.distortion) * noise.spread)

    def _shown(self, colour, point, active):
        """The colour as eval returns it: NaN at a NaN or infinite point — decided here once
        rather than left to how each backend's min/max and float→int conversions treat
        NaN (they differ) — or while a value on the device breaks its rule; 0 where
        ``active`` is False."""
        return self._kept_attached(dr.select(active, dr.select(
            self._defined(point.finite), colour, dr.nan), 0.0))

    def _warn_without_footprint(self, si) -> None:
        """Once per texture: a filter that needs a footprint, given none."""
        if self.pixel_filter.needs_footprint and not self._quiet_about_footprints.value \
                and not footprints_omitted():
            self._quiet_about_footprints.value = True
            if without_footprint(si):
                warnings.warn(no_footprint_message(self.id(), self.filter), NoFootprintWarning,
                              stacklevel=3)

    def prepare_alternate(self) -> None:
        """Make what :meth:`eval_and_alternate` reads (the phase-average tables), before a
        kernel that calls it is traced."""
        if self.ramp.size > 1:
            self.pixel_filter.prepare_alternate()

    def eval_and_alternate(self, si, active=True):
        """(:meth:`eval`'s colour, a second estimate of the pixel's colour): the filter's
        other view of the footprint (mimarble/texture/filters.py) — the prefiltered mean for a
        point sample, the colour at the point for a filtered marble. Their difference is
        the marble's own estimate of how wrong one sample of it can be here, which
        adaptive sampling reads (mimarble/mitsuba/rendering/adaptive.py). Needs the footprint (ray
        differentials) and :meth:`prepare_alternate` first."""
        if self.ramp.size == 1 or self.pixel_filter.average is None:
            # A constant; or a marble not prepared (another scene's, traced by a symbolic
            # call over every live material): one estimate.
            colour = self.eval_3(si, active)          # (kept attached there)
            return colour, colour
        point = self.mapping.map(si, True)
        noise, other = self.pixel_filter.noise_and_alternate(point, self._octaves())
        phase = self._phase(point.v, noise)
        alternate = None if other is None else self._phase(point.v, other)
        colour, alternate = self.pixel_filter.colour_and_alternate(phase, alternate, point)
        return tuple(self._shown(c, point, active) for c in (colour, alternate))

    def eval_1_grad(self, si, active=True):
        """∂(luminance)/∂(u, v), exact, by the chain rule (what Mitsuba's ``bumpmap`` reads):

            ∇_p lum = lum(ramp′(t)) · t′(φ) · scale · (period·e_a + distortion·∇F(v)),

        mapped to world space by ``to_world``'s inverse transpose, then dotted with
        ∂p/∂u and ∂p/∂v; ∇F with F, in one pass, over every evaluated octave (filters
        act on the colour, not on its derivative).
        """
        if self.ramp.size == 1:
            return dr.zeros(mi.Vector2f, dr.width(si.p))
        v = self.mapping.point(si.p)
        if self.needs_noise:
            F = fractal_gradient(v, self.octaves_evaluated, self.turbulence, self.spectrum)
            phase = self.phase(v, F.value)
            grad_phase = self.phase_gradient(v, F.gradient * self.distortion)
        else:
            phase, grad_phase = self.phase(v), self.phase_gradient(v)
        slope = mi.luminance(self.ramp.slope(self.stripe.t(phase)))
        gradient = self.mapping.gradient_to_world(
            (slope * self.stripe.slope(phase) * self.scale) * grad_phase)
        return dr.select(self._defined(True), mi.Vector2f(dr.dot(gradient, si.dp_du),
                                                         dr.dot(gradient, si.dp_dv)), dr.nan)


