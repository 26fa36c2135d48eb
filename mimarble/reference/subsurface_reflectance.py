"""The colour you see, the reference's: F̄(η) by Walsh's closed form, and a subsurface's
reflectance inverted to its single-scattering albedo, in float64.

The model (docs/rendering-model.md, "The colour you see: reflectance"): a reflectance C is
the colour a thick piece of the medium shows under even light; per component, clamped to
[0, 1],

    a = clamp((C − F̄(η)) / (1 − F̄(η)), 0, 1)
    α = 1 − s²,  s the root in [0, 1] of (1 − s)(1 − B s)/(1 + C_fit s) = a

(B, C_fit: ``contract.SPHERICAL_ALBEDO_FIT_B``, ``_C``, van de Hulst's fit of the spherical
albedo), here by the quadratic's textbook root
s = [(1 + B + C_fit·a) − √((1 + B + C_fit·a)² − 4B(1 − a))] / (2B), whose cancellation as
a → 1 costs float64 nothing that matters (α's error stays below 10⁻¹⁴). Mitsuba's side
computes both in its own code (mimarble/mitsuba/plugins/subsurface_reflectance.py).
"""

from __future__ import annotations

from decimal import Decimal, localcontext

import numpy as np

from mimarble.contract import FLT_MIN_NORMAL
from mimarble.contract import SPHERICAL_ALBEDO_FIT_B as FIT_B, SPHERICAL_ALBEDO_FIT_C as FIT_C

__all__ = ["diffuse_fresnel_reflectance", "single_scattering_albedo", "spherical_albedo",
           "spherical_albedo_seen"]

#: Decimal digits Walsh's form is evaluated with: its terms grow as 1/(η − 1)² near η = 1
#: while their sum falls as (η − 1)/3, so float64 would lose every digit within 10⁻⁸ of 1.
DIGITS = 100


def _walsh(m: float) -> float:
    """∫₀¹ F(μ, m) 2μ dμ for light from outside into a denser medium, m > 1: Walsh's closed
    form (S. A. Prahl, Light Transport in Tissue, 1988, eq. B.41)."""
    with localcontext() as context:
        context.prec = DIGITS
        m = Decimal(m)                    # the float's exact value
        m2 = m * m
        m4 = m2 * m2
        total = (Decimal(1) / 2 + (m - 1) * (3 * m + 1) / (6 * (m + 1) ** 2)
                 + m2 * (m2 - 1) ** 2 / (m2 + 1) ** 3 * ((m - 1) / (m + 1)).ln()
                 - 2 * m ** 3 * (m2 + 2 * m - 1) / ((m2 + 1) * (m4 - 1))
                 + 8 * m4 * (m4 + 1) / ((m2 + 1) * (m4 - 1) ** 2) * m.ln())
        return float(total)


def diffuse_fresnel_reflectance(eta: float) -> float:
    """F̄(η) = ∫₀¹ F(μ, η) 2μ dμ, F the unpolarised Fresnel reflectance for light arriving
    from outside a boundary of relative index η (inside over outside) at cos θ = μ: the
    share of an even light's flux that the boundary reflects. η > 1: Walsh's form; η = 1:
    0; η < 1 by reciprocity — the flux crossing from the denser side is η² times the
    flux crossing from the other, 1 − F̄(η) = η²·(1 − F̄(1/η))."""
    eta = float(eta)
    if eta == 1.0:
        return 0.0
    if eta > 1.0:
        return _walsh(eta)
    return 1.0 - eta * eta * (1.0 - _walsh(1.0 / eta))


def spherical_albedo_seen(reflectance, fresnel_mean: float) -> np.ndarray:
    """a = clamp((C − F̄)/(1 − F̄), 0, 1) (same shape as ``reflectance``, float64, C clamped
    to [0, 1] first): the spherical albedo the walk must return under a boundary of
    F̄ = ``fresnel_mean`` for a thick piece to show C (module docstring); 0 where F̄ rounds
    to 1."""
    c = np.clip(np.asarray(reflectance, dtype=np.float64), 0.0, 1.0)
    return np.clip((c - fresnel_mean) / max(1.0 - fresnel_mean, FLT_MIN_NORMAL), 0.0, 1.0)


def spherical_albedo(albedo) -> np.ndarray:
    """Van de Hulst's fit forwards: A = (1 − s)(1 − B s)/(1 + C_fit s), s = √(1 − α), of the
    single-scattering albedo α clamped to [0, 1] (same shape, float64)."""
    s = np.sqrt(1.0 - np.clip(np.asarray(albedo, dtype=np.float64), 0.0, 1.0))
    return (1.0 - s) * (1.0 - FIT_B * s) / (1.0 + FIT_C * s)


def single_scattering_albedo(reflectance, fresnel_mean: float) -> np.ndarray:
    """α (same shape as ``reflectance``, float64) of each reflectance component, for a
    boundary of F̄ = ``fresnel_mean`` (module docstring); 0 everywhere where F̄ rounds to 1
    (the coat reflects all even light)."""
    a = spherical_albedo_seen(reflectance, fresnel_mean)
    b = 1.0 + FIT_B + FIT_C * a
    s = (b - np.sqrt(b * b - 4.0 * FIT_B * (1.0 - a))) / (2.0 * FIT_B)
    return 1.0 - s * s
