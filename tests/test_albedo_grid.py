"""A translucent material's albedo read from a grid (mimarble/scene/albedo_grid.py, issue 40):
the rule's layouts worked by hand and what it leaves alone, that the translation and the
float64 reference walk both apply it, that Mitsuba's lookup (``marble_medium``'s grid, float32,
Dr.Jit) gives what the reference's (float64, NumPy, its own marble and inversion) gives at the
same points, that an edit and a gradient reach the grid, and the limit checked before
anything is allocated. The walks' agreement where the grid applies is the z-test of
tests/test_subsurface_band_limit.py (its scene has a grid: asserted below)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import mimarble
from mimarble.contract import MAX_GRID_NODES
from mimarble.reference import volume_scene
from mimarble.scene import model
from mimarble.scene import albedo_grid as albedo_grid_module
from mimarble.scene.albedo_grid import AlbedoGrid, albedo_grid

from test_translucent_reference import SIDE_LIGHT, llvm_variant  # noqa: F401

dr, mi = mimarble.dr, mimarble.mi

VEINS = model.MarbleChannel(function="sine", axis="x", period=3.0, distortion=2.0, octaves=3,
                            ramp=((0.93, 0.92, 0.9), (0.55, 0.35, 0.2), (0.2, 0.5, 0.3)))


def subsurface(**kw):
    base = dict(reflectance=VEINS, mean_free_path=0.2, ior=1.5)
    base.update(kw)
    return model.Subsurface(**base)


def scene_of(sub, spheres=((0.0, 0.0, 0.0, 1.0),), planes=(), size=16):
    return model.Scene(
        image=model.Image(width=size, height=size),
        camera=model.Camera(eye=(0.0, 0.4, 5.0), lookat=(0.0, 0.0, 0.0), fov=30.0),
        ambient=(0.6, 0.65, 0.7), lights=(SIDE_LIGHT,),
        materials={"m": model.Material("m", subsurface=sub)},
        spheres=tuple(model.Sphere("m", (x, y, z), r) for x, y, z, r in spheres),
        planes=planes)


# ---------------------------------------------------------------------------
# The rule, by hand

def test_the_layout_by_hand():
    """h = ℓ/2. A sphere of radius 2 at the origin, ℓ = 1/16: 4/(1/32) = 128 cells, 129
    nodes a side from −2. Two spheres (centres 0 and 3 on x, radii 1 and 0.5), ℓ = 1/4:
    the box [−1, 3.5] × [−1, 1]², 4.5/(1/8) = 36 cells (37 nodes), 2/(1/8) = 16 (17)."""
    assert albedo_grid_module.GRID_SPACING_PER_MEAN_FREE_PATH == 0.5
    one = albedo_grid(subsurface(mean_free_path=1 / 16), [model.Sphere("m", (0, 0, 0), 2.0)])
    assert one == AlbedoGrid((-2.0, -2.0, -2.0), 1 / 32, (129, 129, 129))
    two = albedo_grid(subsurface(mean_free_path=0.25), [model.Sphere("m", (0, 0, 0), 1.0),
                                                        model.Sphere("m", (3, 0, 0), 0.5)])
    assert two == AlbedoGrid((-1.0, -1.0, -1.0), 0.125, (37, 17, 17))
    # A box that is not a whole number of cells: 2.1/0.125 = 16.8 → 17 cells, 18 nodes
    # reaching 0.025 past the far face.
    odd = albedo_grid(subsurface(mean_free_path=0.25), [model.Sphere("m", (0, 0, 0), 1.05)])
    assert odd.counts == (18, 18, 18)


@pytest.mark.parametrize("sub, shapes", [
    (subsurface(reflectance=model.ColorChannel((0.8, 0.7, 0.6))), None),     # no marble
    (subsurface(density=model.ColorChannel((1.0, 1.0, 1.0))), None),          # a density
    (subsurface(), [model.Sphere("m", (0, 0, 0), 1.0), model.Plane("m")]),    # unbounded
    (subsurface(), []),                                                       # no shape
    (subsurface(mean_free_path=1e-2), None),       # 401³ nodes: past MAX_GRID_NODES
    (subsurface(mean_free_path=1e-30), None),      # cells past any count: none computed
], ids=["constant", "density", "plane", "no shape", "past the limit", "tiny mean free path"])
def test_what_the_rule_leaves_to_direct_evaluation(sub, shapes):
    shapes = [model.Sphere("m", (0, 0, 0), 1.0)] if shapes is None else shapes
    assert albedo_grid(sub, shapes) is None


def test_the_largest_grid_allowed_is_made():
    """203³ ≤ MAX_GRID_NODES = 2²³ < 204³: a unit sphere at 202 cells a side is made, at
    203 it is not."""
    assert 203 ** 3 <= MAX_GRID_NODES < 204 ** 3
    h = albedo_grid_module.GRID_SPACING_PER_MEAN_FREE_PATH
    at = albedo_grid(subsurface(mean_free_path=2.0 / 202 / h), [model.Sphere("m", (0, 0, 0), 1.0)])
    assert at is not None and at.counts == (203, 203, 203)
    past = albedo_grid(subsurface(mean_free_path=2.0 / 203 / h),
                       [model.Sphere("m", (0, 0, 0), 1.0)])
    assert past is None


# ---------------------------------------------------------------------------
# Both walks apply it

def grid_props(translated: dict) -> list:
    return [{k: v for k, v in shape["interior"].items() if k.startswith("grid_")}
            for shape in translated.values() if isinstance(shape, dict) and "interior" in shape]


def test_the_translation_and_the_reference_both_use_the_grid():
    from mimarble.mitsuba.translate import scene_dict
    scene = scene_of(subsurface(mean_free_path=0.25), spheres=((0, 0, 0, 1.0), (3, 0, 0, 0.5)))
    expected = albedo_grid(scene.materials["m"].subsurface, scene.spheres)
    assert expected.counts == (37, 17, 17)      # the box around both spheres (one medium)
    props = grid_props(scene_dict.to_mitsuba(scene, "path", 4))
    assert props and all(p == {"grid_origin": list(expected.origin),
                               "grid_spacing": expected.spacing,
                               "grid_counts": list(expected.counts)} for p in props)
    assert volume_scene.WalkSpheres(scene).grids == [expected, expected]
    # Object-space marbles: a medium (and a grid) per placement.
    placed = scene_of(subsurface(reflectance=dataclasses.replace(VEINS, space="object")),
                      spheres=((0, 0, 0, 1.0), (3, 0, 0, 0.5)))
    grids = volume_scene.WalkSpheres(placed).grids
    assert [g.origin for g in grids] == [(-1.0, -1.0, -1.0), (2.5, -0.5, -0.5)]
    assert sorted(p["grid_origin"] for p in grid_props(scene_dict.to_mitsuba(placed, "path", 4))) \
        == [[-1.0, -1.0, -1.0], [2.5, -0.5, -0.5]]


def test_the_band_limit_tests_scene_has_a_grid():
    """tests/test_subsurface_band_limit.py's z-test of the two walks runs with the grid."""
    from test_subsurface_band_limit import marble, scene_of as band_limit_scene
    sub = model.Subsurface(reflectance=marble(distortion=4.0), mean_free_path=0.25, ior=1.5)
    assert volume_scene.WalkSpheres(band_limit_scene(sub)).grids[0] is not None


# ---------------------------------------------------------------------------
# Mitsuba's grid against the reference's

def loaded_medium(scene):
    from mimarble.mitsuba.translate import scene_dict
    translated = scene_dict.to_mitsuba(scene, "path", 4)
    loaded = mi.load_dict(translated)
    return next(s.interior_medium() for s in loaded.shapes() if s.interior_medium() is not None)


def albedo_at(medium, points):
    """σ_s/σ_t (n, 3) = α of the medium at world points (n, 3)."""
    mei = dr.zeros(mi.MediumInteraction3f, len(points))
    mei.p = mi.Point3f(*(mi.Float(np.asarray(points[:, k], np.float32)) for k in range(3)))
    sigma_s, _, sigma_t = medium.get_scattering_coefficients(mei, True)
    return (np.array(sigma_s, np.float64) / np.array(sigma_t, np.float64)).T


def in_ball(n, radius, seed):
    rng = np.random.default_rng(seed)
    p = rng.uniform(-radius, radius, (3 * n, 3))
    return p[np.linalg.norm(p, axis=1) < radius][:n]


def within_rounding(actual, expected):
    """|actual − expected| ≤ 2⁻¹¹·(1 − expected) + 2·10⁻⁵: the half precision of the grid's
    1 − α (a relative 2⁻¹¹) and float32's rounding of the marble and the inversion."""
    slack = 2.0 ** -11 * (1.0 - expected) + 2e-5
    assert np.all(np.abs(actual - expected) <= slack), np.abs(actual - expected).max()


def test_mitsubas_lookup_draws_a_corner_with_its_trilinear_weight(llvm_variant):
    """Mitsuba's lookup (its marble and inversion in float32, its grid in half precision, one
    corner drawn per point by a hash of the point) against the reference walk's (float64,
    its own marble and inversion, the trilinear interpolation itself — the draw's
    expectation): at each of 20000 points in the ball the value read is one of the eight
    corners' (:func:`within_rounding` of the reference's nodes); over the points, each
    corner is drawn as often as its trilinear weight says, and the mean of what is read
    is the mean of the interpolation, within 4 standard errors (the draws' spread)."""
    scene = scene_of(subsurface())
    medium = loaded_medium(scene)
    assert medium.grid is not None
    points = in_ball(20000, 1.0, 1)
    walk = volume_scene.WalkSpheres(scene)
    trilinear = walk.coefficients(0, points)[1]
    read = albedo_at(medium, points)
    grid = walk.grids[0]
    counts = np.asarray(grid.counts)
    u = np.clip((points - np.asarray(grid.origin)) / grid.spacing, 0.0, counts - 1.0)
    cell = np.minimum(np.floor(u).astype(np.int64), counts - 2)
    f = u - cell
    nodes = walk._grid_albedo[0]
    weights, values = [], []
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                weights.append(np.prod([f[:, a] if d else 1.0 - f[:, a]
                                        for a, d in enumerate((dx, dy, dz))], axis=0))
                values.append(nodes[(cell[:, 0] + dx) + counts[0] * ((cell[:, 1] + dy)
                                                                      + counts[1] * (cell[:, 2] + dz))])
    weights, values = np.stack(weights, axis=1), np.stack(values, axis=1)   # (n, 8), (n, 8, 3)
    slack = 2.0 ** -11 * (1.0 - values) + 2e-5
    hit = np.all(np.abs(read[:, None, :] - values) <= slack, axis=2)         # (n, 8)
    assert hit.any(axis=1).all()
    # The corner drawn (the first that matches; corners of equal value are one outcome
    # for the mean below) against its weight: Σ (1{drawn} − w) ≈ 0 per corner slot.
    drawn = np.zeros_like(weights)
    drawn[np.arange(len(points)), hit.argmax(axis=1)] = 1.0
    distinct = np.all(np.abs(values[:, :, None, :] - values[:, None, :, :]).max(axis=3)
                      + np.eye(8)[None] > 1e-3, axis=(1, 2))
    excess = (drawn - weights)[distinct]
    se = np.sqrt((weights * (1 - weights))[distinct].sum(axis=0))
    assert np.all(np.abs(excess.sum(axis=0)) < 4 * se + 1e-9), (excess.sum(axis=0), se)
    difference = read - trilinear
    z = difference.mean(axis=0) / (difference.std(axis=0) / np.sqrt(len(points)))
    assert np.all(np.abs(z) < 4), z
    walk.grids[0] = None                                   # the reference, evaluated directly
    direct = walk.coefficients(0, points)[1]
    assert np.abs(direct - trilinear).max() > 1e-3


def test_at_the_nodes_the_grid_is_the_colour(llvm_variant):
    """At the grid's nodes the lookup gives the colour evaluated there (the node placement),
    within :func:`within_rounding` (and float32's rounding of u = (p − origin)/h)."""
    scene = scene_of(subsurface())
    medium = loaded_medium(scene)
    grid = albedo_grid(scene.materials["m"].subsurface, scene.spheres)
    rng = np.random.default_rng(2)
    ijk = np.stack([rng.integers(0, n, 500) for n in grid.counts], axis=1)
    nodes = np.asarray(grid.origin) + grid.spacing * ijk
    walk = volume_scene.WalkSpheres(scene)
    walk.grids[0] = None
    within_rounding(albedo_at(medium, nodes), walk.coefficients(0, nodes)[1])


# ---------------------------------------------------------------------------
# Edits and gradients

def test_an_edit_of_the_colour_bakes_the_grid_again(llvm_variant):
    """An edit of the reflectance's ramp through ``mi.traverse``, which tells the scene (the
    texture's first parent) and not the medium: the medium refuses to be traced with the
    old grid, in one sentence; refreshed (as the pass renderer does before each render) it
    gives the α a medium loaded with that ramp gives."""
    other = ((0.3, 0.4, 0.5), (0.9, 0.8, 0.7), (0.6, 0.6, 0.6))
    from mimarble.mitsuba.translate import scene_dict
    scene = scene_of(subsurface(), spheres=((0, 0, 0, 1.0), (3, 0, 0, 0.5)))
    loaded = mi.load_dict(scene_dict.to_mitsuba(scene, "path", 4))
    media = [s.interior_medium() for s in loaded.shapes() if s.interior_medium() is not None]
    params = mi.traverse(loaded)
    key = next(k for k in params.keys() if k.endswith(".ramp"))
    params[key] = mi.Color3f(*zip(*other))
    params.update()
    edited = scene_of(subsurface(reflectance=dataclasses.replace(VEINS, ramp=other)))
    points = in_ball(300, 0.5, 3)
    expected = albedo_at(loaded_medium(edited), points)
    assert key == "texture_0.ramp"      # told: the scene, the texture's first parent
    with pytest.raises(Exception, match="marble_medium: its colour texture was edited after "
                                        "the albedo grid was made"):
        albedo_at(media[0], points)
    for medium in media:
        medium.refresh_grid()           # what the pass renderer does before each render
        np.testing.assert_allclose(albedo_at(medium, points), expected, atol=1e-6)


def test_every_refresh_after_edits_bakes_the_grid_again(llvm_variant):
    """Dr.Jit hands a freed variable's index to a later variable, and the grid tells an edit
    by its colour's variable indices: one to four edits of the period between refreshes,
    many times, so that a later value can be made after an edit freed the baked one. Each
    refresh after an edit bakes the grid again, and the last grid is the edited colour's."""
    from mimarble.mitsuba.translate import scene_dict
    scene = scene_of(subsurface())
    loaded = mi.load_dict(scene_dict.to_mitsuba(scene, "path", 4))
    medium = next(s.interior_medium() for s in loaded.shapes()
                  if s.interior_medium() is not None)
    params = mi.traverse(loaded)
    key = next(k for k in params.keys() if k.endswith(".period"))
    period = VEINS.period
    for round_ in range(24):
        for _ in range(1 + round_ % 4):
            period = VEINS.period * (1.0 + 0.01 * (round_ + 1)) + 0.001 * _
            params[key] = period
            params.update()
        before = medium.grid
        medium.refresh_grid()           # as before each render
        assert medium.grid is not before, f"round {round_}: the grid was not baked again"
    edited = scene_of(subsurface(reflectance=dataclasses.replace(VEINS, period=period)))
    points = in_ball(200, 0.5, 5)
    np.testing.assert_allclose(albedo_at(medium, points),
                               albedo_at(loaded_medium(edited), points), atol=1e-6)


def test_a_gradient_reaches_the_colour_through_the_grid(llvm_variant):
    """∂(Σ α at the nodes)/∂ramp through the grid equals it without the grid (at a node
    the lookup is the node's value, whose derivative is the texture's)."""
    from mimarble.mitsuba.translate import scene_dict
    scene = scene_of(subsurface())
    grid = albedo_grid(scene.materials["m"].subsurface, scene.spheres)
    nodes = np.asarray(grid.origin) + grid.spacing * np.array([[3, 4, 5], [6, 2, 7], [5, 5, 5]])
    grads = []
    for with_grid in (True, False):
        translated = scene_dict.to_mitsuba(scene, "path", 4)
        for shape in translated.values():
            if isinstance(shape, dict) and "interior" in shape and not with_grid:
                for k in ("grid_origin", "grid_spacing", "grid_counts"):
                    shape["interior"].pop(k)
        loaded = mi.load_dict(translated)
        medium = next(s.interior_medium() for s in loaded.shapes() if s.interior_medium())
        params = mi.traverse(loaded)
        key = next(k for k in params.keys() if k.endswith(".ramp"))
        dr.enable_grad(params[key])
        params.update()
        medium.refresh_grid()
        assert (medium.grid is not None) == with_grid
        mei = dr.zeros(mi.MediumInteraction3f, len(nodes))
        mei.p = mi.Point3f(*(mi.Float(nodes[:, k].astype(np.float32)) for k in range(3)))
        sigma_s, _, sigma_t = medium.get_scattering_coefficients(mei, True)
        dr.backward(dr.sum(sigma_s / sigma_t, axis=None))
        grads.append(np.array(dr.grad(params[key])))
    assert np.abs(grads[1]).max() > 0.1
    np.testing.assert_allclose(grads[0], grads[1], atol=1e-4)


def test_a_renders_gradient_through_the_grid_matches_finite_differences(llvm_variant):
    """∂(mean image)/∂(one ramp component) of a gridded reflectance medium, by ``prbvolpath``
    through ``mi.render(scene, params)`` (whose primal pass runs under ``dr.suspend_grad``:
    the grid baked with the gradient must still count as current there), against central
    differences of renders with the grid baked again at ±h. The differences use common
    random numbers (one seed both sides): with roulette off the albedo enters only the
    weights and the corner drawn hashes the point, not the parameters, so both renders
    take the same paths and the difference is the derivative of one estimate — unbiased
    up to the O(h²) of the difference. Measured: AD 0.13674 ± 0.00010, FD 0.13688 ±
    0.00007 (h 0.01). Asserted: within 5 standard errors of both plus 1 %."""
    from test_marble_medium import MAX_DEPTH, sphere_scene
    from mimarble.mitsuba.translate.scene_dict import texture_dict
    veins = dataclasses.replace(VEINS, ramp=((0.3, 0.5, 0.4), (0.7, 0.6, 0.5)))
    layout = albedo_grid(subsurface(reflectance=veins, mean_free_path=0.25),
                         [model.Sphere("m", (0, 0, 0), 1.0)])
    medium = {"type": "marble_medium", "reflectance": texture_dict(veins), "ior": 1.5,
              "scale": 4.0, "sample_emitters": False, "grid_origin": list(layout.origin),
              "grid_spacing": layout.spacing, "grid_counts": list(layout.counts)}
    described = sphere_scene(medium, size=16, spp=1024)
    described["integrator"] = {"type": "prbvolpath", "max_depth": MAX_DEPTH,
                               "rr_depth": MAX_DEPTH}
    scene = mi.load_dict(described)
    medium = next(s.interior_medium() for s in scene.shapes() if s.interior_medium())
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith(".ramp"))
    base, component = np.array(params[key]), (1, 1)    # the second colour's green

    def set_ramp(delta=0.0):
        ramp = base.copy()
        ramp[component] += delta
        params[key] = type(params[key])(ramp)
        params.update()
        medium.refresh_grid()           # a bare mi.render: the medium was not told

    ad = []
    for seed in range(4):
        set_ramp()
        dr.enable_grad(params[key])
        params.update()
        medium.refresh_grid()
        assert medium.grid is not None
        dr.backward(dr.mean(mi.render(scene, params, seed=10 + seed), axis=None))
        ad.append(np.array(dr.grad(params[key]))[component])
        dr.disable_grad(params[key])

    def mean_at(delta, seed):
        set_ramp(delta)
        return float(np.mean(mi.render(scene, seed=seed)))
    h = 0.01
    fd = np.array([(mean_at(h, seed) - mean_at(-h, seed)) / (2 * h) for seed in range(4)])
    ad = np.array(ad)
    error = np.hypot(ad.std(ddof=1), fd.std(ddof=1)) / 2
    assert fd.mean() > 0.05, fd
    assert abs(ad.mean() - fd.mean()) < 5 * error + 0.01 * fd.mean(), (ad, fd)


# ---------------------------------------------------------------------------
# Bad grids

@pytest.mark.parametrize("props, words", [
    ({"grid_origin": [0, 0, 0]}, "grid_origin, grid_spacing and grid_counts go together"),
    ({"grid_origin": [0, 0, 0], "grid_spacing": 0.1, "grid_counts": [300, 300, 300]},
     "an albedo grid of 27000000 nodes is past the limit of 8388608"),
    ({"grid_origin": [0, 0, 0], "grid_spacing": 0.0, "grid_counts": [2, 2, 2]},
     "grid_spacing=0.0 must be a finite number > 0"),
    ({"grid_origin": [0, 0, 0], "grid_spacing": 0.1, "grid_counts": [1, 2, 2]},
     "grid_counts=.* must be three whole numbers ≥ 2"),
    ({"grid_origin": 0.5, "grid_spacing": 0.1, "grid_counts": [2, 2, 2]},
     "grid_origin=0.5 must be three finite numbers"),
    ({"grid_origin": [0, 0, 0], "grid_spacing": 0.1, "grid_counts": "abc"},
     "grid_counts='abc' must be three whole numbers ≥ 2"),
])
def test_bad_grids_are_refused_in_one_sentence(llvm_variant, props, words):
    with pytest.raises(Exception, match=f"marble_medium: {words}"):
        mi.load_dict({"type": "marble_medium", "reflectance": 0.5, **props})


# ---------------------------------------------------------------------------
# The off switch

def test_grid_false_in_the_scene_language_renders_the_exact_walk():
    """``subsurface { … grid false }``: no grid in either walk; anything but true or false
    refused at the word, in one sentence with its line and column."""
    from mimarble import scene as S
    from mimarble.mitsuba.translate import scene_dict
    text = '''material "m" { subsurface { reflectance marble { function sine period 3 }
        mean_free_path 0.2 grid WORD } }
    sphere { center < 0 0 0 > radius 1 material "m" }'''
    on, off = (S.parse(text.replace("WORD", w)) for w in ("true", "false"))
    assert on.materials["m"].subsurface.grid and not off.materials["m"].subsurface.grid
    assert grid_props(scene_dict.to_mitsuba(on, "path", 4))[0]
    assert grid_props(scene_dict.to_mitsuba(off, "path", 4)) == [{}]
    assert volume_scene.WalkSpheres(off).grids == [None]
    with pytest.raises(S.SceneError, match=r"^<string>:2:33: grid is true or false, found 'maybe'"):
        S.parse(text.replace("WORD", "maybe"))
    with pytest.raises(S.SceneError, match=r"^<string>:2:33: grid is true or false, found number 1"):
        S.parse(text.replace("WORD", "1"))    # not a word: the parser's sentence, the same
