"""The ``subsurface_boundary`` BSDF (mimarble/mitsuba/plugins/subsurface_boundary.py) on its
own, in every RGB variant: its samples against its eval and pdf, its lobes' integrals by
quadrature, the exit lobe as the entry lobe's transpose over 1 − F̄, and F̄ against a
numerical integral of Fresnel's sine and tangent laws (written here, not the plugin's)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mimarble
from mimarble.mitsuba.plugins import subsurface_boundary as plugin
from mimarble.mitsuba.plugins.subsurface_reflectance import diffuse_fresnel_reflectance

dr, mi = mimarble.dr, mimarble.mi


def fresnel_by_angles(mu, eta):
    """Fresnel's unpolarised reflectance from outside at cosine μ, from the angles (the sine
    and tangent laws); 1 past the critical angle (η < 1)."""
    theta = np.arccos(np.clip(mu, 0.0, 1.0))
    sin_t = np.sin(theta) / eta
    total = sin_t >= 1.0
    theta_t = np.arcsin(np.minimum(sin_t, 1.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.sin(theta - theta_t) / np.sin(theta + theta_t)
        p = np.tan(theta - theta_t) / np.tan(theta + theta_t)
    normal = ((eta - 1.0) / (eta + 1.0)) ** 2
    value = np.where(theta < 1e-6, normal, 0.5 * (s * s + p * p))
    return np.where(total, 1.0, value)


def mean_by_midpoints(eta, n=200_000):
    """F̄ = ∫₀^{π/2} F(θ) 2 cos θ sin θ dθ by the midpoint rule (error ~(π/2n)², and
    ~(π/2n)^1.5 at the critical angle's √ kink where η < 1: about 10⁻⁸ either way)."""
    theta = (np.arange(n) + 0.5) * (0.5 * math.pi / n)
    return float(np.sum(fresnel_by_angles(np.cos(theta), eta) * np.sin(2.0 * theta))
                 * (0.5 * math.pi / n))


@pytest.mark.parametrize("eta", [1.5, 1.33, 2.4, 1.0, 0.8])
def test_the_boundarys_mean_fresnel_reflectance_matches_a_numerical_integral(eta):
    assert diffuse_fresnel_reflectance(eta) == pytest.approx(mean_by_midpoints(eta), abs=1e-7)
    if eta == 1.5:
        assert diffuse_fresnel_reflectance(eta) == pytest.approx(0.0918, abs=1e-4)


# ---------------------------------------------------------------------------
# The BSDF, lane by lane (a loop in scalar_rgb, arrays in JIT variants)

def boundary(eta):
    return mi.load_dict({"type": "subsurface_boundary", "int_ior": eta, "ext_ior": 1.0})


def _interaction(wi):
    si = dr.zeros(mi.SurfaceInteraction3f, len(wi)) if dr.is_jit_v(mi.Float) \
        else dr.zeros(mi.SurfaceInteraction3f)
    si.wi = mi.Vector3f(*(wi.T if dr.is_jit_v(mi.Float) else wi))
    return si


def _lanes(function, *columns):
    """``function(*values)`` for each row of the (k, …) NumPy ``columns``, as NumPy rows."""
    if dr.is_jit_v(mi.Float):
        return function(*columns)
    rows = [function(*(c[k] for c in columns)) for k in range(len(columns[0]))]
    return tuple(np.array(part) for part in zip(*rows))


def sample(bsdf, wi, u1, u2):
    """(wo (k, 3), pdf, weight (k,), delta (bool k,)) of ``bsdf.sample``."""
    def one(wi, u1, u2):
        bs, w = bsdf.sample(mi.BSDFContext(), _interaction(wi), mi.Float(u1),
                            mi.Point2f(*(u2.T if dr.is_jit_v(mi.Float) else u2)))
        wo = np.array(bs.wo).T if dr.is_jit_v(mi.Float) else np.array(bs.wo)
        delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
        return wo, np.array(bs.pdf), np.array(w)[0], np.array(delta)
    return _lanes(one, wi, u1, u2)


def eval_pdf(bsdf, wi, wo):
    """(eval's value (k,), pdf (k,)) at wi → wo."""
    def one(wi, wo):
        value, pdf = bsdf.eval_pdf(mi.BSDFContext(), _interaction(wi),
                                   mi.Vector3f(*(wo.T if dr.is_jit_v(mi.Float) else wo)))
        return np.array(value)[0], np.array(pdf)
    return _lanes(one, wi, wo)


def directions(rng, k, sign):
    """k unit directions spread over the hemisphere z·sign > 0 (uniform in μ ∈ (0.02, 1))."""
    mu = rng.uniform(0.02, 1.0, k)
    phi = rng.uniform(0.0, 2.0 * math.pi, k)
    r = np.sqrt(1.0 - mu * mu)
    return np.stack([r * np.cos(phi), r * np.sin(phi), sign * mu], axis=1)


@pytest.mark.parametrize("side", [1.0, -1.0], ids=["from outside", "from inside"])
def test_smooth_samples_weigh_eval_over_pdf_and_delta_ones_mirror(variant, side):
    rng = np.random.default_rng(1)
    k = 64 if variant == "scalar_rgb" else 4096
    bsdf = boundary(1.5)
    wi = directions(rng, k, side)
    wo, pdf, weight, delta = sample(bsdf, wi, rng.random(k), rng.random((k, 2)))
    value, pdf_at = eval_pdf(bsdf, wi, wo)
    smooth = ~delta
    assert smooth.sum() > k // 2
    assert np.all(wo[smooth, 2] < 0) if side > 0 else np.all(wo[:, 2] > 0)   # in; out
    np.testing.assert_allclose(pdf_at[smooth], pdf[smooth], rtol=1e-5)
    np.testing.assert_allclose(value[smooth] / pdf_at[smooth], weight[smooth], rtol=1e-5)
    if side > 0:         # entering: weight 1; the mirror: weight 1, eval 0
        np.testing.assert_allclose(weight, 1.0, rtol=1e-6)
        assert delta.any()
        np.testing.assert_allclose(wo[delta], wi[delta] * [-1, -1, 1], atol=1e-6)
        assert np.all(value[delta] == 0.0)
        # the mirror is chosen with probability F(μᵢ): the fraction within 4.5 σ of its mean
        f = fresnel_by_angles(wi[:, 2], 1.5)
        assert abs(delta.sum() - f.sum()) < 4.5 * math.sqrt(np.sum(f * (1 - f))) + 1
    else:                # leaving: always out, weight W(μₒ) = (1 − F(μₒ))/(1 − F̄)
        assert not delta.any()
        expected = (1.0 - fresnel_by_angles(wo[:, 2], 1.5)) / (1.0 - mean_by_midpoints(1.5))
        np.testing.assert_allclose(weight, expected, rtol=1e-5, atol=1e-6)


def _hemisphere_quadrature(sign, eta, n_mu=48, n_phi=4):
    """Directions and weights of a quadrature over the hemisphere z·sign > 0 for
    ∫ g(ω) dω = ∫₀¹ ∫₀^{2π} g dφ dμ: Gauss–Legendre in μ, midpoints in φ; where η < 1
    the μ range is split at the critical cosine μ_c, above which F's √(μ − μ_c) is
    smoothed by μ = μ_c + (1 − μ_c)·t²."""
    x, w = np.polynomial.legendre.leggauss(n_mu)
    t, w_t = 0.5 * (x + 1.0), 0.5 * w
    if eta >= 1.0:
        mu, w_mu = t, w_t
    else:
        c = math.sqrt(1.0 - eta * eta)
        mu = np.concatenate([c * t, c + (1.0 - c) * t * t])
        w_mu = np.concatenate([c * w_t, 2.0 * (1.0 - c) * t * w_t])
    phi = (np.arange(n_phi) + 0.5) * 2.0 * math.pi / n_phi
    mu, phi = np.meshgrid(mu, phi, indexing="ij")
    r = np.sqrt(1.0 - mu * mu)
    dirs = np.stack([r * np.cos(phi), r * np.sin(phi), sign * mu], axis=-1).reshape(-1, 3)
    weights = (w_mu[:, None] * np.full(n_phi, 2.0 * math.pi / n_phi)).ravel()
    return dirs, weights


@pytest.mark.parametrize("eta", [1.5, 1.0, 0.8])
def test_each_lobe_integrates_to_what_it_transmits(variant, eta):
    """∫ f |cos θₒ| dω by quadrature: the exit lobe 1 from any inside direction; the entry
    lobe 1 − F(μᵢ) (F going to the mirror), so that nothing is lost."""
    bsdf = boundary(eta)
    out_dirs, weights = _hemisphere_quadrature(1.0, eta)
    in_dirs, _ = _hemisphere_quadrature(-1.0, eta)
    for mu_i in (0.1, 0.5, 0.95):
        s = math.sqrt(1 - mu_i * mu_i)
        inside = np.tile([s, 0.0, -mu_i], (len(out_dirs), 1))
        exit_total = np.sum(weights * eval_pdf(bsdf, inside, out_dirs)[0])
        assert exit_total == pytest.approx(1.0, abs=2e-5)
        outside = inside * [1, 1, -1]
        entry_total = np.sum(weights * eval_pdf(bsdf, outside, in_dirs)[0])
        assert entry_total == pytest.approx(1.0 - fresnel_by_angles(mu_i, eta), abs=2e-5)
        assert np.sum(weights * eval_pdf(bsdf, outside, in_dirs)[1]) == pytest.approx(entry_total, abs=2e-5)
        assert np.sum(weights * eval_pdf(bsdf, inside, out_dirs)[1]) == pytest.approx(1.0, abs=2e-5)
        assert np.all(eval_pdf(bsdf, outside, out_dirs)[0] == 0.0)     # no smooth reflection


def test_the_exit_lobe_is_the_entry_lobe_transposed_over_one_minus_the_mean(variant):
    """Reciprocity of the normalisation: f_exit(b → a) = f_entry(a → b)/(1 − F̄) for any a
    outside and b inside, with F̄ the numerical integral; f_exit does not depend on b."""
    rng = np.random.default_rng(2)
    k = 64
    bsdf = boundary(1.5)
    a, b = directions(rng, k, 1.0), directions(rng, k, -1.0)
    entry = eval_pdf(bsdf, a, b)[0] / np.abs(b[:, 2])          # f without the cosine
    leave = eval_pdf(bsdf, b, a)[0] / a[:, 2]
    np.testing.assert_allclose(leave * (1.0 - mean_by_midpoints(1.5)), entry, rtol=2e-5)
    other = eval_pdf(bsdf, directions(rng, k, -1.0), a)[0] / a[:, 2]
    np.testing.assert_allclose(other, leave, rtol=1e-6)
