"""The float64 random walk through translucent spheres (mimarble/reference/volume.py):
checked against closed forms (Fresnel, energy conservation, the mirror image of the
environment) and, statistically, against Mitsuba's own ``volpath`` and
``homogeneous`` / ``heterogeneous`` media behind the project's ``subsurface_boundary``
(whose lobes tests/test_subsurface_boundary.py checks on their own), which share nothing
with it.

**The statistical test** (:func:`agreement`). Both images are cut into 4×4-pixel blocks.
The reference gives each block's mean and, from its per-pixel sample variances, the
variance of that mean; Mitsuba renders K = :data:`SEEDS` independent seeds, and the spread
of a block's K means gives its standard error (K − 1 degrees of freedom). Per block and
colour z = (reference − Mitsuba)/√(se_ref² + se_mi²). Under agreement z is Student-t
distributed with Welch–Satterthwaite's degrees of freedom ν; the test fails when any |z|
passes the two-sided quantile of level α/m (Bonferroni over the m block-colours tested),
the t quantile from the normal one by its Cornish–Fisher expansion (Abramowitz & Stegun
26.7.5). α = :data:`ALPHA` = 10⁻³: the probability that correct renderers fail one
comparison is at most 10⁻³ (the seeds are fixed, so a run is reproducible; α says how
unlucky a seed would have to be). Blocks the sphere covers less than
:data:`COVERAGE` of are not tested: there only a few samples hit it and their variance
estimate is poor; blocks both renderers give exactly 0 (the hidden background) must agree
exactly. A planted error (albedo × 0.9, ior 1.2 for 1.5, the point light left out) fails
the same test.

Measured (24², 16 blocks × 3 colours tested, so m = 48 and the normal quantile
z* = 4.26; AMD EPYC Zen 3, 2 cores, llvm_ad_rgb), largest |z| of the tests below with the
``subsurface_boundary`` (issue 40): homogeneous, sky + sphere light + point light, 2.48
(Mitsuba 24 × 64 spp 1.3 s, reference 768 spp 1.0 s); max_depth 4 1.50; marble albedo
and density against the 64³ grid 2.42 (4.7 s together); a point light alone 1.97, a
rectangle alone 2.00; max_depth 2 against the closed form passes as before. Planted:
albedo × 0.9 32.7, ior 1.2 for 1.5 7.0, the point light left out 66.8 (ior 1.4, planted
against the former dielectric at 7.0, gives 3.3 now: the boundary's ior acts through F
and F̄ only). Over four more seed pairs each, the largest |z| stayed at 2.1–2.7
(homogeneous), 1.7–2.3 (rectangle), 2.0–2.7 (point light), as the largest of 48
|N(0, 1)| is (median 2.5); the mean z over the blocks did not grow with 4–16× the samples
(no bias). Before the walk estimated area lights at the exits (it met them by chance),
the rectangle alone gave |z| up to 5.4: the heavy tail of rare hits on a small bright
light.
"""

import math
import statistics

import numpy as np
import pytest

import mimarble
from mimarble.reference import channels, tracer, volume, volume_scene
from mimarble.scene import model

dr, mi = mimarble.dr, mimarble.mi

#: The family-wise probability of failing one comparison of correct renderers.
ALPHA = 1e-3
#: Mitsuba's independent renders per comparison (their spread gives its standard error).
SEEDS = 24
#: Pixels per block side.
BLOCK = 4
#: The least fraction of a block the sphere must cover for the block to be tested.
COVERAGE = 0.25
SIZE = 24                      # image side, pixels


# ---------------------------------------------------------------------------
# Scenes and the statistics

def translucent_scene(albedo=model.ColorChannel((0.9, 0.8, 0.6)), mean_free_path=0.3, ior=1.5,
                      density=None, lights=(), ambient=(1.0, 1.0, 1.0), size=SIZE):
    """A unit translucent sphere at the origin, seen from (0, 0.4, 5)."""
    sub = model.Subsurface(albedo=albedo, mean_free_path=mean_free_path, ior=ior, density=density)
    return model.Scene(
        image=model.Image(width=size, height=size),
        camera=model.Camera(eye=(0.0, 0.4, 5.0), lookat=(0.0, 0.0, 0.0), fov=30.0),
        ambient=ambient, lights=tuple(lights),
        materials={"m": model.Material("m", subsurface=sub)},
        spheres=(model.Sphere("m", (0.0, 0.0, 0.0), 1.0),))


BACK_LIGHT = model.Light((0.3, 0.6, -3.0), (0.2, 0.18, 0.15), area=model.SphereArea(0.5))
POINT_LIGHT = model.Light((2.0, 3.0, 4.0), (1.0, 1.0, 1.0))
SIDE_LIGHT = model.Light((2.5, 0.5, 1.0), (0.3, 0.3, 0.3),
                         area=model.RectangleArea((0.0, 1.0, 0.0), (-0.4, 0.0, 1.0)))

MARBLE_ALBEDO = model.MarbleChannel(function="sine", axis="x", period=3.0, distortion=0.6,
                                    octaves=2, ramp=((0.97, 0.95, 0.9), (0.55, 0.35, 0.2)))
MARBLE_DENSITY = model.MarbleChannel(function="sine", axis="y", period=2.5, distortion=0.5,
                                     octaves=2, ramp=((0.4, 0.4, 0.4), (1.6, 1.4, 1.5)))


def coverage(scene, n=16):
    """The fraction of each pixel whose camera ray meets a sphere (n×n stratum centres),
    (H, W)."""
    w, h = scene.image.width, scene.image.height
    x, y = tracer.sample_positions(w, h, n)
    eye, d = tracer.camera_rays(scene, x, y)
    met = np.zeros(len(d), dtype=bool)
    for sphere in scene.spheres:
        oc = eye - np.array(sphere.center)
        b = d @ oc
        met |= (b < 0) & (oc @ oc - b * b < sphere.radius ** 2)
    return met.reshape(h, w, n * n).mean(axis=2)


def blocks(image):
    """(…, H, W, C) → (…, H/B, W/B, C): each block's mean."""
    *lead, h, w, c = image.shape
    return image.reshape(*lead, h // BLOCK, BLOCK, w // BLOCK, BLOCK, c).mean(axis=(-4, -2))


def t_quantile(z, nu):
    """Student's t quantile from the normal quantile z at ν degrees of freedom (Cornish–Fisher,
    Abramowitz & Stegun 26.7.5; within 10⁻³ of it from ν = 10 at z ≤ 5)."""
    return (z + (z ** 3 + z) / (4 * nu) + (5 * z ** 5 + 16 * z ** 3 + 3 * z) / (96 * nu ** 2)
            + (3 * z ** 7 + 19 * z ** 5 + 17 * z ** 3 - 15 * z) / (384 * nu ** 3))


def agreement(scene, reference, variance, spp, renders):
    """(largest |z|/threshold over the tested block-colours, largest |z|, tests m); fails
    (AssertionError) where blocks both exactly zero in one renderer are not so in the other."""
    covered = blocks(coverage(scene)[..., None])[..., 0] >= COVERAGE
    ref = blocks(reference)
    se_ref2 = blocks(variance / spp) / BLOCK ** 2
    nu_ref = BLOCK ** 2 * (spp - 1)
    mine = blocks(renders)
    mi_mean = mine.mean(axis=0)
    se_mi2 = mine.var(axis=0, ddof=1) / len(renders)
    nu_mi = len(renders) - 1
    total = se_ref2 + se_mi2
    empty = ~covered[..., None] & (total == 0)
    assert np.array_equal(ref[empty], mi_mean[empty]), "blocks off the sphere differ"
    tested = covered[..., None] & (total > 0)
    m = int(tested.sum())
    z = (ref - mi_mean)[tested] / np.sqrt(total[tested])
    nu = total[tested] ** 2 / (se_ref2[tested] ** 2 / nu_ref + se_mi2[tested] ** 2 / nu_mi)
    z_star = statistics.NormalDist().inv_cdf(1 - ALPHA / (2 * m))
    ratio = np.abs(z) / t_quantile(z_star, nu)
    return float(ratio.max()), float(np.abs(z).max()), m


# ---------------------------------------------------------------------------
# Mitsuba's side, built here: volpath, subsurface_boundary, Mitsuba's own media

def _homogeneous(sub, sphere):
    return {"type": "homogeneous", "albedo": {"type": "rgb", "value": list(sub.albedo.rgb)},
            "sigma_t": 1.0 / sub.mean_free_path}


GRID = 64     # voxels a side of the baked albedo and density


def _grid_medium(sub, sphere):
    """Mitsuba's ``heterogeneous`` medium with the albedo and σ_t baked on a GRID³ grid of
    voxel centres over the sphere's box (one voxel wider each side, so that every point of
    the sphere is interpolated, not clamped)."""
    c, r = np.array(sphere.center), sphere.radius
    h = 2 * r / (GRID - 2)
    lo = c - r - h
    side = GRID * h
    at = (np.arange(GRID) + 0.5) * h
    zz, yy, xx = np.meshgrid(lo[2] + at, lo[1] + at, lo[0] + at, indexing="ij")
    points = np.stack([xx.ravel(), yy.ravel(), zz.ravel()], axis=1)
    albedo = np.clip(channels.channel_color(sub.albedo, points), 0, 1)
    density = np.ones(len(points)) if sub.density is None else \
        np.maximum(channels.channel_color(sub.density, points).mean(axis=1), 0)
    to_world = mi.ScalarTransform4f().translate(list(lo)).scale(side)
    return {"type": "heterogeneous", "has_spectral_extinction": False,
            "albedo": {"type": "gridvolume", "raw": True, "to_world": to_world,
                       "data": mi.TensorXf(albedo.reshape(GRID, GRID, GRID, 3).astype(np.float32))},
            "sigma_t": {"type": "gridvolume", "raw": True, "to_world": to_world,
                        "data": mi.TensorXf((density / sub.mean_free_path)
                                            .reshape(GRID, GRID, GRID, 1).astype(np.float32))}}


def mitsuba_dict(scene, spp, max_depth, medium=_homogeneous):
    from mimarble.mitsuba.translate import scene_dict as translate
    out = {"type": "scene",
           "integrator": {"type": "volpath", "max_depth": max_depth, "hide_emitters": True},
           "sensor": translate._sensor(scene, {"type": "independent", "sample_count": spp})}
    for k, sphere in enumerate(scene.spheres):
        sub = scene.materials[sphere.material].subsurface
        out[f"sphere_{k}"] = {"type": "sphere", "center": list(sphere.center),
                              "radius": sphere.radius,
                              "bsdf": {"type": "subsurface_boundary", "int_ior": sub.ior,
                                       "ext_ior": 1.0},
                              "interior": medium(sub, sphere)}
    for k, light in enumerate(scene.lights):
        if light.area is not None:
            out[f"light_{k}"] = translate.area_light_dict(light, scene.camera.lookat, "path")
        else:     # path mode's point light (translate.to_mitsuba): I·π·d²
            d2 = math.dist(light.position, scene.camera.lookat) ** 2
            out[f"light_{k}"] = {"type": "point", "position": list(light.position),
                                 "intensity": {"type": "rgb",
                                               "value": [c * math.pi * d2 for c in light.color]}}
    out["ambient"] = {"type": "constant", "radiance": {"type": "rgb", "value": list(scene.ambient)}}
    return out


def mitsuba_renders(scene, spp, max_depth, medium=_homogeneous, seeds=SEEDS):
    """(SEEDS, H, W, 3) float64: independent llvm_ad_rgb renders."""
    loaded = mi.load_dict(mitsuba_dict(scene, spp, max_depth, medium))
    return np.stack([np.array(mi.render(loaded, seed=1000 + k), dtype=np.float64)
                     for k in range(seeds)])


# ---------------------------------------------------------------------------
# Closed forms

def fresnel_by_angles(theta_i, eta):
    """Fresnel's reflectance from the angles (the sine and tangent laws), unpolarised."""
    theta_t = np.arcsin(np.sin(theta_i) / eta)
    s = np.sin(theta_i - theta_t) / np.sin(theta_i + theta_t)
    p = np.tan(theta_i - theta_t) / np.tan(theta_i + theta_t)
    return 0.5 * (s * s + p * p)


def test_fresnel_matches_the_sine_and_tangent_laws():
    rng = np.random.default_rng(1)
    for eta in (1.5, 1.33, 2.4, 1 / 1.5, 0.8):
        critical = math.asin(min(eta, 1.0)) if eta < 1 else math.pi / 2
        theta = rng.uniform(1e-3, critical - 1e-3, 200)
        f, cos_t = volume.fresnel_dielectric(np.cos(theta), eta)
        assert np.allclose(f, fresnel_by_angles(theta, eta), rtol=1e-10, atol=1e-14)
        assert np.allclose(cos_t, np.cos(np.arcsin(np.sin(theta) / eta)), atol=1e-12)
    f, _ = volume.fresnel_dielectric(np.array([1.0]), 1.5)
    assert f[0] == pytest.approx(0.04, abs=1e-15)               # ((η − 1)/(η + 1))²
    brewster = math.atan(1.5)                                    # r_p = 0 there
    f, _ = volume.fresnel_dielectric(np.array([math.cos(brewster)]), 1.5)
    rs = math.sin(brewster - math.atan(1 / 1.5)) ** 2 / math.sin(brewster + math.atan(1 / 1.5)) ** 2
    assert f[0] == pytest.approx(rs / 2, rel=1e-12)
    f, cos_t = volume.fresnel_dielectric(np.cos(np.array([0.75, 1.2, 1.5])), 1 / 1.5)
    assert np.all(f == 1.0) and np.all(cos_t == 0.0)            # past asin(1/1.5) = 0.7297
    f, _ = volume.fresnel_dielectric(np.array([0.0, 0.3, 1.0]), 1.0)
    assert np.allclose(f[1:], 0.0) and f[0] == 1.0              # index matched; grazing: 1


@pytest.mark.parametrize("eta", [1.5, 1.33, 2.4, 0.8])
def test_the_walks_mean_fresnel_reflectance_matches_the_midpoint_rule(eta):
    from mimarble.reference.subsurface_reflectance import diffuse_fresnel_reflectance
    """The walk's F̄ = ∫₀¹ F(μ) 2μ dμ against 200 000 midpoints in θ of the sine and tangent
    laws (F = 1 past the critical angle where η < 1), and 0 at η = 1."""
    n = 200_000
    theta = (np.arange(n) + 0.5) * (0.5 * math.pi / n)
    critical = math.asin(eta) if eta < 1 else math.pi / 2
    f = np.where(theta < critical, fresnel_by_angles(np.minimum(theta, critical - 1e-12), eta), 1.0)
    expected = float(np.sum(f * np.sin(2 * theta)) * (0.5 * math.pi / n))
    assert diffuse_fresnel_reflectance(eta) == pytest.approx(expected, abs=1e-7)
    assert diffuse_fresnel_reflectance(1.0) == 0.0


def test_channel_interval_bounds_every_value():
    rng = np.random.default_rng(2)
    points = rng.uniform(-3, 3, (4000, 3))
    a = MARBLE_DENSITY
    b = model.ColorChannel((0.5, -0.2, 2.0))
    for channel in (a, b, model.Add((a, b)), model.Multiply((a, b, a)),
                    model.Mix(a, b, 0.3), model.Mix(a, b, MARBLE_ALBEDO),
                    model.Multiply((model.Add((a, model.ColorChannel((-1.0, -1.0, -1.0)))), b))):
        lo, hi = volume_scene.channel_interval(channel)
        values = channels.channel_color(channel, points)
        assert np.all(values >= lo - 1e-12) and np.all(values <= hi + 1e-12), channel
    lo, hi = volume_scene.channel_interval(model.Multiply((b, model.ColorChannel((-2.0, 1.0, 0.5)))))
    assert np.allclose(lo, [-1.0, -0.2, 1.0]) and np.allclose(hi, lo)
    sub = model.Subsurface(albedo=b, mean_free_path=0.5, density=model.Add((a, b)))
    # mean of the upper bounds (1.6 + 0.5, 1.4 − 0.2, 1.5 + 2)/3
    assert volume_scene.density_bound(sub) == pytest.approx((2.1 + 1.2 + 3.5) / 3)


def test_white_sphere_under_a_white_sky_returns_the_sky_exactly():
    """Energy conservation (the furnace test): albedo 1, no Russian roulette, an
    index-matched boundary (F = 0, W = 1), so every path leaves with weight 1 to a sky of
    radiance A, through the null collisions of a marble density: a pixel the sphere
    covers is A exactly (to rounding), whatever the walk did (none reaches depth 256 here)."""
    scene = translucent_scene(albedo=model.ColorChannel((1.0, 1.0, 1.0)), mean_free_path=0.2,
                              density=MARBLE_DENSITY, ambient=(0.7, 0.5, 0.25), size=16, ior=1.0)
    image, variance = volume.render_translucent(scene, 16, seed=3, rr_depth=None, variance=True)
    full = coverage(scene) == 1.0
    assert full.sum() > 50
    # (to the rounding of a sum of 16 equal numbers)
    assert np.allclose(image[full], [0.7, 0.5, 0.25], rtol=1e-14, atol=0)
    assert np.all(variance[full] < 1e-15)
    assert np.all(image[coverage(scene) == 0.0] == 0.0)          # the hidden sky


def test_white_sphere_under_a_white_sky_returns_the_sky_on_average_at_ior_1_5():
    """The furnace at ior 1.5: a path reflects (weight 1) or enters (weight 1) and leaves
    with the weight W(μₒ) = (1 − F(μₒ))/(1 − F̄), whose mean over the cosine-distributed
    exit is 1: the covered pixels' mean is A within its standard error (z-test, normal
    quantile of 10⁻³), and single paths are not all A (the exit weight varies)."""
    scene = translucent_scene(albedo=model.ColorChannel((1.0, 1.0, 1.0)), mean_free_path=0.2,
                              ambient=(0.7, 0.5, 0.25), size=16)
    spp = 64
    image, variance = volume.render_translucent(scene, spp, seed=3, rr_depth=None, variance=True)
    full = coverage(scene) == 1.0
    mean = image[full].mean(axis=0)
    se = np.sqrt(variance[full].sum(axis=0) / spp) / full.sum()
    z = np.abs(mean - [0.7, 0.5, 0.25]) / se
    assert z.max() < statistics.NormalDist().inv_cdf(1 - ALPHA / 2), (mean, z)
    assert variance[full].max() > 0


def reflection_only(scene, n=12):
    """Each pixel's mean of A·F(θ) over its n×n stratum centres (0 off the sphere): what a
    path tracer sees of the environment mirrored by the sphere, nothing refracted."""
    w, h = scene.image.width, scene.image.height
    x, y = tracer.sample_positions(w, h, n)
    eye, d = tracer.camera_rays(scene, x, y)
    sphere = scene.spheres[0]
    oc = eye - np.array(sphere.center)
    b = d @ oc
    miss2 = np.maximum(oc @ oc - b * b, 0.0)
    met = (b < 0) & (miss2 < sphere.radius ** 2)
    theta = np.arcsin(np.sqrt(np.minimum(miss2, sphere.radius ** 2)) / sphere.radius)
    eta = scene.materials[sphere.material].subsurface.ior
    with np.errstate(invalid="ignore", divide="ignore"):
        f = np.where(theta > 1e-9, fresnel_by_angles(np.maximum(theta, 1e-9), eta),
                     ((eta - 1) / (eta + 1)) ** 2)
    f = np.where(met, np.nan_to_num(f, nan=1.0), 0.0)
    return f.reshape(h, w, n * n).mean(axis=2)[..., None] * np.array(scene.ambient)


def test_max_depth_two_shows_the_mirrored_sky_only():
    """max_depth 2 in volpath's meaning: the camera ray's hit on the sphere is vertex 1, so
    only paths that reflect there and escape (k = 1 < 2) add light; refracted ones end at
    their next event. The image is then A·F(θ) averaged over each pixel (θ the angle of
    incidence, F from the sine and tangent laws). Checked block by block with the same
    z-test, the closed form having no noise (its quadrature error, ~10⁻⁴ at the silhouette,
    is below the test's resolution)."""
    scene = translucent_scene(ambient=(1.0, 0.8, 0.6))
    spp = 64
    image, variance = volume.render_translucent(scene, spp, seed=4, max_depth=2, variance=True)
    expected = reflection_only(scene)
    covered = blocks(coverage(scene)[..., None])[..., 0] >= COVERAGE
    se = np.sqrt(blocks(variance / spp) / BLOCK ** 2)[covered]
    z = (blocks(image) - blocks(expected))[covered] / se
    z_star = statistics.NormalDist().inv_cdf(1 - ALPHA / (2 * z.size))
    assert np.abs(z).max() < z_star, np.abs(z).max()


# ---------------------------------------------------------------------------
# Against Mitsuba

@pytest.fixture(scope="module")
def llvm_variant():
    from mimarble.runtime import environment
    problem = environment.variant_problem("llvm_ad_rgb")
    if problem:
        pytest.skip(problem)
    previous = mi.variant()
    mi.set_variant("llvm_ad_rgb")
    yield
    if previous:
        mi.set_variant(previous)


HOMOGENEOUS = translucent_scene(lights=(BACK_LIGHT, POINT_LIGHT))


@pytest.fixture(scope="module")
def homogeneous_renders(llvm_variant):
    """Mitsuba's renders of HOMOGENEOUS at volume.MAX_DEPTH (a point light included: both
    reach it by next-event estimation at exit points)."""
    return mitsuba_renders(HOMOGENEOUS, 64, volume.MAX_DEPTH)


REF_SPP = 768


@pytest.fixture(scope="module")
def homogeneous_reference():
    return volume.render_translucent(HOMOGENEOUS, REF_SPP, seed=5, variance=True)


def test_homogeneous_sphere_agrees_with_mitsuba(homogeneous_renders, homogeneous_reference):
    image, variance = homogeneous_reference
    ratio, z, m = agreement(HOMOGENEOUS, image, variance, REF_SPP, homogeneous_renders)
    assert ratio < 1, (z, m)


@pytest.mark.parametrize("planted", ["albedo × 0.9", "ior 1.2", "no point light"])
def test_a_planted_error_fails_the_agreement(planted, homogeneous_renders):
    sub = HOMOGENEOUS.materials["m"].subsurface
    lights = HOMOGENEOUS.lights
    if planted == "ior 1.2":
        wrong = model.Subsurface(sub.albedo, sub.mean_free_path, ior=1.2)
    elif planted == "no point light":
        wrong, lights = sub, tuple(light for light in lights if light.area is not None)
    else:
        wrong = model.Subsurface(model.ColorChannel(tuple(0.9 * c for c in sub.albedo.rgb)),
                                 sub.mean_free_path, ior=sub.ior)
    scene = model.Scene(image=HOMOGENEOUS.image, camera=HOMOGENEOUS.camera,
                        ambient=HOMOGENEOUS.ambient, lights=lights,
                        materials={"m": model.Material("m", subsurface=wrong)},
                        spheres=HOMOGENEOUS.spheres)
    image, variance = volume.render_translucent(scene, REF_SPP, seed=5, variance=True)
    ratio, z, m = agreement(HOMOGENEOUS, image, variance, REF_SPP, homogeneous_renders)
    assert ratio > 1, (z, m)


def test_single_scattering_depth_agrees_with_mitsuba(llvm_variant):
    """max_depth 4: in (1), one collision (2), out (3), the sky or the light (k = 3 < 4),
    or a mirror path of as many vertices: the depth is counted as volpath counts it."""
    scene = translucent_scene(lights=(BACK_LIGHT,))
    renders = mitsuba_renders(scene, 32, 4)
    image, variance = volume.render_translucent(scene, 256, seed=6, max_depth=4, variance=True)
    ratio, z, m = agreement(scene, image, variance, 256, renders)
    assert ratio < 1, (z, m)


@pytest.mark.parametrize("light", ["point", "rectangle"])
def test_a_sphere_under_one_light_alone_is_lit_and_agrees_with_mitsuba(light, llvm_variant):
    """No ambient light: a point light (reached only by next-event estimation at the exit
    points, in both renderers) or a rectangular area light (Mitsuba: NEE with MIS; the
    walk: by hitting it) lights the sphere — not black — and the two agree."""
    scene = translucent_scene(lights=(POINT_LIGHT if light == "point" else SIDE_LIGHT,),
                              ambient=(0.0, 0.0, 0.0))
    renders = mitsuba_renders(scene, 32, volume.MAX_DEPTH)
    image, variance = volume.render_translucent(scene, 384, seed=9, variance=True)
    covered = coverage(scene) > 0.5
    assert image[covered].mean() > 0.02 and renders.mean(axis=0)[covered].mean() > 0.02
    ratio, z, m = agreement(scene, image, variance, 384, renders)
    assert ratio < 1, (z, m)


MARBLED = translucent_scene(albedo=MARBLE_ALBEDO, density=MARBLE_DENSITY, mean_free_path=0.25,
                            lights=(SIDE_LIGHT,), ambient=(0.6, 0.65, 0.7))


def test_marble_albedo_and_density_agree_with_mitsuba(llvm_variant):
    """The marble albedo and density against Mitsuba's ``heterogeneous`` medium of the same
    channels baked on a 64³ grid (trilinear: the bake's error, ~(k·h)²/8 ≈ 10⁻³ of the
    ramp's range for the stripes' wavenumber k = 3 and voxel h = 1/31, is far below the
    test's resolution), lit by the sky and a rectangle to the side. The reference's
    majorant is its interval bound (1.6/0.25), Mitsuba's its grid's maximum: other null
    collisions, the same expectation."""
    renders = mitsuba_renders(MARBLED, 48, volume.MAX_DEPTH, _grid_medium)
    image, variance = volume.render_translucent(MARBLED, 256, seed=7, variance=True)
    ratio, z, m = agreement(MARBLED, image, variance, 256, renders)
    assert ratio < 1, (z, m)


def test_the_project_path_mode_agrees_where_it_renders_subsurface(llvm_variant):
    """The project's own translation of a subsurface scene (translate.to_mitsuba, path mode:
    volpath around its marble_medium), once it exists, against the walk at the translator's
    max_depth."""
    import mimarble.mitsuba.plugins.marble_medium  # noqa: F401  (an import error fails, not skips)
    from mimarble.mitsuba.translate import scene_dict as translate
    translated = translate.to_mitsuba(MARBLED, "path", spp=48)
    assert translated["integrator"]["type"] == "volpath"
    depth = translated["integrator"].get("max_depth", -1)
    loaded = mi.load_dict(translated)
    renders = np.stack([np.array(mi.render(loaded, seed=2000 + k), dtype=np.float64)
                        for k in range(SEEDS)])
    image, variance = volume.render_translucent(MARBLED, 256, seed=8, max_depth=depth,
                                                variance=True)
    ratio, z, m = agreement(MARBLED, image, variance, 256, renders)
    assert ratio < 1, (z, m)


def test_the_pass_renderer_stratified_agrees_with_the_walk(llvm_variant):
    """``mimarble.render`` in path mode — the pass renderer, whose translucent scenes draw a
    pixel's samples as one stratified (``multijitter``) sequence (rendering/passes.py,
    ``stratify``) — against the walk, on long walks: a reflectance from white (α ≈ 0.998 at
    ior 1.5) to brown, a marble density, the sky and a rectangle. Stratified samples are
    still an unbiased estimate (each sample alone is uniform; Mitsuba's samplers permute
    each dimension apart, its dimension index carried through volpath's loop), and the
    spread of :data:`SEEDS` seeds still gives its standard error (each seed's render is
    independent of the others)."""
    from mimarble.contract import VOLPATH_MAX_DEPTH
    from mimarble.mitsuba.translate.modes import translucent_sampler
    assert translucent_sampler(48)["type"] == "multijitter"
    veins = model.MarbleChannel(function="sine", axis="x", period=3.0, distortion=0.6,
                                octaves=2, ramp=((0.93, 0.92, 0.9), (0.55, 0.35, 0.2)))
    sub = model.Subsurface(reflectance=veins, density=MARBLE_DENSITY, mean_free_path=0.25,
                           ior=1.5)
    base = translucent_scene(lights=(SIDE_LIGHT,), ambient=(0.6, 0.65, 0.7))
    scene = model.Scene(image=base.image, camera=base.camera, ambient=base.ambient,
                        lights=base.lights, spheres=base.spheres,
                        materials={"m": model.Material("m", subsurface=sub)})
    renders = np.stack([np.asarray(mimarble.render(scene, mode="path", spp=48, seed=4000 + k),
                                   dtype=np.float64) for k in range(SEEDS)])
    image, variance = volume.render_translucent(scene, 192, seed=9, max_depth=VOLPATH_MAX_DEPTH,
                                                variance=True)
    ratio, z, m = agreement(scene, image, variance, 192, renders)
    assert ratio < 1, (z, m)


# ---------------------------------------------------------------------------
# What the walk refuses

@pytest.mark.parametrize("change, words", [
    ({"planes": (model.Plane("m"),)}, "translucent spheres only"),
    ({"materials": {"m": model.Material("m", diffuse=model.ColorChannel((1, 1, 1)))}},
     "has no subsurface"),
    ({"spheres": (model.Sphere("m", (0, 0, 0), 1.0), model.Sphere("m", (1.5, 0, 0), 1.0))},
     "overlap"),
    ({"camera": model.Camera(eye=(0.0, 0.0, 0.5))}, "eye is inside"),
    ({"lights": (model.Light((0.0, 0.0, 1.2), area=model.SphereArea(0.5)),)}, "meets sphere_0"),
    ({"lights": (model.Light((0.0, 0.0, 0.9), area=model.RectangleArea((1, 0, 0), (0, 1, 0))),)},
     "meets sphere_0"),
])
def test_scenes_it_cannot_render_are_refused_in_one_sentence(change, words):
    fields = dict(image=model.Image(width=8, height=8), camera=model.Camera(),
                  materials={"m": model.Material("m", subsurface=model.Subsurface(
                      model.ColorChannel((0.5, 0.5, 0.5)), 0.5))},
                  spheres=(model.Sphere("m", (0, 0, 0), 1.0),))
    fields.update(change)
    with pytest.raises(ValueError, match=words) as caught:
        volume.render_translucent(model.Scene(**fields), 1)
    assert "\n" not in str(caught.value)


def test_rectangle_lights_clear_of_the_sphere_are_accepted():
    scene = translucent_scene(lights=(SIDE_LIGHT,), size=8)
    assert volume.render_translucent(scene, 1).shape == (8, 8, 3)


def test_the_seed_decides_the_image():
    scene = translucent_scene(size=8)
    a = volume.render_translucent(scene, 4, seed=11)
    assert np.array_equal(a, volume.render_translucent(scene, 4, seed=11))
    assert not np.array_equal(a, volume.render_translucent(scene, 4, seed=12))
