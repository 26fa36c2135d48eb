"""``subsurface_boundary``: the surface of a translucent material, a BSSRDF-style boundary that enters and leaves diffusely (issue 40).

η = int_ior/ext_ior (inside over outside). F(μ) is the exact unpolarised Fresnel
reflectance for light arriving from *outside* at cosine μ (Mitsuba's ``fresnel``), and
F̄ = ∫₀¹ F(μ) 2μ dμ its cosine-weighted hemispherical mean (:func:`mean_fresnel_reflectance`,
computed once on the host: 0 at η = 1, ≈ 0.092 at 1.5). In the shading frame, wᵢ the
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

import numpy as np

from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import describe, plugin

dr, mi = environment.import_drjit_and_mitsuba()

#: Mitsuba's defaults of ``dielectric`` (src/bsdfs/dielectric.cpp: "bk7" inside, "air" outside).
DEFAULT_INT_IOR = 1.5046
DEFAULT_EXT_IOR = 1.000277
#: Gauss–Legendre nodes of F̄'s quadrature (its integrand is smooth: float64 rounding is
#: reached well before this many).
_QUADRATURE_NODES = 64


class SubsurfaceBoundaryError(ValueError):
    """An invalid ``subsurface_boundary``; the message names the parameter."""


def fresnel_from_outside(mu, eta: float) -> np.ndarray:
    """F(μ, η) on the host, float64: the unpolarised reflectance r = (r_s² + r_p²)/2 for
    light from outside at cosine μ ∈ [0, 1], η inside over outside;
    r_s = (μ − η μₜ)/(μ + η μₜ), r_p = (η μ − μₜ)/(η μ + μₜ), μₜ = √(1 − (1 − μ²)/η²); 1
    where sin θₜ would pass 1 (η < 1, past the critical angle) and at μ = 0 (η ≠ 1)."""
    mu = np.clip(np.asarray(mu, dtype=np.float64), 0.0, 1.0)
    sin2_t = (1.0 - mu * mu) / (eta * eta)
    mu_t = np.sqrt(np.maximum(1.0 - sin2_t, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        r_s = (mu - eta * mu_t) / (mu + eta * mu_t)
        r_p = (eta * mu - mu_t) / (eta * mu + mu_t)
        r = 0.5 * (r_s * r_s + r_p * r_p)
    return np.where((sin2_t >= 1.0) | ~np.isfinite(r), 1.0, r) if eta != 1.0 else np.zeros_like(mu)


def mean_fresnel_reflectance(eta: float) -> float:
    """F̄(η) = ∫₀¹ F(μ, η) 2μ dμ, by Gauss–Legendre quadrature. For η ≥ 1 F is smooth on
    [0, 1]. For η < 1, F = 1 below the critical cosine μ_c = √(1 − η²) (2μ integrates to
    1 − η² there) and above it behaves as 1 − c·√(μ − μ_c): the substitution
    μ = μ_c + (1 − μ_c)·t² makes that piece smooth in t ∈ [0, 1]."""
    if eta == 1.0:
        return 0.0
    nodes, weights = np.polynomial.legendre.leggauss(_QUADRATURE_NODES)
    t, w = 0.5 * (nodes + 1.0), 0.5 * weights
    if eta > 1.0:
        return float(np.sum(w * fresnel_from_outside(t, eta) * 2.0 * t))
    critical = math.sqrt(1.0 - eta * eta)
    mu = critical + (1.0 - critical) * t * t
    jacobian = 2.0 * (1.0 - critical) * t
    return critical * critical + float(np.sum(w * jacobian * fresnel_from_outside(mu, eta) * 2.0 * mu))


def _ior(props, name: str, default: float) -> float:
    value = props.get(name, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not (0.0 < value < math.inf):
        raise SubsurfaceBoundaryError(f"subsurface_boundary: {name}={value!r} must be a "
                                      f"positive finite number")
    return float(value)


@plugin("bsdf", "subsurface_boundary")
class SubsurfaceBoundary:
    """The surface of a translucent material: Fresnel-weighted delta reflection outside,
    diffuse entry and Fresnel-weighted diffuse exit (module docstring)."""

    def __init__(self, props):
        mi.BSDF.__init__(self, props)
        self.int_ior = _ior(props, "int_ior", DEFAULT_INT_IOR)
        self.ext_ior = _ior(props, "ext_ior", DEFAULT_EXT_IOR)
        self.eta = self.int_ior / self.ext_ior
        self.mean_reflectance = mean_fresnel_reflectance(self.eta)
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
        return mi.fresnel(mi.Float(mu), self.eta)[0] if dr.is_jit_v(mi.Float) \
            else mi.fresnel(mu, self.eta)[0]

    def _reflect_probability(self, ctx, f_i, outside):
        """The probability of the delta reflection at a point seen from outside: F(μᵢ),
        or 1 / 0 when the context enables only the reflection / only the transmission."""
        reflection = ctx.is_enabled(mi.BSDFFlags.DeltaReflection, 0)
        transmission = ctx.is_enabled(mi.BSDFFlags.DiffuseTransmission, 1)
        if reflection and transmission:
            chance = f_i
        else:
            chance = f_i * 0.0 + (1.0 if reflection else 0.0)
        return dr.select(outside, chance, 0.0)

    def sample(self, ctx, si, sample1, sample2, active=True):
        cos_i = mi.Frame3f.cos_theta(si.wi)
        outside, inside = cos_i > 0.0, cos_i < 0.0
        f_i = self._fresnel(dr.maximum(cos_i, 0.0))
        p_reflect = self._reflect_probability(ctx, f_i, outside)
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
        p_reflect = self._reflect_probability(ctx, f_i, cos_i > 0.0)
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
