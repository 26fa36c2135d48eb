"""The colour you see, Mitsuba's side: F̄(η) by quadrature of ``mi.fresnel``, and a
subsurface's reflectance inverted to its single-scattering albedo in Dr.Jit, and the spherical
albedo forwards (the fast preview's).

A thick translucent object under even light of radiance L shows, on the mean over its
silhouette, L·[F̄ + (1 − F̄)·A(α)] (docs/rendering-model.md, "The colour you see:
reflectance"): F̄(η) = ∫₀¹ F(μ, η) 2μ dμ the cosine-weighted mean of Fresnel's reflectance
for light arriving from outside, A(α) the spherical albedo of the semi-infinite medium. A
reflectance C is the colour wanted there; per component, clamped to [0, 1]:

    a = clamp((C − F̄) / (1 − F̄), 0, 1)                   (the coat's mean share taken out)
    s = 2(1 − a) / (b + √(b² − 4B(1 − a))),  b = 1 + B + C_fit·a
    α = 1 − s²

s the root in [0, 1] of van de Hulst's (1 − s)(1 − B s)/(1 + C_fit s) = a (B, C_fit:
``contract.SPHERICAL_ALBEDO_FIT_B``, ``_C``), written without the cancellation of the
quadratic formula's usual form as a → 1 (s → 0: white marble), where float32 would lose
the digits that make α differ from 1. b² − 4B(1 − a) ≥ (1 + B)² − 4B = (1 − B)² > 0: no
NaN, and its derivative is finite everywhere, so gradients flow through the texture.
The float64 reference has its own code for both (mimarble/reference/subsurface_reflectance.py).
"""

from __future__ import annotations

import numpy as np

from mimarble.runtime import environment
from mimarble.contract import FLT_MIN_NORMAL
from mimarble.contract import SPHERICAL_ALBEDO_FIT_B as FIT_B, SPHERICAL_ALBEDO_FIT_C as FIT_C

dr, mi = environment.import_drjit_and_mitsuba()

#: Gauss–Legendre nodes of F̄'s quadrature: F(μ(t)) is analytic in t on [0, 1] (below), so
#: 64 give F̄ to float32's resolution for every η not within 10⁻⁴ of 1 (and there F̄ < 10⁻⁴).
QUADRATURE_NODES = 64


def _fresnel(cos_i: np.ndarray, eta: float) -> np.ndarray:
    """Mitsuba's unpolarised Fresnel reflectance (``mi.fresnel``) at each cos θᵢ > 0, light
    arriving from outside a boundary of relative index η, as float64 NumPy."""
    if dr.is_jit_v(mi.Float):
        return np.array(mi.fresnel(mi.Float(cos_i.astype(np.float32)), mi.Float(eta))[0],
                        dtype=np.float64)
    return np.array([mi.fresnel(float(c), float(eta))[0] for c in cos_i], dtype=np.float64)


def diffuse_fresnel_reflectance(eta: float, nodes: int = QUADRATURE_NODES) -> float:
    """F̄(η) = ∫₀¹ F(μ, η) 2μ dμ, on the host, once.

    Below η = 1 the light from outside is wholly reflected for μ < μ_c = √(1 − η²), where
    F's derivative jumps; above μ_c the substitution μ² = μ_c² + (1 − μ_c²)·t² makes
    2μ dμ = 2(1 − μ_c²)·t dt and cos θₜ ∝ t, so that the integrand is smooth in t:
    F̄ = μ_c² + (1 − μ_c²)·∫₀¹ F(μ(t)) 2t dt, by Gauss–Legendre (μ_c = 0 for η ≥ 1)."""
    mu_c2 = max(0.0, 1.0 - eta * eta)
    if mu_c2 == 1.0:          # η < 10⁻⁸: every direction from outside is wholly reflected
        return 1.0
    x, w = np.polynomial.legendre.leggauss(nodes)
    t, w = (x + 1.0) / 2.0, w / 2.0
    mu = np.sqrt(mu_c2 + (1.0 - mu_c2) * t * t)
    return float(mu_c2 + (1.0 - mu_c2) * np.sum(w * _fresnel(mu, eta) * 2.0 * t))


def spherical_albedo_seen(reflectance, fresnel_mean: float):
    """a = clamp((C − F̄)/(1 − F̄), 0, 1) per component of ``reflectance`` C clamped to
    [0, 1]: the spherical albedo a thick medium behind the boundary must have for its
    silhouette's mean under even light to be C (the coat's mean share F̄ taken out) — what
    the inversion gives α for, and what the fast preview (``subsurface_preview``) returns."""
    c = dr.clip(reflectance, 0.0, 1.0)
    transmitted = max(1.0 - fresnel_mean, FLT_MIN_NORMAL)     # 1 − F̄, never 0
    return dr.clip((c - fresnel_mean) / transmitted, 0.0, 1.0)


def spherical_albedo(albedo):
    """Van de Hulst's fit, forwards: A(α) = (1 − s)(1 − B s)/(1 + C_fit s), s = √(1 − α),
    per component of the single-scattering ``albedo`` clamped to [0, 1] — the spherical
    albedo of the semi-infinite medium (0 at α = 0, 1 at α = 1), what the inversion below
    undoes."""
    s = dr.sqrt(1.0 - dr.clip(albedo, 0.0, 1.0))
    return (1.0 - s) * (1.0 - FIT_B * s) / (1.0 + FIT_C * s)


def single_scattering_albedo(reflectance, fresnel_mean: float):
    """α per component of ``reflectance`` (any Dr.Jit colour, spectrum or number) for a
    boundary of mean reflectance F̄ = ``fresnel_mean`` (module docstring): in [0, 1], 1
    where the reflectance is 1, 0 where it is at most F̄ — everywhere once F̄ rounds to 1
    (an ior past 10¹⁶ or below 10⁻⁸: the coat reflects all even light)."""
    a = spherical_albedo_seen(reflectance, fresnel_mean)
    b = (1.0 + FIT_B) + FIT_C * a
    s = 2.0 * (1.0 - a) / (b + dr.sqrt(b * b - 4.0 * FIT_B * (1.0 - a)))
    return 1.0 - s * s
