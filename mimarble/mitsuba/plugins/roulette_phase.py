"""``roulette_isotropic``: the isotropic phase function with Russian roulette by the albedo at each scattering, so that long walks end (issue 40).

``volpath`` multiplies a path's weight by the albedo α = σ_s/σ_t at a real collision, then
samples the phase function. This one draws the new direction uniformly on the sphere (as
``isotropic``) and, with the ``sample1`` volpath gives it, keeps the path with probability

    q = a^p   where lo ≤ a < hi,   else a     (a = max_c α_c, the largest channel,
                                                clamped to [0, 1]; p = ``survival_power``,
                                                [lo, hi) = [``power_albedo_min``,
                                                ``power_albedo_max``))

weight 1/q, else ends it (weight 0: volpath stops a path whose weight is 0). The
expectation is the isotropic medium's for every p: E[weight] = q·(1/q) = 1. Over the
two factors a collision weighs a survivor by α/q per channel:

- **p = 1** (the default, the analog walk): α/q ≤ 1, exactly 1 for a grey albedo; no
  weight grows. A walk ends after 1/(1 − α) collisions on average instead of running to
  the boundary or the depth cap with a weight αᵏ that adds little (docs/benchmarks.md,
  "Where volpath's time goes on the Cycles-twin sphere").
- **p > 1** (where lo ≤ a < hi): the walk ends p times as often near α = 1 (q ≈ 1 − p(1 − α)), and a
  survivor of k collisions weighs α^((1−p)k): fewer long walks — the ones that keep a
  packet of lanes looping (docs/benchmarks.md, "Where volpath's time goes") — for more
  noise. A walk of k collisions that leaves has the second moment α^((2−p)k) against the
  analog walk's αᵏ: bounded for p ≤ 2, growing with k beyond; volpath's depth cap
  bounds k. Path mode takes p = ``media.WALK_SURVIVAL_POWER`` on
  ``media.WALK_POWER_ALBEDOS`` (docs/benchmarks.md, "The walk's survival power against
  Cycles"): from its lower end the depth cap bounds the growth (α^(2−p) ≤ 1/0.99 a
  scattering, 256 of them at most), below it the walks are short anyway; above it (white
  marble) the boundary and the cap end them before absorption would, and the extra deaths
  cost more noise than they save time.
- p < 1 ends fewer walks than the analog walk (0: none, weight 1).

volpath's own roulette (survival min(max β, 0.95)) multiplies weights by 1/0.95 wherever
they stay near 1, which they do here: path mode turns it off
(``contract.VOLPATH_RR_DEPTH``).

``eval_pdf`` is the isotropic 1/(4π) (value and pdf): next-event estimation from inside
the medium, where a medium does it, is unchanged by the roulette of the direction that
follows.

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Description
   * - ``survival_power``
     - float (1, the analog walk)
     - p ≥ 0, finite: a walk survives a scattering with probability (max α)^p, its
       weight divided by that. A constant of the traced code (its ``recording_key``), not
       a traversed parameter. Path mode gives ``media.WALK_SURVIVAL_POWER``.
   * - ``power_albedo_min``, ``power_albedo_max``
     - float (0, 1: the power at every albedo)
     - 0 ≤ lo ≤ hi ≤ 1: the power applies where lo ≤ max α < hi; elsewhere the survival is
       max α (the analog walk). Path mode gives ``media.WALK_POWER_ALBEDOS``.
"""

from __future__ import annotations

import math

from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import plugin

dr, mi = environment.import_drjit_and_mitsuba()


class RouletteIsotropicError(ValueError):
    """An invalid ``roulette_isotropic``; the message names the parameter."""


@plugin("phase", "roulette_isotropic")
class RouletteIsotropic:
    """Isotropic scattering, kept with probability (max α)^p (module docstring)."""

    def __init__(self, props):
        mi.PhaseFunction.__init__(self, props)
        power = props.get("survival_power", 1.0)
        if isinstance(power, bool) or not isinstance(power, (int, float)) \
                or not math.isfinite(power) or power < 0:
            raise RouletteIsotropicError(
                f"roulette_isotropic: survival_power={power!r:.40} must be a finite number ≥ 0")
        self.power = float(power)
        window = [props.get(name, default) for name, default in
                  (("power_albedo_min", 0.0), ("power_albedo_max", 1.0))]
        if any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in window) \
                or not 0.0 <= window[0] <= window[1] <= 1.0:
            raise RouletteIsotropicError(
                f"roulette_isotropic: power_albedo_min={window[0]!r:.40} and power_albedo_max="
                f"{window[1]!r:.40} must be numbers with 0 ≤ min ≤ max ≤ 1")
        self.window = (float(window[0]), float(window[1]))
        self.m_flags = mi.PhaseFunctionFlags.Isotropic
        self.m_components = [self.m_flags]

    def survival(self, mei):
        """q = a^p where lo ≤ a < hi, else a; a = max over channels of σ_s/σ_t at the collision,
        in [0, 1] (0 where σ_t is 0). Any q > 0 where α > 0 keeps the walk unbiased: the
        weight is 1/q of the q used."""
        albedo = dr.select(mei.sigma_t > 0.0, mei.sigma_s / mei.sigma_t, 0.0)
        q = dr.clip(dr.max(mi.UnpolarizedSpectrum(albedo)), 0.0, 1.0)
        if self.power == 1.0:           # the analog walk: the same kernel as before p existed
            return q
        if self.power == 0.0:           # no roulette (0⁰ = 1; Dr.Jit's power gives NaN there)
            powered = dr.full(mi.Float, 1.0, dr.width(q))
        else:
            powered = dr.power(q, self.power)
        lo, hi = self.window
        if (lo, hi) == (0.0, 1.0):      # a = 1 gives q = 1 either way
            return powered
        return dr.select((q >= lo) & (q < hi), powered, q)

    def sample(self, ctx, mei, sample1, sample2, active=True):
        wo = mi.warp.square_to_uniform_sphere(sample2)
        pdf = mi.warp.square_to_uniform_sphere_pdf(wo)
        q = self.survival(mei)
        weight = dr.select(sample1 < q, dr.rcp(q), 0.0)
        return wo, mi.Spectrum(weight), pdf

    def eval_pdf(self, ctx, mei, wo, active=True):
        pdf = mi.warp.square_to_uniform_sphere_pdf(wo)
        return mi.Spectrum(pdf), pdf

    def recording_key(self) -> tuple:
        return ("roulette_isotropic", self.power, self.window)

    def to_string(self):
        return (f"RouletteIsotropic[survival_power={self.power:g}, "
                f"power_albedos=[{self.window[0]:g}, {self.window[1]:g})]")
