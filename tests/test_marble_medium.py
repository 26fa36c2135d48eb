"""The ``marble_medium`` plugin (issue 26): a heterogeneous medium with texture albedo and
density, under Mitsuba's ``volpath`` and ``prbvolpath``.

Checked against what does not come from it: Mitsuba's own ``homogeneous`` and
``heterogeneous`` media (the latter with the marble baked on a grid by the float64
reference, mimarble/tools/bake.py), the float64 reference channels
(mimarble/reference/channels.py) for the coefficients, and finite differences for the
gradients.

Same seed, same majorant: Mitsuba's samplers hand both media the same random numbers, and a
medium's albedo enters the walk only as the weight σ_s/σ_t of a real collision (Russian
roulette off: rr_depth = max_depth), so the two walks take the same paths and the images
differ only by what the albedos differ by at the same points.
"""

import dataclasses
import math

import numpy as np
import pytest

import mimarble
from mimarble.tools import bake
from mimarble.texture import error_budget
from mimarble import scene as S
from mimarble.mitsuba.plugins.marble_medium import MarbleMedium, MarbleMediumError
from mimarble.mitsuba.translate.scene_dict import texture_dict
from mimarble.reference.channels import channel_color

dr, mi = mimarble.dr, mimarble.mi

MAX_DEPTH = 64
ALBEDO = (0.9, 0.6, 0.3)
#: A smooth marble (the ``sine`` wave, 2 octaves, a 3-colour ramp): C² but at the ramp's
#: middle key, so a grid's trilinear error falls as h² over most of the volume.
SMOOTH = S.parse("""
material "m" { diffuse { marble { function sine scale 0.7 period 2 distortion 1.5 octaves 2
    ramp { < 0.95 0.9 0.8 > < 0.6 0.5 0.3 > < 0.9 0.2 0.1 > } } } }
sphere { center < 0 0 0 > radius 1 material "m" }
""")
VEINS = S.MarbleChannel(octaves=4, period=2.0, ramp=((0.3, 0.3, 0.3), (1.0, 1.0, 1.0)))


def sphere_scene(interior, size=32, spp=16):
    """A unit sphere, smooth dielectric (IOR 1.5), ``interior`` inside, under a constant
    white sky, seen whole from z = 5."""
    return {"type": "scene",
            "integrator": {"type": "volpath", "max_depth": MAX_DEPTH, "rr_depth": MAX_DEPTH},
            "sensor": {"type": "perspective", "fov": 30,
                       "to_world": mi.ScalarTransform4f().look_at([0, 0, 5], [0, 0, 0], [0, 1, 0]),
                       "film": {"type": "hdrfilm", "width": size, "height": size,
                                "rfilter": {"type": "box"}},
                       "sampler": {"type": "independent", "sample_count": spp}},
            "sky": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
            "sphere": {"type": "sphere", "bsdf": {"type": "dielectric", "int_ior": 1.5},
                       "interior": interior}}


def rendered(scene_dict, seed=3):
    return np.array(mi.render(mi.load_dict(scene_dict), seed=seed))


def one_colour_marble(rgb):
    return {"type": "marble", "ramp_0": {"type": "rgb", "value": list(rgb)}}


def medium_interactions(points):
    """Medium interactions at (n, 3) points (JIT variants: one batch; scalar: a list)."""
    points = np.asarray(points, dtype=np.float32)
    if not dr.is_jit_v(mi.Float):
        out = []
        for p in points:
            mei = dr.zeros(mi.MediumInteraction3f)
            mei.p = mi.Point3f(*map(float, p))
            out.append(mei)
        return out
    mei = dr.zeros(mi.MediumInteraction3f, len(points))
    mei.p = mi.Point3f(*(mi.Float(points[:, k]) for k in range(3)))
    return [mei]


def coefficients(medium, points):
    """(σ_s, σ_n, σ_t) at the points, each (n, 3) float64."""
    parts = [[np.array(c, dtype=np.float64).reshape(3, -1).T
              for c in medium.get_scattering_coefficients(mei, True)]
             for mei in medium_interactions(points)]
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(3))


def in_ball(n, radius, seed):
    rng = np.random.default_rng(seed)
    p = rng.uniform(-radius, radius, (3 * n, 3))
    return p[np.linalg.norm(p, axis=1) < radius][:n]


# ---------------------------------------------------------------------------

@pytest.mark.parametrize("density", [None, 0.5], ids=["no density", "constant density"])
def test_a_constant_medium_renders_as_mitsubas_homogeneous_medium(variant, density):
    """σ_t = 2 either way (scale 2, or scale 4 · density 0.5 at its bound): the majorant is
    σ_t, σ_n = 0, and the walk is the homogeneous medium's, random number for random
    number (module docstring): the images are equal to float32 rounding of σ_s/σ_t."""
    size, spp = (32, 16) if dr.is_jit_v(mi.Float) else (8, 4)
    ours = {"type": "marble_medium", "albedo": one_colour_marble(ALBEDO), "scale": 2.0,
            "sample_emitters": False}
    if density is not None:
        ours.update(density={"type": "rgb", "value": [density] * 3}, density_bound=density,
                    scale=2.0 / density)
    theirs = {"type": "homogeneous", "albedo": {"type": "rgb", "value": list(ALBEDO)},
              "sigma_t": 2.0, "has_spectral_extinction": False, "sample_emitters": False}
    a, b = rendered(sphere_scene(ours, size, spp)), rendered(sphere_scene(theirs, size, spp))
    assert 0.3 < a.mean() < 0.95                       # the sphere is there, and lit
    np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)


def grid_medium(path, sigma_t):
    """Mitsuba's ``heterogeneous`` medium: albedo the grid at ``path``, σ_t constant over a
    box around the unit sphere (a ``constvolume``'s box is its to_world's unit cube, and
    the medium exists only inside its σ_t's box)."""
    box = mi.ScalarTransform4f().translate([-1.5] * 3) @ mi.ScalarTransform4f().scale(3.0)
    return {"type": "heterogeneous",
            "albedo": {"type": "gridvolume", "filename": str(path), "use_grid_bbox": True,
                       "raw": True, "filter_type": "trilinear", "wrap_mode": "clamp"},
            "sigma_t": {"type": "constvolume", "value": sigma_t, "to_world": box},
            "has_spectral_extinction": False, "sample_emitters": False}


def test_a_marble_albedo_renders_as_its_baked_grid_converging_as_trilinear_interpolation(
        llvm, tmp_path):
    """The reference marble baked on N³ grids (mimarble/tools/bake.py) under ``heterogeneous``, the
    same seed and majorant (σ_t = 4): per path |ΔL| ≤ Σ_k |Δα(p_k)| over its collisions,
    so the images differ by the grid's interpolation error, O(h²) for this smooth marble.
    Measured (mean |Δ| over the 32² image): 1.5e-4 at 32³, 3.7e-5 at 64³ (ratio 4.0; the
    grid's own mean error at random points: 1.6e-3, 4.0e-4). Asserted: below 1e-4 at 64³
    and a ratio above 3 (h²: 4; a medium that missed the marble would not converge)."""
    ours = {"type": "marble_medium", "albedo": texture_dict(SMOOTH.materials["m"].diffuse),
            "scale": 4.0, "sample_emitters": False}
    image = rendered(sphere_scene(ours))
    errors = {}
    for n in (32, 64):
        path = tmp_path / f"albedo{n}.vol"
        bake.bake_volume(SMOOTH, "sphere_0", path, n)
        errors[n] = np.abs(image - rendered(sphere_scene(grid_medium(path, 4.0)))).mean()
    assert errors[64] < 1e-4, errors
    assert errors[32] / errors[64] > 3.0, errors


def test_the_coefficients_are_the_channels_clamped_as_the_model_says(variant):
    """σ_t = scale·clamp(mean(density), 0, bound), σ_s = clamp(albedo, 0, 1)·σ_t,
    σ_n = scale·bound − σ_t, against the float64 reference channels; channels that leave
    [0, 1] (an offset colour added) and a bound below the density's largest, so that every
    clamp acts."""
    albedo = S.Add((VEINS, S.ColorChannel((-0.5, 0.2, 0.4))))
    density = S.Add((VEINS, S.ColorChannel((-0.5, -0.5, -0.5))))
    scale, bound = 3.0, 0.3
    medium = mi.load_dict({"type": "marble_medium", "albedo": texture_dict(albedo),
                           "density": texture_dict(density), "scale": scale,
                           "density_bound": bound})
    points = in_ball(64 if dr.is_jit_v(mi.Float) else 16, 1.0, seed=1)
    d = np.clip(channel_color(density, points).mean(axis=1), 0.0, bound)
    alpha = np.clip(channel_color(albedo, points), 0.0, 1.0)
    assert (d == 0).any() and (d == bound).any() and ((d > 0) & (d < bound)).any()
    assert (alpha == 0).any() and (alpha == 1).any()
    sigma_s, sigma_n, sigma_t = coefficients(medium, points)
    tolerance = scale * error_budget.DEFAULT_TOLERANCE     # the marble's own error budget
    np.testing.assert_allclose(sigma_t, np.repeat(scale * d[:, None], 3, 1), atol=tolerance)
    np.testing.assert_allclose(sigma_s, alpha * scale * d[:, None], atol=tolerance)
    np.testing.assert_allclose(sigma_n, scale * bound - sigma_t, atol=1e-6)


def tentative_collisions(medium, n=1 << 15, seed=2):
    """Mitsuba's ``sample_interaction`` on rays from random points of the unit ball in
    random directions, up to the sphere: the valid tentative collisions' (σ_t/σ̄, σ_n, p)."""
    rng = np.random.default_rng(seed)
    o = in_ball(n, 1.0, seed)
    d = rng.normal(size=(len(o), 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    od = (o * d).sum(1)
    exit_t = -od + np.sqrt(od ** 2 - (o * o).sum(1) + 1.0)      # |o + t d| = 1, t > 0
    f = lambda a: [mi.Float(a[:, k].astype(np.float32)) for k in range(a.shape[1])]  # noqa: E731
    ray = mi.Ray3f(mi.Point3f(*f(o)), mi.Vector3f(*f(d)))
    ray.maxt = mi.Float(exit_t.astype(np.float32))
    mei = medium.sample_interaction(ray, mi.Float(rng.uniform(size=len(o)).astype(np.float32)),
                                    mi.UInt32(0), mi.Bool(True))
    valid = np.array(mei.is_valid())
    ratio = np.array(mei.sigma_t[0] / mei.combined_extinction[0])[valid]
    return ratio, np.array(mei.sigma_n[0])[valid], np.array(mei.p).T[valid]


def test_the_majorant_is_tight_no_null_collisions_at_a_constant_density(llvm):
    medium = mi.load_dict({"type": "marble_medium", "albedo": one_colour_marble(ALBEDO),
                           "density": {"type": "rgb", "value": [0.25] * 3},
                           "density_bound": 0.25, "scale": 8.0})
    ratio, sigma_n, _ = tentative_collisions(medium)
    assert len(ratio) > 10_000
    assert (sigma_n == 0).all() and (ratio == 1).all()        # every collision is real


def test_a_marble_density_under_its_channel_bound_collides_really_as_often_as_d_over_bound(llvm):
    """The channel bound (error_budget.channel_bound: every component's, so the mean's too)
    holds: σ_n ≥ 0 at every
    tentative collision, and the share of real ones, the mean of σ_t/σ̄, is the
    reference's d/bound at the same points. Measured efficiency: 0.74 for these veins
    (a grey ramp from 0.3 to 1)."""
    bound = error_budget.channel_bound(VEINS)
    medium = mi.load_dict({"type": "marble_medium", "albedo": one_colour_marble(ALBEDO),
                           "density": texture_dict(VEINS), "density_bound": bound,
                           "scale": 8.0})
    ratio, sigma_n, points = tentative_collisions(medium)
    assert (sigma_n >= 0).all()
    expected = channel_color(VEINS, points).mean(axis=1) / bound
    # The marble's colour is within its error budget of the reference's (its tolerance).
    np.testing.assert_allclose(ratio, expected, atol=error_budget.DEFAULT_TOLERANCE / bound)
    assert 0.5 < ratio.mean() < 1.0


def test_scale_and_bound_are_traversed_and_a_bad_edit_is_refused(llvm):
    medium = mi.load_dict({"type": "marble_medium", "albedo": one_colour_marble(ALBEDO),
                           "density": texture_dict(VEINS)})
    assert isinstance(medium, MarbleMedium)
    params = mi.traverse(medium)
    assert {"scale", "albedo.ramp", "density.ramp"} <= set(params.keys())
    assert "density_bound" not in params.keys()          # not given: the texture's, in the kernel
    given = mi.traverse(mi.load_dict({"type": "marble_medium", "density_bound": 2.0}))
    fixed = int(mi.ParamFlags.NonDifferentiable)         # Differentiable is its absence
    assert not params.flags("scale") & fixed and given.flags("density_bound") & fixed
    point = [[0.1, 0.2, 0.3]]
    _, _, before = coefficients(medium, point)
    params["scale"] = 2.5
    params.update()
    _, _, after = coefficients(medium, point)
    np.testing.assert_allclose(after, 2.5 * before, rtol=1e-6)
    # The default bound is the density's max(), and follows an edit of its ramp.
    assert dr.allclose(medium.density_bound(), 1.0)
    params["density.ramp"] = dr.ravel(mi.TensorXf(np.array([[0.3] * 3, [2.0] * 3], np.float32)))
    params.update()
    assert dr.allclose(medium.density_bound(), 2.0)
    params["scale"] = -1.0
    with pytest.raises(MarbleMediumError, match=r"^marble_medium: scale=-1\.0 must be a finite "
                                                r"number > 0$"):
        params.update()
    assert dr.allclose(mi.traverse(medium)["scale"], 2.5)


@pytest.mark.parametrize("props, words", [
    ({"scale": 0.0}, "scale=0.0 must be a finite number > 0"),
    ({"scale": math.inf}, "scale=inf must be a finite number > 0"),
    ({"density_bound": -1.0}, "density_bound=-1.0 must be a finite number ≥ 0"),
    ({"scale": 1e30, "density_bound": 1e10},
     "the majorant scale·density_bound = 1e\\+40 is past float32's 3.4e\\+38"),
    ({"density": {"type": "checkerboard"}},
     "the density texture \\(Checkerboard\\) gives no max\\(\\); give density_bound"),
    ("sggx", "a microflake phase function is not supported; use isotropic"),
])
def test_invalid_media_are_refused_in_one_sentence(llvm, props, words):
    if props == "sggx":     # its S: a volume of 6 channels (S_xx, S_yy, S_zz, S_xy, S_xz, S_yz)
        grid = mi.VolumeGrid(np.tile(np.float32([1, 1, 1, 0, 0, 0]), (2, 2, 2, 1)))
        props = {"phase": {"type": "sggx", "S": {"type": "gridvolume", "grid": grid}}}
    with pytest.raises(Exception, match=f"marble_medium: {words}"):
        mi.load_dict({"type": "marble_medium", "albedo": 0.5, **props})


def test_scale_gradients_through_prbvolpath_match_finite_differences(llvm):
    """∂(mean image)/∂scale by ``prbvolpath`` (the majorant keeps scale's derivative:
    ``get_majorant``) against central differences of independent renders, for a marble
    density with null collisions. Measured: −0.0576 (AD) against −0.0577 ± 0.0003 (FD,
    4 pairs of 1024 spp); with the majorant detached, the AD of a constant density's
    scale said +0.113 against the FD's −0.047. Asserted: within 5 standard errors of the
    FD estimate plus 5 % (the O(h²) curvature of a central difference)."""
    medium = {"type": "marble_medium", "albedo": {"type": "rgb", "value": [0.8, 0.6, 0.4]},
              "density": texture_dict(VEINS), "scale": 2.0, "sample_emitters": False}
    scene_dict = sphere_scene(medium, size=16, spp=256)
    scene_dict["integrator"] = {"type": "prbvolpath", "max_depth": MAX_DEPTH,
                                "rr_depth": MAX_DEPTH}
    scene = mi.load_dict(scene_dict)
    params = mi.traverse(scene)
    key = "sphere.interior_medium.scale"
    dr.enable_grad(params[key])
    params.update()
    dr.backward(dr.mean(mi.render(scene, params, seed=1), axis=None))
    ad = float(dr.grad(params[key])[0])

    def mean_at(value, seed):
        params[key] = mi.Float(value)
        params.update()
        return float(np.mean(mi.render(scene, seed=seed, spp=1024)))
    h = 0.25
    fd = np.array([(mean_at(2.0 + h, s) - mean_at(2.0 - h, s + 100)) / (2 * h)
                   for s in range(4)])
    error = fd.std(ddof=1) / math.sqrt(len(fd))
    assert ad < 0 and abs(ad - fd.mean()) < 5 * error + 0.05 * abs(fd.mean()), (ad, fd)


# ---------------------------------------------------------------------------
# The bound follows its texture, whoever Mitsuba tells (issue 37, item 2)

#: The medium's density around the shared marble: itself, or an expression holding it
#: (whose maximum is made from its operands' as they are when the kernel runs).
DENSITIES = {"marble": lambda veins: veins,
             "expression": lambda veins: S.Add((veins, S.ColorChannel((0.1, 0.2, 0.3))))}


def shared_density_scene(ramp, density):
    """A translucent sphere whose density holds a marble that a second shape's diffuse
    BSDF shares (one object, a ``ref``): mi.traverse reaches it first through that shape,
    so an edit of it tells that shape's BSDF, not the medium. Path-traced with volpath."""
    medium = {"type": "marble_medium", "albedo": {"type": "rgb", "value": 0.8}, "scale": 4.0,
              "sample_emitters": False}
    channel = DENSITIES[density](VEINS)
    medium["density"] = {"type": "ref", "id": "veins"} if channel is VEINS else {
        "type": "channel_expression", "op": "add", "operand_0": {"type": "ref", "id": "veins"},
        "operand_1": {"type": "rgb", "value": [0.1, 0.2, 0.3]}}
    return {"veins": {**texture_dict(dataclasses.replace(VEINS, ramp=ramp)), "id": "veins"},
            "floor": {"type": "rectangle", "bsdf": {"type": "diffuse",
                                                     "reflectance": {"type": "ref", "id": "veins"}},
                      "to_world": mi.ScalarTransform4f().translate([0, 0, -3]).scale(4.0)},
            **sphere_scene(medium, size=16, spp=4)}


@pytest.mark.parametrize("density", list(DENSITIES))
def test_an_edit_of_a_shared_density_moves_the_bound_of_a_medium_it_was_not_told_of(
        llvm, monkeypatch, density):
    from mimarble.mitsuba.rendering.render import render_in_passes
    low = ((0.3, 0.3, 0.3), (0.9, 0.9, 0.9))
    high = ((0.3, 0.3, 0.3), (2.7, 2.7, 2.7))
    scene = mi.load_dict(shared_density_scene(low, density))
    for _ in range(3):                                    # recorded, then replayed
        render_in_passes(scene, 4, "path")
    params = mi.traverse(scene)
    texture_key = next(k for k in params.keys() if k.endswith(".ramp"))
    assert not texture_key.startswith("sphere.")          # the medium is not its first parent
    medium = scene.shapes()[[s.id() for s in scene.shapes()].index("sphere")].interior_medium()
    params[texture_key] = mi.Color3f(*zip(*high))
    params.update()
    # σ_t at points inside: scale · the reference's mean density of the edited channel,
    # none clamped at the old bound, and σ_n ≥ 0 (the majorant bounds it).
    points = in_ball(64, 1.0, seed=4)
    d = channel_color(DENSITIES[density](dataclasses.replace(VEINS, ramp=high)),
                      points).mean(axis=1)
    assert d.max() > 1.2
    sigma_s, sigma_n, sigma_t = coefficients(medium, points)
    np.testing.assert_allclose(sigma_t[:, 0], 4.0 * d, atol=4.0 * error_budget.DEFAULT_TOLERANCE)
    assert (sigma_n >= 0).all()
    # The image: as the same scene loaded with that ramp; replayed, as traced afresh.
    np.testing.assert_array_equal(rendered_scene(scene), rendered_scene(
        mi.load_dict(shared_density_scene(high, density))))
    replayed = render_in_passes(scene, 4, "path")
    monkeypatch.setenv("MIMARBLE_FREEZE", "0")
    np.testing.assert_array_equal(replayed, render_in_passes(scene, 4, "path"))


def rendered_scene(scene, seed=3):
    return np.array(mi.render(scene, seed=seed))


def test_a_mitsuba_density_texture_edited_elsewhere_records_its_new_maximum(llvm, monkeypatch):
    # Mitsuba's srgb as a density shared with a surface: its max() is read before each pass
    # (outside the recording, where reading is allowed) and is part of the key, so the
    # replay after the edit is a fresh trace's image and a fresh load's, not the old bound's.
    from mimarble.mitsuba.rendering.render import render_in_passes
    scene_dict = shared_density_scene(((0.3, 0.3, 0.3), (0.9, 0.9, 0.9)), "marble")
    scene_dict["veins"] = {"type": "srgb", "color": [0.3, 0.3, 0.3], "id": "veins"}
    scene = mi.load_dict(scene_dict)
    for _ in range(2):
        render_in_passes(scene, 4, "path")
    params = mi.traverse(scene)
    (key,) = [k for k in params.keys() if k.endswith("veins.value")]
    params[key] = mi.Color3f(0.8, 0.8, 0.8)
    params.update()
    replayed = render_in_passes(scene, 4, "path")
    monkeypatch.setenv("MIMARBLE_FREEZE", "0")
    np.testing.assert_array_equal(replayed, render_in_passes(scene, 4, "path"))
    scene_dict["veins"]["color"] = [0.8, 0.8, 0.8]
    np.testing.assert_array_equal(replayed, render_in_passes(mi.load_dict(scene_dict), 4, "path"))
