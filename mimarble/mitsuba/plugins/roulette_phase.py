"""``roulette_isotropic``: the isotropic phase function with Russian roulette by the albedo at each scattering, so that long walks end with bounded weights (issue 40).

``volpath`` multiplies a path's weight by the albedo α = σ_s/σ_t at a real collision, then
samples the phase function. This one draws the new direction uniformly on the sphere (as
``isotropic``) and, with the ``sample1`` volpath gives it, keeps the path with probability
q = max_c α_c (the largest channel, clamped to [0, 1]), weight 1/q, else ends it (weight
0: volpath stops a path whose weight is 0). Over the two factors a collision weighs the
path by α/q ≤ 1 per channel, exactly 1 for a grey albedo: the expectation is the
isotropic medium's, and no weight grows. volpath's own roulette (survival
min(max β, 0.95)) multiplies weights by 1/0.95 wherever they stay near 1, which they do
here: path mode turns it off (``contract.VOLPATH_RR_DEPTH``). A walk of single-scattering
albedo α then ends after 1/(1 − α) collisions on average instead of running to the
boundary or the depth cap with a weight αᵏ that adds little (docs/benchmarks.md, "Where
volpath's time goes on the Cycles-twin sphere").

``eval_pdf`` is the isotropic 1/(4π) (value and pdf): next-event estimation from inside
the medium, where a medium does it, is unchanged by the roulette of the direction that
follows. No parameters.
"""

from __future__ import annotations

from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import plugin

dr, mi = environment.import_drjit_and_mitsuba()


@plugin("phase", "roulette_isotropic")
class RouletteIsotropic:
    """Isotropic scattering, kept with probability max α (module docstring)."""

    def __init__(self, props):
        mi.PhaseFunction.__init__(self, props)
        self.m_flags = mi.PhaseFunctionFlags.Isotropic
        self.m_components = [self.m_flags]

    def survival(self, mei):
        """q = max over channels of σ_s/σ_t at the collision, in [0, 1] (0 where σ_t is 0)."""
        albedo = dr.select(mei.sigma_t > 0.0, mei.sigma_s / mei.sigma_t, 0.0)
        return dr.clip(dr.max(mi.UnpolarizedSpectrum(albedo)), 0.0, 1.0)

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
        return ("roulette_isotropic",)

    def to_string(self):
        return "RouletteIsotropic[]"
