"""``subsurface_boundary``: the surface of a translucent material, a BSSRDF-style boundary that enters and leaves diffusely (issue 40).

η = int_ior/ext_ior (inside over outside). F(μ) is the exact unpolarised Fresnel
reflectance for light arriving from *outside* at cosine μ (Mitsuba's ``fresnel``), and
F̄ = ∫₀¹ F(μ) 2μ dμ its cosine-weighted hemispherical mean (
:func:`~mimarble.mitsuba.plugins.subsurface_reflectance.diffuse_fresnel_reflectance`, computed once on the host: 0 at η = 1, ≈ 0.092 at 1.5). In the shading frame, wᵢ the
direction towards where the path came from, μᵢ = cos θᵢ, μₒ = cos θₒ:

* **From outside** (μᵢ > 0): with probability F(μᵢ) the mirror direction (a delta
  reflection, weight 1); else the path *enters*, its direction cosine-distributed about
  the inward normal (Lambertian transmission, weight 1). The entering lobe's value is
  f = (1 − F(μᵢ))/π (times |μₒ|), its pdf (1 − F(μᵢ))·|μₒ|/π.
* **From inside** (μᵢ < 0): the path always *leaves*, its direction cosine-distributed
  about the outward normal, weight W(μₒ) = (1 − F(μₒ))/(1 − F̄). The lobe's value is
  f = (1 − F(μₒ))/((1 − F̄)π), so ∫ f μₒ dω = 1 (nothing is lost or reflected back), its
  pdf μₒ/π.

Both transmission lobes are smooth, so ``volpath`` does next-event estimation at the point
where a walk leaves — to point lights, area lights and the environment, with MIS — as
BSSRDF renderers connect the exit point to the lights (pbrt-v3's SeparableBSSRDF, whose
weights these are). What the model gives up: no refraction (no caustics or images seen
through the boundary) and no internal reflection (its effect on the walk is carried by F̄
and the direction's inversion); docs/rendering-model.md, "Translucent materials". ``eta``
of every sample is 1: the radiance scale 1/η² of a crossing cancels between the entry and
the exit of a walk. The lobes are written for radiance transport (camera paths, what
``volpath`` traces); the model is not reciprocal (the exit lobe's 1/(1 − F̄)), so light
tracing would need the adjoint.

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Description
   * - ``int_ior``
     - float (1.5046, Mitsuba's ``bk7``)
     - Index of refraction of the interior (a number, as Mitsuba's ``dielectric``).
   * - ``ext_ior``
     - float (1.000277, Mitsuba's ``air``)
     - Index of refraction of the exterior.

Flags: ``DeltaReflection | FrontSide`` (component 0, the specular coat) and
``DiffuseTransmission | FrontSide | BackSide`` (component 1, entering and leaving). η is a
constant of the traced code (its ``recording_key``), not a traversed parameter.
"""

from __future__ import annotations

import math

from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import describe, plugin
from mimarble.mitsuba.plugins.subsurface_reflectance import diffuse_fresnel_reflectance

dr, mi = environment.import_drjit_and_mitsuba()

#: Mitsuba's defaults of ``dielectric`` (src/bsdfs/dielectric.cpp: "bk7" inside, "air" outside).
DEFAULT_INT_IOR = 1.5046
DEFAULT_EXT_IOR = 1.000277


class SubsurfaceBoundaryError(ValueError):
    """An invalid ``subsurface_boundary``; the message names the parameter."""


def ior_property(props, name: str, default: float, plugin_name: str = "subsurface_boundary",
         error=None) -> float:
    """A positive finite index of refraction ``name`` (``default`` when not given), else
    ``error`` (default :class:`SubsurfaceBoundaryError`) naming the plugin."""
    value = props.get(name, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not (0.0 < value < math.inf):
        raise (error or SubsurfaceBoundaryError)(f"{plugin_name}: {name}={value!r} must be a "
                                                 f"positive finite number")
    return float(value)


def fresnel_from_outside(mu, eta: float):
    """F(μ, η) for μ ≥ 0, light arriving from outside (``mi.fresnel``), in the kernel."""
    return mi.fresnel(mi.Float(mu), eta)[0] if dr.is_jit_v(mi.Float) else mi.fresnel(mu, eta)[0]


def mirror_probability(ctx, fresnel, other_lobe):
    """The chance of a Fresnel mirror (component 0) against the BSDF's other lobe (component
    1, of flag ``other_lobe``): F(μᵢ), or 1 / 0 when the context enables only the mirror /
    only the other lobe (Mitsuba's component selection)."""
    mirror = ctx.is_enabled(mi.BSDFFlags.DeltaReflection, 0)
    other = ctx.is_enabled(other_lobe, 1)
    return fresnel if mirror and other else fresnel * 0.0 + (1.0 if mirror else 0.0)


@plugin("bsdf", "subsurface_boundary")
class SubsurfaceBoundary:
    """The surface of a translucent material: Fresnel-weighted delta reflection outside,
    diffuse entry and Fresnel-weighted diffuse exit (module docstring)."""

    def __init__(self, props):
        mi.BSDF.__init__(self, props)
        self.int_ior = ior_property(props, "int_ior", DEFAULT_INT_IOR)
        self.ext_ior = ior_property(props, "ext_ior", DEFAULT_EXT_IOR)
        self.eta = self.int_ior / self.ext_ior
        self.mean_reflectance = diffuse_fresnel_reflectance(self.eta)
        # W(μₒ) = (1 − F(μₒ))·exit_scale: F̄ < 1 for every finite η > 0
        self.exit_scale = 1.0 / (1.0 - self.mean_reflectance)
        reflection = mi.BSDFFlags.DeltaReflection | mi.BSDFFlags.FrontSide
        transmission = mi.BSDFFlags.DiffuseTransmission | mi.BSDFFlags.FrontSide \
            | mi.BSDFFlags.BackSide
        self.m_components = [reflection, transmission]
        self.m_flags = reflection | transmission

    # -- the lobes ---------------------------------------------------------------

    def _fresnel(self, mu):
        """F(μ) for μ ≥ 0 (light from outside), in the kernel."""
        return fresnel_from_outside(mu, self.eta)

    def sample(self, ctx, si, sample1, sample2, active=True):
        cos_i = mi.Frame3f.cos_theta(si.wi)
        outside, inside = cos_i > 0.0, cos_i < 0.0
        f_i = self._fresnel(dr.maximum(cos_i, 0.0))
        p_reflect = dr.select(outside, mirror_probability(
            ctx, f_i, mi.BSDFFlags.DiffuseTransmission), 0.0)
        transmission = ctx.is_enabled(mi.BSDFFlags.DiffuseTransmission, 1)
        reflect = outside & (sample1 < p_reflect)
        diffuse = mi.warp.square_to_cosine_hemisphere(sample2)            # about +z
        cos_d = mi.Frame3f.cos_theta(diffuse)
        mirror = mi.Vector3f(-si.wi.x, -si.wi.y, si.wi.z)
        wo = dr.select(reflect, mirror,
                       dr.select(outside, mi.Vector3f(diffuse.x, diffuse.y, -diffuse.z), diffuse))
        lobe_pdf = cos_d * dr.inv_pi
        # weights: reflection F/P(reflect) = 1, entry (1 − F)/(1 − P(reflect)) = 1 (each
        # exactly 1 when both components are enabled), exit W(μₒ) = (1 − F(μₒ))/(1 − F̄)
        f_o = self._fresnel(cos_d)
        weight = dr.select(reflect, f_i / dr.maximum(p_reflect, 1e-30),
                           dr.select(outside, (1.0 - f_i) / dr.maximum(1.0 - p_reflect, 1e-30),
                                     (1.0 - f_o) * self.exit_scale))
        bs = dr.zeros(mi.BSDFSample3f)
        bs.wo = wo
        bs.pdf = dr.select(reflect, p_reflect,
                           dr.select(outside, (1.0 - p_reflect) * lobe_pdf, lobe_pdf))
        bs.eta = 1.0
        bs.sampled_type = dr.select(reflect, mi.UInt32(+mi.BSDFFlags.DeltaReflection),
                                    mi.UInt32(+mi.BSDFFlags.DiffuseTransmission))
        bs.sampled_component = dr.select(reflect, mi.UInt32(0), mi.UInt32(1))
        ok = active & (outside | (inside & transmission)) & (bs.pdf > 0.0)
        if not transmission:
            ok &= reflect
        bs.pdf = dr.select(ok, bs.pdf, 0.0)
        return bs, mi.Spectrum(dr.select(ok, weight, 0.0))

    def _smooth(self, ctx, si, wo, active):
        """(value of the transmission lobes · |μₒ|, their pdf) for ``wo``: the entering lobe
        from outside, the exit lobe from inside, 0 elsewhere (the delta reflection has no
        value at a given direction)."""
        cos_i = mi.Frame3f.cos_theta(si.wi)
        cos_o = mi.Frame3f.cos_theta(wo)
        entering = (cos_i > 0.0) & (cos_o < 0.0)
        leaving = (cos_i < 0.0) & (cos_o > 0.0)
        ok = active & (entering | leaving) \
            & ctx.is_enabled(mi.BSDFFlags.DiffuseTransmission, 1)
        abs_o = dr.abs(cos_o)
        f_i = self._fresnel(dr.maximum(cos_i, 0.0))
        f_o = self._fresnel(dr.maximum(cos_o, 0.0))
        value = dr.select(entering, 1.0 - f_i, (1.0 - f_o) * self.exit_scale) * abs_o * dr.inv_pi
        p_reflect = dr.select(cos_i > 0.0, mirror_probability(
            ctx, f_i, mi.BSDFFlags.DiffuseTransmission), 0.0)
        pdf = dr.select(entering, 1.0 - p_reflect, 1.0) * abs_o * dr.inv_pi
        return dr.select(ok, value, 0.0), dr.select(ok, pdf, 0.0)

    def eval(self, ctx, si, wo, active=True):
        return mi.Spectrum(self._smooth(ctx, si, wo, active)[0])

    def pdf(self, ctx, si, wo, active=True):
        return self._smooth(ctx, si, wo, active)[1]

    def eval_pdf(self, ctx, si, wo, active=True):
        value, pdf = self._smooth(ctx, si, wo, active)
        return mi.Spectrum(value), pdf

    # -- Mitsuba object protocol -----------------------------------------------

    def traverse(self, cb):
        """Nothing to edit: η decides F̄, computed once on the host."""

    def recording_key(self) -> tuple:
        """η and F̄ are constants of the traced code: a replay needs the same."""
        return ("subsurface_boundary", self.eta)

    def to_string(self):
        return describe("SubsurfaceBoundary", {"int_ior": self.int_ior, "ext_ior": self.ext_ior,
                                               "mean_fresnel_reflectance": self.mean_reflectance})
