"""``subsurface_preview``: a translucent material's fast preview, a BSDF that returns the light where it entered (issue 40).

The random walk's local limit: let the mean free path go to 0 and a walk that enters at a
point leaves at that point, with the probability A(p) that a walk in a semi-infinite
medium of the point's colour comes back out (its spherical albedo). What is left is a
surface: ``subsurface_boundary``'s Fresnel coat and, in place of its entry, the walk and
its exit, one diffuse reflection lobe. η = int_ior/ext_ior, F(μ) Fresnel's unpolarised
reflectance for light arriving from outside at cosine μ (``mi.fresnel``), F̄ its
cosine-weighted mean (:func:`~mimarble.mitsuba.plugins.subsurface_reflectance.diffuse_fresnel_reflectance`,
once on the host); in the shading frame, μᵢ = cos θᵢ > 0, μₒ = cos θₒ > 0:

* with probability F(μᵢ) the mirror direction (a delta reflection, weight 1), as the
  boundary's coat;
* else a cosine-distributed direction about the normal, the lobe

      f(ωᵢ, ωₒ) = (1 − F(μᵢ))·A(p)·(1 − F(μₒ)) / ((1 − F̄)·π)

  — the boundary's entry (1 − F(μᵢ)), the walk's return A(p), the boundary's normalised
  exit (1 − F(μₒ))/(1 − F̄) — so ∫ f μₒ dω = (1 − F(μᵢ))·A(p): its sample weight is
  A(p)·(1 − F(μₒ))/(1 − F̄), its pdf (1 − F(μᵢ))·μₒ/π. Symmetric in ωᵢ and ωₒ: no adjoint.

A(p), per component, from the texture at the surface point:

* ``reflectance`` C: A = clamp((C − F̄)/(1 − F̄), 0, 1), what the reflectance inversion
  makes the walk return (:func:`~mimarble.mitsuba.plugins.subsurface_reflectance.spherical_albedo_seen`),
  so that a thick object under even light shows on its silhouette's mean
  F̄ + (1 − F̄)·A = C, as the walk does;
* ``albedo`` α (single-scattering): van de Hulst's A(α) = (1 − s)(1 − 0.139 s)/(1 + 1.17 s),
  s = √(1 − α) (:func:`~mimarble.mitsuba.plugins.subsurface_reflectance.spherical_albedo`).

What it leaves out is all the walk carries *across* the surface: light entering at one
point and leaving at another (the blur of the veins, the softening of shadow edges), and
light through thin parts (a back-lit tile does not glow). docs/rendering-model.md, "The
fast preview", measures its speed and its difference from the walk. One-sided, as
Mitsuba's BSDFs are (the translator wraps it in ``twosided`` where a shape is seen from
both sides).

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Description
   * - ``reflectance``
     - texture, colour or float
     - The colour seen C (as a subsurface's and ``marble_medium``'s). Not with ``albedo``.
   * - ``albedo``
     - texture, colour or float
     - Instead: the single-scattering albedo α. Exactly one of the two.
   * - ``int_ior``, ``ext_ior``
     - float (1.5046, 1.000277)
     - The boundary's indices, as ``subsurface_boundary``'s.

Flags: ``DeltaReflection | FrontSide`` (component 0, the coat) and ``DiffuseReflection |
FrontSide | SpatiallyVarying`` (component 1, what the walk returns).
"""

from __future__ import annotations

from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import describe, plugin, recording_key
from mimarble.mitsuba.plugins.subsurface_boundary import (DEFAULT_EXT_IOR, DEFAULT_INT_IOR,
                                                          SubsurfaceBoundaryError, ior_property,
                                                          fresnel_from_outside, mirror_probability)
from mimarble.mitsuba.plugins.subsurface_reflectance import (diffuse_fresnel_reflectance,
                                                             spherical_albedo,
                                                             spherical_albedo_seen)

dr, mi = environment.import_drjit_and_mitsuba()


class SubsurfacePreviewError(SubsurfaceBoundaryError):
    """An invalid ``subsurface_preview``; the message names the parameter."""


@plugin("bsdf", "subsurface_preview")
class SubsurfacePreview:
    """A translucent material's fast preview: the boundary's Fresnel coat over a diffuse
    lobe of the walk's spherical albedo (module docstring)."""

    def __init__(self, props):
        mi.BSDF.__init__(self, props)
        given = [name for name in ("reflectance", "albedo") if name in props]
        if len(given) != 1:
            raise SubsurfacePreviewError(
                "subsurface_preview: give reflectance (the colour seen) or albedo "
                "(single-scattering), " + ("not both" if given else "one of them"))
        self.kind = given[0]
        self.texture = props.get_texture(self.kind)
        self.int_ior = ior_property(props, "int_ior", DEFAULT_INT_IOR, "subsurface_preview",
                            SubsurfacePreviewError)
        self.ext_ior = ior_property(props, "ext_ior", DEFAULT_EXT_IOR, "subsurface_preview",
                            SubsurfacePreviewError)
        self.eta = self.int_ior / self.ext_ior
        self.mean_reflectance = diffuse_fresnel_reflectance(self.eta)
        self.exit_scale = 1.0 / (1.0 - self.mean_reflectance)     # F̄ < 1 for finite η > 0
        coat = mi.BSDFFlags.DeltaReflection | mi.BSDFFlags.FrontSide
        diffuse = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide \
            | mi.BSDFFlags.SpatiallyVarying
        self.m_components = [coat, diffuse]
        self.m_flags = coat | diffuse

    # -- the lobes ---------------------------------------------------------------

    def _albedo(self, si, active):
        """A(p) per component (module docstring), from the texture at the surface point."""
        colour = mi.UnpolarizedSpectrum(self.texture.eval(si, active))
        if self.kind == "reflectance":
            return spherical_albedo_seen(colour, self.mean_reflectance)
        return spherical_albedo(colour)

    def sample(self, ctx, si, sample1, sample2, active=True):
        cos_i = mi.Frame3f.cos_theta(si.wi)
        f_i = fresnel_from_outside(dr.maximum(cos_i, 0.0), self.eta)
        p_coat = mirror_probability(ctx, f_i, mi.BSDFFlags.DiffuseReflection)
        mirror = sample1 < p_coat
        wo = mi.warp.square_to_cosine_hemisphere(sample2)
        cos_o = mi.Frame3f.cos_theta(wo)
        bs = dr.zeros(mi.BSDFSample3f)
        bs.wo = dr.select(mirror, mi.Vector3f(-si.wi.x, -si.wi.y, si.wi.z), wo)
        bs.pdf = dr.select(mirror, p_coat, (1.0 - p_coat) * cos_o * dr.inv_pi)
        bs.eta = 1.0
        bs.sampled_type = dr.select(mirror, mi.UInt32(+mi.BSDFFlags.DeltaReflection),
                                    mi.UInt32(+mi.BSDFFlags.DiffuseReflection))
        bs.sampled_component = dr.select(mirror, mi.UInt32(0), mi.UInt32(1))
        ok = active & (cos_i > 0.0) & (bs.pdf > 0.0)
        if not ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 1):
            ok &= mirror
        bs.pdf = dr.select(ok, bs.pdf, 0.0)
        # weights: the mirror F/P(coat) (1 with both lobes); the lobe f·μₒ/pdf =
        # (1 − F(μᵢ))/(1 − P(coat))·A·(1 − F(μₒ))/(1 − F̄) (the first factor 1 with both)
        diffuse = ok & (sample1 >= p_coat)              # (not ~mirror: a bool in scalar_rgb)
        lobe = (1.0 - f_i) / dr.maximum(1.0 - p_coat, 1e-30) \
            * (1.0 - fresnel_from_outside(cos_o, self.eta)) * self.exit_scale
        weight = dr.select(mirror, mi.UnpolarizedSpectrum(f_i / dr.maximum(p_coat, 1e-30)),
                           lobe * self._albedo(si, diffuse))
        return bs, mi.Spectrum(dr.select(ok, weight, 0.0))

    def _lobe(self, ctx, si, wo, active):
        """(the diffuse lobe's value f·μₒ without A, its pdf, where it is nonzero) at ``wo``
        (the mirror, a delta, has no value at a given direction)."""
        cos_i = mi.Frame3f.cos_theta(si.wi)
        cos_o = mi.Frame3f.cos_theta(wo)
        ok = active & (cos_i > 0.0) & (cos_o > 0.0) \
            & ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 1)
        f_i = fresnel_from_outside(dr.maximum(cos_i, 0.0), self.eta)
        value = (1.0 - f_i) * (1.0 - fresnel_from_outside(dr.maximum(cos_o, 0.0), self.eta)) \
            * self.exit_scale * cos_o * dr.inv_pi
        p_coat = mirror_probability(ctx, f_i, mi.BSDFFlags.DiffuseReflection)
        pdf = (1.0 - p_coat) * cos_o * dr.inv_pi
        return dr.select(ok, value, 0.0), dr.select(ok, pdf, 0.0), ok

    def eval(self, ctx, si, wo, active=True):
        value, _, ok = self._lobe(ctx, si, wo, active)
        return mi.Spectrum(dr.select(ok, value * self._albedo(si, ok), 0.0))

    def pdf(self, ctx, si, wo, active=True):
        return self._lobe(ctx, si, wo, active)[1]

    def eval_pdf(self, ctx, si, wo, active=True):
        value, pdf, ok = self._lobe(ctx, si, wo, active)
        return mi.Spectrum(dr.select(ok, value * self._albedo(si, ok), 0.0)), pdf

    def eval_diffuse_reflectance(self, si, active=True):
        """A(p): what the walk returns of the light that enters."""
        return mi.Spectrum(self._albedo(si, active))

    # -- Mitsuba object protocol -----------------------------------------------

    def traverse(self, cb):
        cb.put(self.kind, self.texture, mi.ParamFlags.Differentiable)

    def recording_key(self) -> tuple:
        """η and F̄ are constants of the traced code, and which colour, and its texture's key."""
        return ("subsurface_preview", self.eta, self.kind, recording_key(self.texture))

    def to_string(self):
        return describe("SubsurfacePreview", {self.kind: self.texture, "int_ior": self.int_ior,
                                              "ext_ior": self.ext_ior,
                                              "mean_fresnel_reflectance": self.mean_reflectance})
