"""A subsurface's ``reflectance`` (issue 40, "The colour you see"): the colour seen,
inverted to the single-scattering albedo per point — checked against what does not come
from the inversion.

* **The spherical albedo** A(α) of a semi-infinite, isotropically scattering medium behind
  an index-matched boundary, exactly: A = 1 − 2√(1 − α)∫₀¹ H(μ) μ dμ, Chandrasekhar's H
  by iteration (:func:`chandrasekhar_spherical_albedo`) — itself checked against a float64
  Monte Carlo walk in a half-space and against H's zeroth moment, known in closed form.
  Van de Hulst's fit (``contract.SPHERICAL_ALBEDO_FIT_B``, ``_C``) is within
  :data:`FIT_RESIDUAL` of it for every α (measured: 0.00206, at α ≈ 0.57).
* **F̄(η)** = ∫₀¹ F(μ, η) 2μ dμ of each renderer (Mitsuba's quadrature of ``mi.fresnel``,
  the reference's Walsh closed form) against a quadrature of Fresnel's equations in their
  sine-and-tangent form written here, and against published values (S. A. Prahl, Light
  Transport in Tissue, 1988, Tables B.1 and B.4; 0.092 at η = 1.5).
* **Both inversions** give the same α (float32 against float64, to 10⁻⁶), and Dr.Jit's
  derivative of α is the reference's finite difference; the project's path mode renders a
  veined reflectance as the reference walk does (the z-test of
  tests/test_translucent_reference.py).
* **Renders**: a unit sphere of constant reflectance C (mean free path 0.005: nearly a
  half-space) under a white sky, no lights, seen from afar: the mean radiance over its
  disk is within 5 % of C per channel, C in {0.2, 0.5, 0.8, 0.95}, with the reference
  random walk and with Mitsuba's volpath. Both run without Russian roulette
  (``rr_depth`` = ``max_depth`` = ``VOLPATH_MAX_DEPTH``, 256): every weight is a product of albedos ≤ 1, so the
  white sphere (α ≈ 0.9995) cannot run away. At ior 1 and 1.5 (:data:`IORS`), behind the
  diffuse-entry boundary (``subsurface_boundary``, docs/rendering-model.md).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import mimarble
from mimarble.contract import SPHERICAL_ALBEDO_FIT_B, SPHERICAL_ALBEDO_FIT_C, VOLPATH_MAX_DEPTH
from mimarble.reference import subsurface_reflectance as reference
from mimarble.reference import tracer, volume
from mimarble.scene import model

dr, mi = mimarble.dr, mimarble.mi

#: The fit's largest error against the exact spherical albedo, over every α (docs).
FIT_RESIDUAL = 0.0021
#: The iors at which the render check runs (the boundary's model holds there).
IORS = (1.0, 1.5)
#: The render check's colours: every C of the issue, in two renders.
COLOURS = ((0.2, 0.5, 0.8), (0.95, 0.95, 0.95))


# ---------------------------------------------------------------------------
# The exact spherical albedo

def chandrasekhar_h(alpha: float, nodes: int = 100):
    """(H at the Gauss–Legendre nodes μ_k of [0, 1], μ_k, weights w_k) for isotropic
    scattering of albedo α < 1, by iterating H's equation in the form
    1/H(μ) = √(1 − α) + (α/2) ∫₀¹ μ' H(μ') / (μ + μ') dμ' (Chandrasekhar, Radiative Transfer,
    1950, ch. V) to 10⁻¹⁴."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    mu, w = (x + 1.0) / 2.0, w / 2.0
    kernel = mu[None, :] * w[None, :] / (mu[:, None] + mu[None, :])
    h = np.ones(nodes)
    for _ in range(100_000):
        new = 1.0 / (math.sqrt(1.0 - alpha) + 0.5 * alpha * (kernel @ h))
        if np.max(np.abs(new - h)) < 1e-14:
            return new, mu, w
        h = new
    raise AssertionError(f"H did not converge at α = {alpha}")


def chandrasekhar_spherical_albedo(alpha: float) -> float:
    """A(α) = 1 − 2√(1 − α)∫₀¹ H(μ) μ dμ: the plane albedo 1 − H(μ₀)√(1 − α) of a
    semi-infinite isotropic medium (Chandrasekhar) averaged over cosine-weighted incidence
    2μ₀ dμ₀."""
    h, mu, w = chandrasekhar_h(alpha)
    return 1.0 - 2.0 * math.sqrt(1.0 - alpha) * float(np.sum(w * h * mu))


def half_space_walk(alpha: float, paths: int, seed: int) -> float:
    """The fraction of paths that leave a half-space z > 0 of unit mean free path and
    albedo α (absorbed with probability 1 − α at each collision, isotropic scattering),
    entering at z = 0 with cosine-distributed directions: the spherical albedo, by Monte
    Carlo in float64."""
    rng = np.random.default_rng(seed)
    mu = np.sqrt(rng.random(paths))             # cos θ of a cosine-distributed direction
    z = np.zeros(paths)
    live = np.arange(paths)
    left = 0
    while live.size:
        z[live] += mu[live] * rng.exponential(size=live.size)
        out = z[live] < 0.0
        left += int(out.sum())
        live = live[~out]
        live = live[rng.random(live.size) < alpha]          # scattered, not absorbed
        mu[live] = 1.0 - 2.0 * rng.random(live.size)         # isotropic: cos θ uniform
    return left / paths


def van_de_hulst(alpha):
    s = np.sqrt(1.0 - np.asarray(alpha, dtype=np.float64))
    return (1 - s) * (1 - SPHERICAL_ALBEDO_FIT_B * s) / (1 + SPHERICAL_ALBEDO_FIT_C * s)


@pytest.mark.parametrize("alpha", [0.3, 0.9, 0.999])
def test_h_keeps_its_zeroth_moment_in_closed_form(alpha):
    """∫₀¹ H dμ = (2/α)(1 − √(1 − α)) (Chandrasekhar): the iteration converged to H."""
    h, _, w = chandrasekhar_h(alpha)
    assert float(np.sum(w * h)) == pytest.approx(2 / alpha * (1 - math.sqrt(1 - alpha)), abs=1e-12)


@pytest.mark.parametrize("alpha, exact", [(0.5, 0.146544), (0.9, 0.478024)])
def test_the_exact_spherical_albedo_is_a_half_space_random_walks(alpha, exact):
    """The formula against a float64 Monte Carlo walk (4·10⁵ paths: σ ≈ 0.0006–0.0008):
    |z| < 4. The fit's error at these α (0.0020, 0.0009) is 3 and 1 σ."""
    assert chandrasekhar_spherical_albedo(alpha) == pytest.approx(exact, abs=1e-6)
    paths = 400_000
    walked = half_space_walk(alpha, paths, seed=11)
    z = (walked - exact) / math.sqrt(exact * (1 - exact) / paths)
    assert abs(z) < 4.0, (walked, exact, z)


def test_van_de_hulsts_fit_is_within_its_stated_residual_of_the_exact_albedo():
    s = np.linspace(0.02, 1.0, 50)            # α from 0.9996 to 0
    alphas = 1.0 - s * s
    exact = np.array([chandrasekhar_spherical_albedo(a) if a > 0 else 0.0 for a in alphas])
    error = van_de_hulst(alphas) - exact
    worst = int(np.argmax(np.abs(error)))
    assert abs(error[worst]) <= FIT_RESIDUAL, (alphas[worst], error[worst])
    assert abs(error[worst]) > 0.002 and 0.5 < alphas[worst] < 0.65     # the figure stated
    assert abs(error[0]) < 1e-4                                          # white: α → 1


# ---------------------------------------------------------------------------
# F̄(η)

def fresnel_by_angles(theta_i, eta):
    """Fresnel's unpolarised reflectance from the angles (the sine and tangent laws),
    light from outside; 1 past the critical angle (η < 1)."""
    sin_t = np.sin(theta_i) / eta
    inside = sin_t < 1.0
    theta_t = np.arcsin(np.where(inside, sin_t, 0.0))
    rs = np.sin(theta_i - theta_t) / np.sin(theta_i + theta_t)
    rp = np.tan(theta_i - theta_t) / np.tan(theta_i + theta_t)
    return np.where(inside, 0.5 * (rs * rs + rp * rp), 1.0)


def fresnel_mean_by_angles(eta: float, pieces: int = 400, nodes: int = 20) -> float:
    """F̄(η) = ∫₀^{π/2} F(θ) sin 2θ dθ by composite Gauss–Legendre. Below η = 1, F = 1 past
    the critical angle θ_c = asin η, and below it F − 1 ∝ √(θ_c − θ): there θ = θ_c(1 − t²),
    dθ = 2θ_c·t dt, smooth in t."""
    if eta == 1.0:
        return 0.0
    x, w = np.polynomial.legendre.leggauss(nodes)
    edges = np.linspace(0.0, 1.0, pieces + 1)
    half = np.diff(edges)[:, None] / 2
    t = (edges[:-1, None] + half * (x[None, :] + 1)).ravel()
    weight = (half * w[None, :]).ravel()
    if eta > 1.0:
        theta, jacobian, rest = t * math.pi / 2, math.pi / 2, 0.0
    else:
        critical = math.asin(eta)
        theta, jacobian = critical * (1 - t * t), 2 * critical * t
        rest = math.cos(critical) ** 2                  # ∫ sin 2θ dθ from θ_c to π/2
    theta = np.clip(theta, 1e-12, math.pi / 2 - 1e-12)
    return rest + float(np.sum(weight * jacobian * fresnel_by_angles(theta, eta)
                               * np.sin(2 * theta)))


ETAS = (1.5, 1.33, 2.0, 1.0001, 1 / 1.5, 0.8, 1.0)


def test_the_references_fresnel_mean_is_the_integral():
    for eta in ETAS:
        assert reference.diffuse_fresnel_reflectance(eta) == pytest.approx(
            fresnel_mean_by_angles(eta), abs=1e-10), eta


def test_mitsubas_fresnel_mean_is_the_integral(variant):
    from mimarble.mitsuba.plugins.subsurface_reflectance import diffuse_fresnel_reflectance
    for eta in ETAS:
        # float32 Fresnel at each node: 10⁻⁷ relative
        assert diffuse_fresnel_reflectance(eta) == pytest.approx(
            fresnel_mean_by_angles(eta), abs=3e-8), eta


def test_the_fresnel_mean_has_its_published_values():
    """Prahl (1988) Table B.1 (light from the rarer side; n_i/n_t = 1/η; ±0.001): 0.50 →
    0.161, 0.65 → 0.097, 0.70 → 0.081, 0.90 → 0.027; Table B.4 (from the denser side)
    1.50 → 0.596: F̄(1/1.5), and 1 − (1 − F̄(1.5))/1.5² by reciprocity; and 0.092 at
    η = 1.5."""
    f = reference.diffuse_fresnel_reflectance
    for ratio, table in ((0.50, 0.161), (0.65, 0.097), (0.70, 0.081), (0.90, 0.027)):
        assert f(1 / ratio) == pytest.approx(table, abs=0.001), ratio
    assert f(1 / 1.5) == pytest.approx(0.596, abs=0.001)       # outside the denser side
    assert 1 - (1 - f(1.5)) / 1.5 ** 2 == pytest.approx(0.596, abs=0.001)
    assert f(1.5) == pytest.approx(0.0918, abs=5e-5)


# ---------------------------------------------------------------------------
# The inversion, each side

def reflectance_grid():
    """Colours from below 0 to above 1 (the clamps), dense near 1 (white marble)."""
    return np.concatenate([[-0.2, 0.0, 1.0, 1.3], np.linspace(0.01, 0.99, 99),
                           1.0 - np.geomspace(1e-5, 1e-2, 16)])


@pytest.mark.parametrize("eta", [1.0, 1.3, 1.5, 0.8])
def test_the_reference_inverts_van_de_hulsts_fit(eta):
    """α from C: the fit at α, with the coat put back, is C (where C lies in [F̄, 1])."""
    fresnel = reference.diffuse_fresnel_reflectance(eta)
    c = reflectance_grid()
    alpha = reference.single_scattering_albedo(c, fresnel)
    assert np.all((alpha >= 0) & (alpha <= 1))
    seen = fresnel + (1 - fresnel) * van_de_hulst(alpha)
    inside = (c >= fresnel) & (c <= 1)
    np.testing.assert_allclose(seen[inside], c[inside], atol=1e-12)
    assert np.all(alpha[c <= fresnel] == 0) and np.all(alpha[c >= 1] == 1)


@pytest.mark.parametrize("eta", [1.0, 1.3, 1.5, 0.8])
def test_both_sides_invert_the_same_colours_to_the_same_albedo(variant, eta):
    from mimarble.mitsuba.plugins import subsurface_reflectance as mitsuba_side
    c = reflectance_grid()
    expected = reference.single_scattering_albedo(c, reference.diffuse_fresnel_reflectance(eta))
    fresnel = mitsuba_side.diffuse_fresnel_reflectance(eta)
    if dr.is_jit_v(mi.Float):
        got = np.array(mitsuba_side.single_scattering_albedo(mi.Float(c.astype(np.float32)),
                                                             fresnel), dtype=np.float64)
    else:
        got = np.array([mitsuba_side.single_scattering_albedo(mi.Float(v), fresnel) for v in c])
    np.testing.assert_allclose(got, expected, atol=1e-6, rtol=0)


@pytest.mark.parametrize("eta", [1e-30, 3e38])
def test_an_ior_whose_coat_reflects_all_light_gives_albedo_zero_not_nan(llvm, eta):
    from mimarble.mitsuba.plugins import subsurface_reflectance as mitsuba_side
    c = np.array([0.0, 0.5, 1.0])
    fresnel = mitsuba_side.diffuse_fresnel_reflectance(eta)
    assert fresnel == reference.diffuse_fresnel_reflectance(eta) == 1.0
    got = np.array(mitsuba_side.single_scattering_albedo(mi.Float(c), fresnel))
    assert np.all(got == 0) and np.all(reference.single_scattering_albedo(c, fresnel) == 0)


def test_the_medium_scatters_with_the_inverted_albedo(variant):
    """marble_medium with a ``reflectance`` and an ``ior``: σ_s/σ_t at a point is the
    reference's α of the colour."""
    colour = [0.2, 0.7, 0.97]
    medium = mi.load_dict({"type": "marble_medium", "ior": 1.5, "scale": 3.0,
                           "reflectance": {"type": "rgb", "value": colour}})
    mei = dr.zeros(mi.MediumInteraction3f, 1) if dr.is_jit_v(mi.Float) \
        else dr.zeros(mi.MediumInteraction3f)
    mei.p = mi.Point3f(0.1, 0.2, 0.3)
    sigma_s, _, sigma_t = medium.get_scattering_coefficients(mei, True)
    got = np.array(sigma_s, dtype=np.float64).ravel() / np.array(sigma_t, dtype=np.float64).ravel()
    expected = reference.single_scattering_albedo(colour, reference.diffuse_fresnel_reflectance(1.5))
    np.testing.assert_allclose(got, expected, atol=1e-6)


def test_the_albedos_derivative_is_the_references_finite_difference(llvm):
    from mimarble.mitsuba.plugins import subsurface_reflectance as mitsuba_side
    c = np.array([0.15, 0.3, 0.6, 0.9, 0.99, 0.999])
    fresnel = reference.diffuse_fresnel_reflectance(1.5)
    x = mi.Float(c.astype(np.float32))
    dr.enable_grad(x)
    alpha = mitsuba_side.single_scattering_albedo(x, mitsuba_side.diffuse_fresnel_reflectance(1.5))
    dr.backward(dr.sum(alpha))
    h = 1e-6
    finite = (reference.single_scattering_albedo(c + h, fresnel)
              - reference.single_scattering_albedo(c - h, fresnel)) / (2 * h)
    np.testing.assert_allclose(np.array(dr.grad(x)), finite, rtol=1e-3)


def test_a_medium_refuses_both_colours_and_an_ior_without_a_reflectance(llvm):
    from mimarble.mitsuba.plugins.marble_medium import MarbleMediumError
    for props, words in (({"albedo": 0.5, "reflectance": 0.5}, "not both"),
                         ({"albedo": 0.5, "ior": 1.5}, "without a reflectance"),
                         ({"reflectance": 0.5, "ior": 0.0}, "ior=0.0 must be")):
        with pytest.raises((MarbleMediumError, RuntimeError), match=words):
            mi.load_dict({"type": "marble_medium", **props})


def test_the_reflectance_is_traversed_and_an_edit_changes_the_albedo(llvm):
    medium = mi.load_dict({"type": "marble_medium", "ior": 1.0,
                           "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}})
    params = mi.traverse(medium)
    assert "reflectance.value" in params and not any(k.startswith("albedo") for k in params.keys())
    params["reflectance.value"] = mi.Color3f(0.8, 0.8, 0.8)
    params.update()
    mei = dr.zeros(mi.MediumInteraction3f, 1)
    sigma_s, _, sigma_t = medium.get_scattering_coefficients(mei, True)
    expected = reference.single_scattering_albedo(0.8, 0.0)
    assert np.array(sigma_s)[0, 0] / np.array(sigma_t)[0, 0] == pytest.approx(expected, abs=1e-6)


# ---------------------------------------------------------------------------
# Renders: the colour seen

SIZE, SPP, MEAN_FREE_PATH, DISTANCE = 16, 128, 0.005, 50.0


def sphere_scene(colour, ior):
    """A unit sphere of constant reflectance, under a white sky (ambient 1), no lights,
    seen from 50 radii away (nearly orthographic: over the disk cos θ is distributed as
    2μ dμ, the weighting of F̄ and A) with the disk just inside the image."""
    sub = model.Subsurface(reflectance=model.ColorChannel(colour), mean_free_path=MEAN_FREE_PATH,
                           ior=ior)
    fov = 2 * math.degrees(math.asin(1 / DISTANCE)) * 1.05
    return model.Scene(image=model.Image(width=SIZE, height=SIZE),
                       camera=model.Camera(eye=(0.0, 0.0, DISTANCE), lookat=(0.0, 0.0, 0.0), fov=fov),
                       ambient=(1.0, 1.0, 1.0), materials={"m": model.Material("m", subsurface=sub)},
                       spheres=(model.Sphere("m", (0.0, 0.0, 0.0), 1.0),))


def disk_mean(scene, image):
    """The mean radiance over the sphere's disk (3,): the image's sum (the sky is hidden from
    camera rays: 0 off the sphere) over the disk's area in pixels (32² stratum centres a
    pixel)."""
    x, y = tracer.sample_positions(scene.image.width, scene.image.height, 32)
    eye, d = tracer.camera_rays(scene, x, y)
    b = d @ eye
    area = float(((b < 0) & (eye @ eye - b * b < 1.0)).mean()) * scene.image.width * scene.image.height
    return image.reshape(-1, 3).sum(axis=0) / area


@pytest.mark.parametrize("colour", COLOURS, ids=["0.2-0.5-0.8", "0.95"])
@pytest.mark.parametrize("ior", IORS)
def test_the_reference_walk_shows_the_reflectance(ior, colour):
    scene = sphere_scene(colour, ior)
    image = volume.render_translucent(scene, SPP, seed=5, max_depth=VOLPATH_MAX_DEPTH,
                                      rr_depth=None)
    np.testing.assert_allclose(disk_mean(scene, image), colour, rtol=0.05)


@pytest.mark.parametrize("colour", COLOURS, ids=["0.2-0.5-0.8", "0.95"])
@pytest.mark.parametrize("ior", IORS)
def test_mitsuba_shows_the_reflectance(llvm, ior, colour):
    from mimarble.mitsuba.translate.scene_dict import to_mitsuba
    scene = sphere_scene(colour, ior)
    translated = to_mitsuba(scene, "path", spp=SPP)
    assert translated["integrator"]["max_depth"] == VOLPATH_MAX_DEPTH
    translated["integrator"]["rr_depth"] = VOLPATH_MAX_DEPTH        # no roulette
    assert translated["sphere_0"]["interior"]["reflectance"]["color"] == list(colour)
    image = np.array(mi.render(mi.load_dict(translated), seed=5), dtype=np.float64)
    np.testing.assert_allclose(disk_mean(scene, image), colour, rtol=0.05)


# ---------------------------------------------------------------------------
# The statistical agreement of the two renderers with a veined reflectance

def test_a_veined_reflectance_renders_as_the_reference_walk_does(llvm):
    """The project's path mode (translate.to_mitsuba: volpath around marble_medium, its
    reflectance inverted in Dr.Jit) against the float64 walk (its own inversion), a marble
    reflectance from white (α ≈ 0.998 at ior 1.5) to brown and a marble density, lit by the
    sky and a rectangle: tests/test_translucent_reference.py's block z-test. Roulette off
    in both (white would run Mitsuba's away). A reference that inverts as if the boundary
    were index-matched (F̄ = 0 for 1.5's 0.092) fails it (docs/rendering-model.md)."""
    from test_translucent_reference import (MARBLE_DENSITY, SEEDS, SIDE_LIGHT, agreement,
                                            translucent_scene)
    from mimarble.mitsuba.translate.scene_dict import to_mitsuba
    veins = model.MarbleChannel(function="sine", axis="x", period=3.0, distortion=0.6,
                                octaves=2, ramp=((0.93, 0.92, 0.9), (0.55, 0.35, 0.2)))
    base = translucent_scene(density=MARBLE_DENSITY, mean_free_path=0.25, lights=(SIDE_LIGHT,),
                             ambient=(0.6, 0.65, 0.7))
    sub = model.Subsurface(reflectance=veins, density=MARBLE_DENSITY, mean_free_path=0.25, ior=1.5)
    scene = model.Scene(image=base.image, camera=base.camera, ambient=base.ambient,
                        lights=base.lights, spheres=base.spheres,
                        materials={"m": model.Material("m", subsurface=sub)})
    translated = to_mitsuba(scene, "path", spp=24)
    depth = translated["integrator"]["max_depth"]
    translated["integrator"]["rr_depth"] = depth
    loaded = mi.load_dict(translated)
    renders = np.stack([np.array(mi.render(loaded, seed=3000 + k), dtype=np.float64)
                        for k in range(SEEDS)])
    image, variance = volume.render_translucent(scene, 192, seed=9, max_depth=depth,
                                                rr_depth=None, variance=True)
    ratio, z, m = agreement(scene, image, variance, 192, renders)
    assert ratio < 1, (z, m)
