"""``roulette_isotropic`` (mimarble/mitsuba/plugins/roulette_phase.py) on its own, in every RGB
variant: directions uniform on the sphere, kept with probability q = (max α)^p (max α outside
the power's albedo window; a binomial bound), weight 1/q, an isotropic eval_pdf; a bad
survival_power or window refused; and path mode's choice of it."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mimarble
from mimarble import scene as S
from mimarble.mitsuba.plugins.registration import bound_class
from mimarble.mitsuba.translate.scene_dict import to_mitsuba

dr, mi = mimarble.dr, mimarble.mi


def _collision(albedo):
    mei = dr.zeros(mi.MediumInteraction3f)
    mei.sigma_t = mi.UnpolarizedSpectrum(2.0)
    mei.sigma_s = mi.UnpolarizedSpectrum(*(2.0 * a for a in albedo)) if not mi.is_spectral \
        else mi.UnpolarizedSpectrum(2.0 * max(albedo))
    return mei


@pytest.mark.parametrize("power, window", [(None, None), (3.0, None), (0.0, None), (3.0, (0.8, 0.95))])
@pytest.mark.parametrize("albedo", [(0.9, 0.9, 0.9), (0.3, 0.7, 0.5), (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)])
def test_samples_survive_with_the_largest_albedo_and_weigh_its_inverse(variant, albedo, power,
                                                                      window):
    given = {} if power is None else {"survival_power": power}
    given.update({} if window is None else {"power_albedo_min": window[0],
                                             "power_albedo_max": window[1]})
    phase = mi.load_dict({"type": "roulette_isotropic", **given})
    ctx = mi.PhaseFunctionContext(None)
    rng = np.random.default_rng(3)
    k = 200 if variant == "scalar_rgb" else 20000
    a, p, (lo, hi) = max(albedo), 1.0 if power is None else power, window or (0.0, 1.0)
    q = a ** p if lo <= a < hi or a == 1.0 else a   # 0 ** 0 = 1: p = 0 keeps all
    kept, directions = 0, []
    u1, u2 = rng.random(k), rng.random((k, 2))
    if dr.is_jit_v(mi.Float):
        mei = _collision(albedo)
        wo, weight, pdf = phase.sample(ctx, mei, mi.Float(u1), mi.Point2f(u2[:, 0], u2[:, 1]))
        weight, wo, pdf = np.array(weight)[0], np.array(wo).T, np.array(pdf)
    else:
        rows = [phase.sample(ctx, _collision(albedo), float(a), mi.Point2f(*b)) for a, b in zip(u1, u2)]
        wo = np.array([np.array(r[0]) for r in rows])
        weight = np.array([np.array(r[1])[0] for r in rows])
        pdf = np.array([r[2] for r in rows])
    kept = weight > 0
    assert abs(kept.sum() - q * k) <= 4.5 * math.sqrt(k * q * (1 - q)) + 1e-9
    if q > 0:
        np.testing.assert_allclose(weight[kept], 1.0 / q, rtol=1e-6)
    np.testing.assert_allclose(pdf, 1.0 / (4.0 * math.pi), rtol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(wo, axis=1), 1.0, rtol=1e-5)
    assert np.all(np.abs(wo.mean(axis=0)) < 4.5 / math.sqrt(3 * k))     # uniform: mean 0
    value, pdf = phase.eval_pdf(ctx, _collision(albedo), mi.Vector3f(0.0, 0.6, 0.8))
    assert np.allclose(np.array(value).ravel(), 1.0 / (4.0 * math.pi)) and \
        np.allclose(np.array(pdf), 1.0 / (4.0 * math.pi))


@pytest.mark.parametrize("power", [-1.0, float("inf"), float("nan"), "3", True])
def test_a_bad_survival_power_is_refused_in_one_sentence(power):
    with pytest.raises(Exception, match=r"roulette_isotropic: survival_power=.* must be a "
                                        r"finite number ≥ 0"):
        mi.load_dict({"type": "roulette_isotropic", "survival_power": power})


@pytest.mark.parametrize("window", [(-0.1, 1.0), (0.0, 1.5), (0.9, 0.8), (float("nan"), 1.0),
                                    ("0.9", 1.0), (0.0, True)])
def test_a_bad_power_window_is_refused_in_one_sentence(window):
    with pytest.raises(Exception, match=r"roulette_isotropic: power_albedo_min=.* and "
                                        r"power_albedo_max=.* must be numbers with "
                                        r"0 ≤ min ≤ max ≤ 1"):
        mi.load_dict({"type": "roulette_isotropic", "power_albedo_min": window[0],
                      "power_albedo_max": window[1]})


@pytest.mark.parametrize("albedo, phase", [("0.9", None), ("0.99", "roulette_isotropic")])
def test_path_mode_ends_white_walks_at_the_phase_function_where_volpath_rolls_no_dice(albedo, phase):
    text = (f'material "m" {{ subsurface {{ albedo color < {albedo} 0.5 0.5 > mean_free_path 0.1 }} }}\n'
            'sphere { material "m" }')
    d = to_mitsuba(S.parse(text), mode="path")
    assert d["sphere_0"]["interior"].get("phase", {}).get("type") == phase
    assert d["integrator"]["rr_depth"] == (5 if phase is None else 256)


def test_path_mode_takes_the_power_only_on_its_albedo_window(llvm):
    """The translated phase's survival at albedos below, inside and above
    ``media.WALK_POWER_ALBEDOS``: the analog walk's max α outside, (max α)^p inside
    (white marble's 0.9995 stays analog)."""
    from mimarble.mitsuba.translate.media import WALK_POWER_ALBEDOS, WALK_SURVIVAL_POWER
    text = ('material "m" { subsurface { reflectance color < 0.9 0.5 0.5 > mean_free_path 0.1 } }\n'
            'sphere { material "m" }')
    phase_dict = to_mitsuba(S.parse(text), mode="path")["sphere_0"]["interior"]["phase"]
    phase = mi.load_dict(phase_dict)
    lo, hi = WALK_POWER_ALBEDOS
    for a, inside in ((lo - 0.005, False), ((lo + hi) / 2, True), (hi + 0.0005, False)):
        q = float(np.array(phase.survival(_collision((a, 0.5 * a, 0.2))))[0])
        expected = a ** WALK_SURVIVAL_POWER if inside else a
        assert q == pytest.approx(expected, rel=1e-5), (a, q)



def _window_scene():
    """A unit sphere of constant reflectance (0.9, 0.6, 0.3) — max α 0.9974, inside path
    mode's power window —, mean free path 0.1, under a sky and a rectangle light."""
    from test_translucent_reference import SIDE_LIGHT, translucent_scene
    base = translucent_scene(lights=(SIDE_LIGHT,), ambient=(0.6, 0.65, 0.7))
    sub = S.Subsurface(reflectance=S.ColorChannel((0.9, 0.6, 0.3)), mean_free_path=0.1, ior=1.5)
    return S.Scene(image=base.image, camera=base.camera, ambient=base.ambient,
                   lights=base.lights, spheres=base.spheres,
                   materials={"m": S.Material("m", subsurface=sub)})


def _biased_roulette():
    """A test-only phase function: ``roulette_isotropic`` whose surviving weight is off by
    q^(1/6) (α^0.5 a scattering at p = 3): a planted error the agreement must catch."""
    name = "roulette_isotropic_biased_for_test"
    bound = bound_class("roulette_isotropic")

    class Biased(bound):
        def sample(self, ctx, mei, sample1, sample2, active=True):
            wo, weight, pdf = bound.sample(self, ctx, mei, sample1, sample2, active)
            return wo, weight * dr.power(self.survival(mei), 1.0 / 6.0), pdf

    mi.register_phase(name, lambda props: Biased(props))
    return name


@pytest.mark.parametrize("planted", [False, True], ids=["as translated", "biased weight"])
def test_the_windows_power_agrees_with_the_float64_walk(llvm, planted):
    """Path mode's walk with the power (its translated phase) against the float64 walk
    without roulette (its own code: a roulette changes no expectation), by
    tests/test_translucent_reference.py's block z-test; a biased weight fails it."""
    from test_translucent_reference import SEEDS, agreement
    from mimarble.reference import volume
    scene = _window_scene()
    translated = to_mitsuba(scene, "path", spp=24)
    phase = translated["sphere_0"]["interior"]["phase"]
    assert phase["type"] == "roulette_isotropic" and phase["survival_power"] > 1
    if planted:
        translated["sphere_0"]["interior"]["phase"] = dict(phase, type=_biased_roulette())
    loaded = mi.load_dict(translated)
    renders = np.stack([np.array(mi.render(loaded, seed=4000 + k), dtype=np.float64)
                        for k in range(SEEDS)])
    depth = translated["integrator"]["max_depth"]
    image, variance = volume.render_translucent(scene, 192, seed=11, max_depth=depth,
                                                rr_depth=None, variance=True)
    ratio, z, m = agreement(scene, image, variance, 192, renders)
    assert (ratio >= 1) == planted, (ratio, z, m)
