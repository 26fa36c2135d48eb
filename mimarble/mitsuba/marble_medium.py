"""``marble_medium``: a heterogeneous scattering medium whose albedo and density are textures
(issue 26, "Translucent marble": a material's ``subsurface``, rendered by ``volpath``).

At a point p inside (mimarble/scene/model.py, ``Subsurface``)::

    d(p)   = clamp(mean(density(p)), 0, density_bound)   (1 everywhere without a density)
    σ_t(p) = scale · d(p)                                 (scale = 1 / mean_free_path)
    α(p)   = clamp(albedo(p), 0, 1)  componentwise
    σ_s    = α · σ_t,    σ_n = σ̄ − σ_t,    σ̄ = scale · density_bound   (the majorant)

Mitsuba samples a tentative collision at rate σ̄ (``Medium::sample_interaction``) and keeps
it as a real one with probability σ_t/σ̄ (delta tracking): σ̄ ≥ σ_t everywhere is what makes
that unbiased, hence the clamp of d to the bound — a bound below the density renders the
clipped medium rather than negative null probabilities. The same σ̄ in every channel and
``has_spectral_extinction`` False (one scalar density) let ``volpath`` weigh a real
collision by σ_s/σ_t = α alone. A constant density at its bound has σ_n = 0: no null
collisions, the homogeneous medium's random walk exactly.

The textures are any Mitsuba textures (``marble``, ``channel_expression``, ``rgb``,
``srgb``, …), evaluated at a :class:`SurfaceInteraction3f` holding only the point (and
time, wavelengths): no normal, (u, v) = (0, 0), no footprint (``duv_dx``, ``duv_dy`` are
zero; a filtered marble is its colour at the point, as under Mitsuba's own integrators).
Each texture carries its own placement (a marble's ``to_world``), so the medium has no
transform of its own. The medium is unbounded (``intersect_aabb``: [0, ∞) for every ray,
as ``homogeneous``): the shape whose ``interior`` it is bounds it.

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Description
   * - ``albedo``
     - texture, colour or float
     - Single-scattering albedo α, clamped to [0, 1] per component (default 0.75, as
       Mitsuba's media). Traversed as ``albedo.…``, differentiable through the texture.
   * - ``density``
     - texture (optional)
     - d before the clamp: the mean of its three components (none: 1 everywhere).
       Traversed as ``density.…``, differentiable.
   * - ``scale``
     - float > 0 (default 1)
     - σ_t = scale · d, in inverse scene units. Traversed, differentiable, the majorant
       with it (below).
   * - ``density_bound``
     - float ≥ 0
     - An upper bound of d (default: 1 without a density, else the density texture's
       ``max()``, recomputed after an edit). Traversed, not differentiable.
   * - ``sample_emitters``
     - bool (default true)
     - Mitsuba's: shadow rays from inside (useless behind a smooth dielectric).
   * - (nested)
     - phase function
     - Mitsuba's: default ``isotropic``; a microflake phase is refused (its σ_t would need
       its projected area, which this medium does not apply).
"""

from __future__ import annotations

import math

from .. import environment
from ..plugins import describe, first_number, plugin, recording_key
from ..scene.limits import FLT_MAX

dr, mi = environment.import_drjit_and_mitsuba()

#: Mitsuba's default single-scattering albedo of its media (src/media/homogeneous.cpp).
DEFAULT_ALBEDO = 0.75


class MarbleMediumError(ValueError):
    """An invalid ``marble_medium``; the message names the parameter."""


def _number_problem(name: str, value, least: float, strict: bool) -> str | None:
    """What is wrong with a number that must be finite and > (or ≥) ``least``, or None."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value) or (value <= least if strict else value < least):
        return (f"marble_medium: {name}={value!r} must be a finite number "
                f"{'>' if strict else '≥'} {least:g}")
    return None


def _held(value: float):
    """A traversed number in a container ``mi.traverse`` can write into, in every variant:
    ``mi.Float`` in JIT variants, a one-element ``ArrayXf`` in scalar_rgb (where mi.Float is
    a Python float)."""
    return mi.Float(value) if dr.is_jit_v(mi.Float) else dr.scalar.ArrayXf([value])


@plugin("medium", "marble_medium")
class MarbleMedium:
    """Heterogeneous medium with texture albedo and density: see
    mimarble/mitsuba/marble_medium.py for the parameters and the math."""

    def __init__(self, props):
        # The base takes the nested phase function (else makes an isotropic one) and
        # sample_emitters; it leaves the two flags below to the subclass.
        mi.Medium.__init__(self, props)
        if not mi.variant().endswith("_rgb"):
            raise MarbleMediumError(f"marble_medium: variant {mi.variant()} is not supported; "
                                    f"use an RGB variant (llvm_ad_rgb, cuda_ad_rgb, scalar_rgb)")
        self.m_is_homogeneous = False          # d varies: null collisions, a full intersection
        self.m_has_spectral_extinction = False  # one scalar density: σ̄ is grey
        phase = self.phase_function()
        if mi.has_flag(phase.flags(), mi.PhaseFunctionFlags.Microflake):
            raise MarbleMediumError("marble_medium: a microflake phase function is not "
                                    "supported; use isotropic (the default) or hg")
        self.albedo = props.get_texture("albedo") if "albedo" in props \
            else mi.load_dict({"type": "uniform", "value": DEFAULT_ALBEDO})
        self.density = props.get_texture("density") if "density" in props else None
        scale = props.get("scale", 1.0)
        problem = _number_problem("scale", scale, 0.0, strict=True)
        self._bound_given = "density_bound" in props
        bound = props.get("density_bound") if self._bound_given else self._default_bound()
        problem = problem or _number_problem("density_bound", bound, 0.0, strict=False)
        if problem:
            raise MarbleMediumError(problem)
        self.editable = {"scale": _held(float(scale)), "density_bound": _held(float(bound))}
        self.parameters_changed([])

    def _default_bound(self) -> float:
        """1 without a density texture (d = 1); else the texture's ``max()``, an upper bound
        of every component, hence of their mean."""
        if self.density is None:
            return 1.0
        try:
            return max(0.0, first_number(self.density.max()))
        except RuntimeError:         # Texture::max(): not implemented (checkerboard, …)
            raise MarbleMediumError(f"marble_medium: the density texture "
                                    f"({self.density.class_name()}) gives no max(); "
                                    f"give density_bound") from None

    # -- Mitsuba object protocol -------------------------------------------

    def traverse(self, cb):
        mi.Medium.traverse(self, cb)             # phase_function
        cb.put("scale", self.editable["scale"], mi.ParamFlags.Differentiable)
        cb.put("density_bound", self.editable["density_bound"],
               mi.ParamFlags.NonDifferentiable)
        cb.put("albedo", self.albedo, mi.ParamFlags.Differentiable)
        if self.density is not None:
            cb.put("density", self.density, mi.ParamFlags.Differentiable)

    def parameters_changed(self, keys=[]):
        """Check scale and density_bound as ``mi.traverse`` left them (an invalid edit
        raises and puts the last valid values back). Both are opaque: a new value reuses
        the kernel."""
        jit = dr.is_jit_v(mi.Float)
        if jit:
            dr.make_opaque(*self.editable.values())
        if self.density is not None and not self._bound_given:
            mi.set_property(self.editable["density_bound"],
                            _held(self._default_bound()))   # a density edit moves max()
        scale, bound = (first_number(self.editable[k]) for k in ("scale", "density_bound"))
        problem = _number_problem("scale", scale, 0.0, strict=True) \
            or _number_problem("density_bound", bound, 0.0, strict=False)
        if not problem and not scale * bound <= FLT_MAX:   # σ̄ = ∞: every step 0 long
            problem = (f"marble_medium: the majorant scale·density_bound = {scale * bound:.3g} "
                       f"is past float32's {FLT_MAX:.3g}")
        if problem:
            for name, value in getattr(self, "_last_valid", {}).items():
                mi.set_property(self.editable[name], _held(value))   # in place: traverse holds them
            raise MarbleMediumError(problem)
        self._last_valid = {"scale": scale, "density_bound": bound}
        if jit:   # the kernel reads the traversed values themselves
            self.scale, self.bound = self.editable["scale"], self.editable["density_bound"]
        else:     # the scalar variant computes on Python floats
            self.scale, self.bound = scale, bound

    def recording_key(self) -> tuple:
        """What decides the code traced besides Dr.Jit's variables (see
        ``Marble.recording_key``): whether there is a density, the textures' own keys."""
        return ("marble_medium", self.density is None, recording_key(self.albedo),
                recording_key(self.density))

    def to_string(self):
        return describe("MarbleMedium", {
            "albedo": self.albedo,
            "density": "1 (none given)" if self.density is None else self.density,
            "scale": first_number(self.scale), "density_bound": first_number(self.bound),
            "majorant": first_number(self.majorant),
            "phase_function": self.phase_function()})

    # -- The medium ------------------------------------------------------------

    def intersect_aabb(self, ray):
        """Unbounded, as ``homogeneous``: every ray is inside over [0, ∞) (the boundary
        shape ends it)."""
        return mi.Bool(True), mi.Float(0.0), mi.Float(dr.inf)

    @property
    def majorant(self):
        """σ̄ = scale · density_bound, with scale's derivative (below)."""
        return self.scale * self.bound

    def get_majorant(self, mei, active=True):
        """σ̄, the same in every channel.

        It keeps scale's derivative. ``prbvolpath`` differentiates the null-collision
        path weight Π exp(−σ̄ t_i) · Π σ_n · Π σ_s, whose expectation does not depend on σ̄:
        with σ̄ detached, the transmittance's derivative would come only through null
        collisions, which are never sampled where σ_n = 0 (a constant density: the
        derivative of exp(−σ_t t) lost). With σ̄ = scale · bound attached, d log weight =
        −Σ t_i dσ̄ + Σ dσ_n/σ_n + Σ dσ_s/σ_s, over a sampling whose support (σ_n > 0)
        does not move with scale: unbiased. The textures are evaluated at the detached
        point (:meth:`get_scattering_coefficients`), so the sampled distance's own
        dependence on σ̄ adds nothing."""
        return mi.UnpolarizedSpectrum(self.majorant)

    def _texture_point(self, mei):
        """What a texture reads at the medium point: the point, time and wavelengths;
        every other field zero (no normal, (u, v) = (0, 0), no footprint)."""
        si = dr.zeros(mi.SurfaceInteraction3f, dr.width(mei.p)) if dr.is_jit_v(mi.Float) \
            else dr.zeros(mi.SurfaceInteraction3f)
        # Detached: Mitsuba samples the point at a distance −log(1 − u)/σ̄, which moves
        # with scale; the sampling decision is not part of what is differentiated.
        si.p, si.time, si.wavelengths = dr.detach(mei.p), mei.time, mei.wavelengths
        return si

    def density_at(self, si, active=True):
        """d = clamp(mean of the density's three components, 0, density_bound); 1 without
        a density texture (at most density_bound, so that the majorant bounds σ_t)."""
        if self.density is None:
            return dr.minimum(mi.Float(1.0), self.bound)
        c = self.density.eval(si, active)
        return dr.clip((c[0] + c[1] + c[2]) / 3.0, 0.0, self.bound)

    def get_scattering_coefficients(self, mei, active=True):
        """(σ_s, σ_n, σ_t) at ``mei.p``; zero where ``active`` is False (as ``homogeneous``
        gives: Mitsuba asks at points past the medium too, p = ray(∞) there)."""
        si = self._texture_point(mei)
        sigma_t = self.scale * self.density_at(si, active)
        albedo = dr.clip(mi.UnpolarizedSpectrum(self.albedo.eval(si, active)), 0.0, 1.0)
        sigma_s = albedo * sigma_t
        sigma_n = self.majorant - sigma_t
        zero = mi.UnpolarizedSpectrum(0.0)
        return (dr.select(active, sigma_s, zero),
                dr.select(active, mi.UnpolarizedSpectrum(sigma_n), zero),
                dr.select(active, mi.UnpolarizedSpectrum(sigma_t), zero))
