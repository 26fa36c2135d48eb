"""The whitted integrator and the translator against hand-computed pixels of tiny scenes."""

import math

import numpy as np
import pytest
from traced import operations_traced  # noqa: E402

import mimarble
from mimarble import scene as sl
from mimarble.mitsuba import to_mitsuba
from mimarble.reference.marble import marble_color

dr, mi = mimarble.dr, mimarble.mi

KA, KD, KS = (0.1, 0.2, 0.3), (0.4, 0.5, 0.6), (0.2, 0.2, 0.2)
AMBIENT, LIGHT = (0.5, 0.5, 0.5), (1.0, 0.5, 0.25)


def tiny_scene(size=5, samples=1, lights=((0, 0, 5),), specular=True, extra="", fov=30,
               background=(0.05, 0.06, 0.07)):
    spec = f"specular {{ color < {KS[0]} {KS[1]} {KS[2]} > }} shininess 8" if specular else ""
    light_text = "\n".join(f"light {{ position < {p[0]} {p[1]} {p[2]} > "
                           f"color < {LIGHT[0]} {LIGHT[1]} {LIGHT[2]} > }}" for p in lights)
    text = f"""
        image {{ width {size} height {size} samples {samples}
                background < {background[0]} {background[1]} {background[2]} > }}
        camera {{ eye < 0 0 5 > lookat < 0 0 0 > up < 0 1 0 > fov {fov} }}
        ambient < {AMBIENT[0]} {AMBIENT[1]} {AMBIENT[2]} >
        {light_text}
        material "m" {{ ambient {{ color < {KA[0]} {KA[1]} {KA[2]} > }}
                        diffuse {{ color < {KD[0]} {KD[1]} {KD[2]} > }} {spec} }}
        sphere {{ center < 0 0 0 > radius 1 material "m" }}
        {extra}"""
    return sl.parse(text)


def ray_direction(x, y, size, fov=30):
    """The contract's camera: eye (0,0,5) looking at −z, film (x, y) ∈ [0,1]², y down."""
    t = math.tan(math.radians(fov) / 2)
    d = np.array([(2 * x - 1) * t, (1 - 2 * y) * t, -1.0])
    return d / np.linalg.norm(d)


def hit_unit_sphere(o, d):
    b = np.dot(o, d)
    disc = b * b - (np.dot(o, o) - 1)
    return None if disc < 0 else o + (-b - math.sqrt(disc)) * d


def shade(p, d, lights, specular=True, occluded=lambda p, l: False):
    n, v = p / np.linalg.norm(p), -d
    colour = np.multiply(KA, AMBIENT)
    for light in lights:
        l = np.asarray(light, float) - p
        l /= np.linalg.norm(l)
        if np.dot(n, l) <= 0 or occluded(p, light):
            continue
        term = np.multiply(KD, np.dot(n, l))
        if specular:
            h = (l + v) / np.linalg.norm(l + v)
            term += np.multiply(KS, max(np.dot(n, h), 0.0) ** 8)
        colour += np.multiply(LIGHT, term)
    return colour


def pixel(scene, i, j, n=1, **kw):
    """Mean over the n×n stratum centres of pixel (column i, row j), by hand."""
    size, total = scene.image.width, np.zeros(3)
    for a in range(n):
        for b in range(n):
            d = ray_direction((i + (a + 0.5) / n) / size, (j + (b + 0.5) / n) / size, size,
                              scene.camera.fov)
            p = hit_unit_sphere(np.array([0, 0, 5.0]), d)
            total += scene.image.background if p is None else \
                shade(p, d, [lt.position for lt in scene.lights], **kw)
    return total / (n * n)


TOL = 2e-6   # float32 geometry and shading of values ≤ 2


def test_centre_pixel_is_ambient_plus_diffuse_plus_specular(variant):
    image = mimarble.render(tiny_scene())
    expected = np.multiply(KA, AMBIENT) + np.multiply(LIGHT, np.add(KD, KS))   # n·l = n·h = 1
    np.testing.assert_allclose(image[2, 2], expected, atol=TOL)


def test_missing_pixel_is_background(variant):
    image = mimarble.render(tiny_scene())
    np.testing.assert_allclose(image[0, 0], [0.05, 0.06, 0.07], atol=1e-7)


@pytest.mark.parametrize("i, j", [(2, 1), (1, 2), (3, 3), (1, 1)])
def test_off_centre_pixels_match_hand_geometry(jit_variant, i, j):
    scene = tiny_scene(lights=((3, 4, 5),))
    image = mimarble.render(scene)
    np.testing.assert_allclose(image[j, i], pixel(scene, i, j), atol=TOL)


def test_four_samples_average_the_four_stratum_centres(jit_variant):
    scene = tiny_scene(size=3, samples=4, lights=((2, 3, 4),), fov=40)
    image = mimarble.render(scene)
    for i, j in [(0, 1), (1, 1), (2, 0)]:
        np.testing.assert_allclose(image[j, i], pixel(scene, i, j, n=2), atol=TOL)


def test_two_lights_add(jit_variant):
    a, b = (3, 4, 5), (-4, 1, 3)
    both = mimarble.render(tiny_scene(lights=(a, b), size=9))
    one = mimarble.render(tiny_scene(lights=(a,), size=9))
    other = mimarble.render(tiny_scene(lights=(b,), size=9))
    ambient_only = mimarble.render(tiny_scene(lights=(), size=9))
    np.testing.assert_allclose(both, one + other - ambient_only, atol=4 * TOL)


def test_material_without_specular_has_no_highlight(jit_variant):
    scene = tiny_scene(specular=False)
    image = mimarble.render(scene)
    expected = np.multiply(KA, AMBIENT) + np.multiply(LIGHT, KD)
    np.testing.assert_allclose(image[2, 2], expected, atol=TOL)


def segment_hits_sphere(a, b, centre, radius):
    d = b - a
    t = np.clip(np.dot(centre - a, d) / np.dot(d, d), 0, 1)
    return np.linalg.norm(a + t * d - centre) < radius


def test_shadow_ray_blocks_the_light(jit_variant):
    # Light straight above; a small sphere between it and the top of the big one.
    blocker = 'material "b" { diffuse { color < 0 0 0 > } } sphere { center < 0 2.5 0 > radius 0.5 material "b" }'
    lit = tiny_scene(size=21, lights=((0, 5, 0),), specular=False)
    shadowed = tiny_scene(size=21, lights=((0, 5, 0),), specular=False, extra=blocker)
    light, centre = np.array([0, 5.0, 0]), np.array([0, 2.5, 0])
    lit_image, shadowed_image = mimarble.render(lit), mimarble.render(shadowed)
    checked = 0
    for j in range(21):
        i = 10
        d = ray_direction((i + 0.5) / 21, (j + 0.5) / 21, 21)
        p = hit_unit_sphere(np.array([0, 0, 5.0]), d)
        if p is None or p[1] < 0.3 or segment_hits_sphere(np.array([0, 0, 5.0]), p, centre, 0.5):
            continue                               # a miss, unlit, or the blocker is in view
        blocked = segment_hits_sphere(p, light, centre, 0.5)
        expected = pixel(shadowed, i, j, specular=False,
                         occluded=lambda q, l: segment_hits_sphere(q, np.asarray(l, float), centre, 0.5))
        np.testing.assert_allclose(shadowed_image[j, i], expected, atol=TOL)
        np.testing.assert_allclose(lit_image[j, i], pixel(lit, i, j, specular=False), atol=TOL)
        checked += blocked
    assert checked >= 2                            # some pixels really were in shadow


def test_marble_channel_is_the_texture_at_the_hit_point(jit_variant):
    text = """image { width 16 height 16 } camera { eye < 0 0 5 > lookat < 0 0 0 > up < 0 1 0 > fov 30 }
              ambient < 1 1 1 >
              material "m" { ambient { marble { scale 2 octaves 5 ramp { <0 0 0> <1 1 1> } } } }
              sphere { center < 0 0 0 > radius 1 material "m" }"""
    scene = sl.parse(text)
    image = mimarble.render(scene)
    channel = scene.materials["m"].ambient
    for i, j in [(8, 8), (5, 9), (10, 4)]:
        d = ray_direction((i + 0.5) / 16, (j + 0.5) / 16, 16)
        p = hit_unit_sphere(np.array([0, 0, 5.0]), d)
        expected = marble_color(p[None, :], channel)[0]   # the reference's own float64 marble
        np.testing.assert_allclose(image[j, i], expected, atol=2e-4)


def test_translator_shares_equal_marbles_and_inlines_colours():
    scene = sl.load("scenes/fig11a.scene")
    d = to_mitsuba(scene)
    textures = [k for k in d if k.startswith("texture_")]
    assert len(textures) == 1 and d[textures[0]]["type"] == "marble"
    bsdf = d["sphere_0"]["bsdf"]
    assert bsdf["ambient"] == bsdf["diffuse"] == {"type": "ref", "id": textures[0]}
    assert bsdf["specular"]["type"] == "srgb" and bsdf["specular"]["unbounded"]   # HDR colours
    assert d["integrator"]["type"] == "whitted"
    assert d["sensor"]["sampler"] == {"type": "stratified", "sample_count": 4, "jitter": False}


def test_translator_path_mode_uses_standard_bsdfs_and_converts_light_power():
    scene = sl.load("scenes/fig11a.scene")
    d = to_mitsuba(scene, mode="path", spp=16)
    assert d["sphere_0"]["bsdf"]["type"] == "roughplastic"
    assert d["sphere_0"]["bsdf"]["int_ior"] == 1.6          # calcite: a deliberate choice
    light = scene.lights[0]
    d2 = math.dist(light.position, scene.camera.lookat) ** 2
    assert d["light_0"]["intensity"]["value"][0] == pytest.approx(light.color[0] * math.pi * d2)
    assert d["integrator"]["type"] == "path"


def test_translator_rejects_bad_modes_and_sample_counts():
    scene = tiny_scene()
    with pytest.raises(ValueError, match="mode"):
        to_mitsuba(scene, mode="raster")
    with pytest.raises(ValueError, match="perfect square"):
        to_mitsuba(scene, spp=2)


def _with_bsdf(bsdf):
    d = to_mitsuba(tiny_scene())
    d["sphere_0"]["bsdf"] = bsdf
    return mi.load_dict(d)


def test_whitted_under_mi_render_names_the_shape_and_class_of_a_wrong_bsdf(llvm):
    with pytest.raises(Exception) as err:
        mi.render(_with_bsdf({"type": "diffuse"}))
    messages, e = [], err.value
    while e is not None:
        messages.append(str(e))
        e = e.__cause__ or e.__context__
    assert any("shape 'sphere_0' has BSDF 'diffuse' (SmoothDiffuse)" in m and "channel_material" in m
               for m in messages), messages


@pytest.mark.parametrize("variant_name", ["scalar_rgb", "llvm_ad_rgb"])
def test_mimarble_render_refuses_a_wrong_bsdf_before_tracing(variant_name, monkeypatch):
    import importlib
    rendering = importlib.import_module("mimarble.mitsuba.rendering.render")
    previous = mi.variant()
    mi.set_variant(variant_name)
    try:
        scene = _with_bsdf({"type": "roughconductor"})
        def traced(*args, **kwargs):
            pytest.fail("rendered a scene it should refuse")
        monkeypatch.setattr(rendering, "render_in_passes", traced)
        monkeypatch.setattr(mi, "render", traced)
        with pytest.raises(ValueError, match=r"^whitted: shape 'sphere_0' has BSDF "
                                             r"'roughconductor' \(RoughConductor\); "
                                             r".*'channel_material'") as err:
            mimarble.render(scene)
        assert err.value.__cause__ is None
    finally:
        mi.set_variant(previous)


def test_mimarble_render_refuses_an_area_light_naming_its_class(llvm):
    """A light that is not point-like is refused (an environment, ``constant`` or
    ``envmap``, is the background: tests/test_environment_light.py)."""
    d = to_mitsuba(tiny_scene())
    d["sun"] = {"type": "directional", "direction": [0, 0, -1]}
    with pytest.raises(ValueError, match=r"emitter 'sun' is 'directional' \(\w+\), not a point light"):
        mimarble.render(mi.load_dict(d))


def test_specular_work_is_skipped_without_specular_channels(llvm, monkeypatch):
    monkeypatch.setenv("MIMARBLE_FREEZE", "0")      # the code traced, not a replay of it
    assert operations_traced(tiny_scene(specular=False)) < operations_traced(tiny_scene(specular=True))


@pytest.mark.parametrize("path", sorted(__import__("glob").glob("scenes/*.scene")))
@pytest.mark.parametrize("mode", ["whitted", "path"])
def test_every_paper_scene_renders_in_both_modes(llvm, path, mode):
    scene = sl.load(path)
    small = sl.model.Scene(image=sl.Image(width=24, height=24, samples=1,
                                          background=scene.image.background),
                           camera=scene.camera, ambient=scene.ambient, lights=scene.lights,
                           materials=scene.materials, spheres=scene.spheres)
    image = mimarble.render(small, mode=mode)
    assert image.shape == (24, 24, 3) and np.all(np.isfinite(image))
    assert image[12, 12].max() > 0.05


def test_whitted_render_differentiates_like_finite_differences(llvm):
    text = """image { width 24 height 24 } camera { eye < 0 0 5 > lookat < 0 0 0 > up < 0 1 0 > fov 30 }
              ambient < 0.3 0.3 0.3 > light { position < 3 4 5 > color < 1 1 1 > }
              material "m" { ambient { marble { octaves 4 period 0.8 } }
                             diffuse { marble { octaves 4 period 0.8 } } }
              sphere { center < 0 0 0 > radius 1 material "m" }"""
    scene = mi.load_dict(to_mitsuba(sl.parse(text)))
    params = mi.traverse(scene)
    key = "texture_0.period"

    def mean_image(value, grad=False):
        params[key] = mi.Float(value)
        if grad:
            dr.enable_grad(params[key])
        params.update()
        return dr.mean(mi.render(scene, params, seed=1, seed_grad=2), axis=None)

    dr.backward(mean_image(0.8, grad=True))
    ad = float(dr.grad(params[key])[0])
    h = 1e-3
    fd = (float(np.array(mean_image(0.8 + h))) - float(np.array(mean_image(0.8 - h)))) / (2 * h)
    assert abs(fd) > 1e-3 and abs(ad - fd) <= 0.01 * abs(fd) + 1e-5, (ad, fd)


@pytest.mark.parametrize("name", ["diffuse", "roughconductor", "dielectric", "conductor",
                                  "plastic", "roughplastic", "thindielectric", "principled",
                                  "constant", "point", "directional"])
def test_the_plugin_names_table_agrees_with_mitsubas_classes(llvm, name):
    from mimarble.mitsuba.plugins.whitted import MITSUBA_PLUGIN_NAMES
    assert MITSUBA_PLUGIN_NAMES[mi.load_dict({"type": name}).class_name()] == name
