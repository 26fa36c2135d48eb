"""Area lights (``light { … area { … } }``): n×n point lights at fixed stratum centres, in
the language, the model, Mitsuba's whitted integrator (the ``stratified_area`` emitter),
path mode (Mitsuba's own area emitters) and the reference tracer, which follows the same
pattern independently (docs/rendering-model.md, "Area lights")."""

import math

import numpy as np
import pytest
from traced import operations_traced  # noqa: E402

import mimarble
from mimarble import reference
from mimarble import scene as sl
from mimarble.tools.compare import image_metrics
from mimarble.mitsuba import to_mitsuba
from mimarble.reference import tracer

dr, mi = mimarble.dr, mimarble.mi

RECTANGLE = "area { axis1 < 2 0 0 > axis2 < 0 0 1.5 > samples SAMPLES }"
SPHERE = "area { radius 0.8 samples SAMPLES }"


def floor_scene(area="", size=32, spp=1, samples=16, position="3 5 2", color="1 0.9 0.8"):
    """A unit sphere on a large floor sphere, lit from above: it casts a shadow."""
    light = f"light {{ position < {position} > color < {color} > {area.replace('SAMPLES', str(samples))} }}"
    return sl.parse(f"""
        image {{ width {size} height {size} samples {spp} background < 0.1 0.1 0.2 > }}
        camera {{ eye < 0 1.5 6 > lookat < 0 0 0 > up < 0 1 0 > fov 40 }}
        ambient < 0.1 0.1 0.1 >
        {light}
        material "m" {{ ambient {{ color < 1 1 1 > }} diffuse {{ color < 0.8 0.5 0.3 > }}
                        specular {{ color < 0.3 0.3 0.3 > }} shininess 20 }}
        material "g" {{ ambient {{ color < 1 1 1 > }} diffuse {{ color < 0.5 0.5 0.5 > }} }}
        sphere {{ center < 0 0 0 > radius 1 material "m" }}
        sphere {{ center < 0 -101 0 > radius 100 material "g" }}""")


# ---------------------------------------------------------------------------
# The language and the model

def test_area_blocks_parse_into_the_model():
    rect = floor_scene(RECTANGLE, samples=9).lights[0]
    assert rect.area == sl.RectangleArea((2, 0, 0), (0, 0, 1.5), 9) and rect.samples == 9
    sphere = floor_scene("area { radius 0.5 }").lights[0]
    assert sphere.area == sl.SphereArea(0.5) and sphere.samples == 16   # the default, 4×4
    assert floor_scene().lights[0].area is None and floor_scene().lights[0].samples == 1


@pytest.mark.parametrize("area, at, message", [
    ("area { radius 1 samples 10 }", "10", "samples must be a perfect square n·n"),
    ("area { radius 1 samples 0 }", "0 }", "an area light takes 1..1024 samples"),
    ("area { radius 1 samples 1025 }", "1025", "an area light takes 1..1024 samples"),
    ("area { radius 1 samples 2.5 }", "2.5", "samples must be an integer"),
    ("area { radius 0 }", "0 }", "radius must be > 0, found 0"),
    ("area { axis1 < 1 0 0 > axis2 < -2 0 0 > }", "axis2", "must not be parallel"),
    ("area { axis1 < 0 0 0 > axis2 < 0 0 1 > }", "axis1", "must not be zero"),
    ("area { radius 1e38 }", "1e38", "radius must be at most 1e+18"),
    ("area { axis1 < 3e38 0 0 > axis2 < 0 3e38 0 > }", "axis2", "must be at most 1e+18 long"),
    ("area { axis1 < 1 0 0 > radius 1 }", "radius",
     "a rectangle (axis1 and axis2) or a sphere (radius), not both"),
    ("area { axis1 < 1 0 0 > }", "area", "needs both axis1 and axis2 (no 'axis2')"),
    ("area { samples 4 }", "area", "area needs axis1 and axis2 (a rectangle) or radius (a sphere)"),
    ("area { size < 1 2 > }", "size", "unknown keyword 'size' in 'area' block"),
])
def test_a_bad_area_block_is_refused_at_file_line_column(area, at, message):
    line = f"light {{ position < 0 5 0 > {area} }}"
    column = line.index(at) + 1
    with pytest.raises(sl.SceneError) as error:
        sl.parse(f"// an area light\n{line}\n", filename="a.scene")
    assert str(error.value).startswith(f"a.scene:2:{column}: "), str(error.value)
    assert message in str(error.value)


def test_the_constructors_refuse_what_the_parser_refuses_in_its_words():
    with pytest.raises(ValueError, match="perfect square"):
        sl.SphereArea(1.0, samples=8)
    with pytest.raises(ValueError, match="1..1024 samples"):
        sl.RectangleArea((1, 0, 0), (0, 1, 0), samples=32 * 32 + 1)
    with pytest.raises(ValueError, match="must not be parallel"):
        sl.RectangleArea((1, 0, 0), (3, 0, 0))
    with pytest.raises(ValueError, match="radius must be > 0"):
        sl.SphereArea(-1.0)
    with pytest.raises(TypeError, match="a light's area must be"):
        sl.Light((0, 0, 0), area=(1, 2, 3))
    assert sl.LIMITS["max_light_samples"] == 1024


def test_an_area_light_counts_as_one_light_towards_the_light_limit():
    area = "light { position < 0 5 0 > area { radius 1 samples 1024 } }\n"
    points = "light { position < 0 5 0 > }\n" * (sl.LIMITS["max_lights"] - 1)
    assert len(sl.parse(area + points).lights) == sl.LIMITS["max_lights"]
    with pytest.raises(sl.SceneError, match="too many lights"):
        sl.parse(area + points + area)


# ---------------------------------------------------------------------------
# The pattern, in the reference tracer (its own float64 implementation)

def test_the_rectangle_pattern_is_the_grid_of_stratum_centres():
    light = floor_scene(RECTANGLE, samples=4).lights[0]
    points = tracer.area_sample_points(tracer.area_samples(light, (0, 0, 0)), np.zeros((1, 3)))
    expected = [(3 + s * 2, 5, 2 + t * 1.5) for t in (-0.25, 0.25) for s in (-0.25, 0.25)]
    np.testing.assert_allclose(points[:, 0], expected, atol=1e-15)


def test_the_sphere_pattern_is_the_concentric_disk_facing_each_point():
    light = floor_scene(SPHERE, samples=9).lights[0]
    pattern = tracer.area_samples(light, (0, 0, 0))
    # n = 3: the centre stratum maps to the centre, the corners to radius 2/3 at 45°.
    assert np.allclose(pattern.offsets[4], 0) and np.allclose(pattern.offsets[8], [2 / 3 / math.sqrt(2)] * 2)
    p = np.array([[0.3, 1.0, 0.2], [-1.0, 0.1, 0.4], [3.0, -5.0, 2.0]])
    points = tracer.area_sample_points(pattern, p)               # (9, 3 points, 3)
    centre = np.array(light.position)
    w = (p - centre) / np.linalg.norm(p - centre, axis=1, keepdims=True)
    offsets = points - centre
    np.testing.assert_allclose(np.einsum("skj,kj->sk", offsets, w), 0, atol=1e-14)   # a disk ⟂ w
    np.testing.assert_allclose(np.linalg.norm(offsets, axis=2).max(axis=0), 0.8 * 2 / 3, rtol=1e-12)
    np.testing.assert_allclose(points[4], np.broadcast_to(centre, (3, 3)), atol=1e-15)


def test_reference_area_light_is_its_samples_as_point_lights():
    scene = floor_scene(RECTANGLE, samples=4, size=12)
    light = scene.lights[0]
    points = [sl.Light((3 + s * 2, 5, 2 + t * 1.5), tuple(c / 4 for c in light.color))
              for t in (-0.25, 0.25) for s in (-0.25, 0.25)]
    as_points = sl.model.Scene(image=scene.image, camera=scene.camera, ambient=scene.ambient,
                               lights=tuple(points), materials=scene.materials, spheres=scene.spheres)
    np.testing.assert_allclose(reference.render(scene), reference.render(as_points), atol=1e-13)


# ---------------------------------------------------------------------------
# Mitsuba's whitted integrator

@pytest.mark.parametrize("area", [RECTANGLE, SPHERE])
def test_an_area_light_of_one_sample_renders_as_the_point_light_at_its_centre(jit_variant, area):
    point = mimarble.render(floor_scene(size=16))
    one = mimarble.render(floor_scene(area, samples=1, size=16))
    np.testing.assert_array_equal(one, point)


def test_the_scalar_variant_renders_one_sample_as_the_point_light_to_rounding():
    previous = mi.variant()
    mi.set_variant("scalar_rgb")
    try:
        point = mimarble.render(floor_scene(size=8))
        one = mimarble.render(floor_scene(SPHERE, samples=1, size=8))
        four = mimarble.render(floor_scene(SPHERE, samples=4, size=8))
    finally:
        mi.set_variant(previous)
    np.testing.assert_allclose(one, point, atol=1e-6)
    np.testing.assert_allclose(four, mimarble.render(floor_scene(SPHERE, samples=4, size=8)),
                               atol=1e-6)


@pytest.mark.parametrize("area", [RECTANGLE, SPHERE])
def test_area_light_agrees_with_the_reference_above_100_db(llvm, area):
    scene = floor_scene(area, samples=16, size=40, spp=4)
    metrics = image_metrics(mimarble.render(scene), reference.render(scene))
    assert metrics["psnr"] >= 100 and metrics["frac_over_1_255"] == 0, metrics


def light_visible(scene):
    """The fraction of the light that reaches each pixel's floor or sphere point: (image −
    ambient only) / (image without shadows − ambient only), where that is lit at all."""
    unshadowed = to_mitsuba(scene)
    unshadowed["integrator"]["shadows"] = False
    dark = mimarble.render(sl.model.Scene(image=scene.image, camera=scene.camera,
                                          ambient=scene.ambient, materials=scene.materials,
                                          spheres=scene.spheres))
    full = mimarble.render(mi.load_dict(unshadowed)) - dark
    return np.where(full > 1e-3, (mimarble.render(scene) - dark) / np.maximum(full, 1e-3), 1.0)[..., 0]


@pytest.mark.parametrize("area", [RECTANGLE, SPHERE])
def test_the_shadow_has_a_soft_edge_that_rises_monotonically(llvm, area):
    """Along the image row through the darkest point of the sphere's shadow on the floor,
    leftwards (away from the light, at +x): under the point light the light is seen whole
    or not at all; under the area light it rises monotonically from the umbra through
    partly lit pixels to the whole light."""
    size = 48
    hard = light_visible(floor_scene(size=size))
    soft = light_visible(floor_scene(area, samples=64, size=size))
    floor = slice(size // 2 + 4, size)          # rows below the sphere: the floor
    row, column = np.unravel_index(np.argmin(soft[floor]), soft[floor].shape)
    ramp = soft[floor][row, column::-1]
    assert ramp[0] < 0.05 and ramp[-1] > 0.95, ramp
    end = int(np.argmax(ramp > 0.95))
    assert np.all(np.diff(ramp[:end + 1]) >= -1e-4), ramp
    assert ((ramp > 0.05) & (ramp < 0.95)).sum() >= 3, ramp        # the penumbra
    assert not np.any((hard > 1e-4) & (hard < 1 - 1e-4)), "a point light's shadow is hard"


def test_the_samples_are_a_loop_not_unrolled(llvm, monkeypatch):
    monkeypatch.setenv("MIMARBLE_FREEZE", "0")      # the code traced, not a replay of it
    assert operations_traced(floor_scene(SPHERE, samples=4, size=8)) == \
        operations_traced(floor_scene(SPHERE, samples=256, size=8))


# ---------------------------------------------------------------------------
# The plugin's dict interface, its edits and replays

def test_the_stratified_area_plugin_from_a_dict(llvm):
    light = mi.load_dict({"type": "stratified_area", "shape": "sphere", "radius": 0.5,
                          "position": [1, 2, 3], "intensity": [2, 2, 2], "samples": 9})
    assert set(mi.traverse(light).keys()) == {"position", "intensity", "radius"}
    assert light.recording_key() == ("stratified_area", "sphere", 9)
    for bad, message in [({"samples": 8}, "perfect square"), ({"shape": "disk"}, "rectangle or sphere"),
                         ({"axis1": [1, 0, 0], "axis2": [2, 0, 0]}, "parallel"),
                         ({}, "needs axis1 and axis2")]:
        with pytest.raises(RuntimeError, match=message):
            mi.load_dict({"type": "stratified_area", "position": [0, 0, 0], **bad})


def test_an_edited_area_light_replays_what_a_fresh_trace_renders(llvm, monkeypatch):
    from mimarble.mitsuba.rendering import passes
    from mimarble.mitsuba.rendering.render import render_in_passes
    from mimarble.mitsuba.rendering.replay import scene_key
    scene = mi.load_dict(to_mitsuba(floor_scene(SPHERE, samples=9, size=16)))
    render_in_passes(scene, 1)
    before = render_in_passes(scene, 1)
    key, recordings = scene_key(scene), passes.traced_pass.recordings
    for name, value in [("light_0.position", mi.Point3f(-2, 6, 3)),
                        ("light_0.intensity", mi.Color3f(2, 1, 0.5)), ("light_0.radius", mi.Float(0.3))]:
        params = mi.traverse(scene)
        params[name] = value
        params.update()
        replayed = render_in_passes(scene, 1)
        with monkeypatch.context() as m:
            m.setenv("MIMARBLE_FREEZE", "0")
            fresh = render_in_passes(scene, 1)
        np.testing.assert_array_equal(replayed, fresh)
        assert not np.array_equal(replayed, before)
        before = replayed
    assert passes.traced_pass.recordings == recordings and scene_key(scene) == key


# ---------------------------------------------------------------------------
# Path mode: Mitsuba's own area emitters

def test_path_mode_area_lights_are_mitsuba_area_emitters_of_matched_intensity():
    lookat = (0.0, 0.0, 0.0)
    sphere = to_mitsuba(floor_scene(SPHERE), mode="path")["light_0"]
    d2 = 3 ** 2 + 5 ** 2 + 2 ** 2
    assert sphere["type"] == "sphere" and sphere["radius"] == 0.8
    np.testing.assert_allclose(sphere["emitter"]["radiance"]["value"],
                               np.array([1, 0.9, 0.8]) * d2 / 0.8 ** 2)   # π R² L = I π d²
    rect = to_mitsuba(floor_scene(RECTANGLE), mode="path")["light_0"]
    matrix = np.array(rect["to_world"].matrix)
    normal = matrix[:3, 2]
    towards = (np.array(lookat) - (3, 5, 2)) / math.sqrt(d2)
    assert rect["type"] == "rectangle" and normal @ towards > 0          # it faces the scene
    np.testing.assert_allclose(abs(np.linalg.det(matrix[:3, :3])) * 4, 2 * 1.5)   # its area
    cos = normal @ towards
    np.testing.assert_allclose(rect["emitter"]["radiance"]["value"],
                               np.array([1, 0.9, 0.8]) * math.pi * d2 / (3.0 * cos))


def test_path_mode_sphere_light_lights_as_the_point_light_does(llvm):
    point = mimarble.render(floor_scene(size=16), mode="path", spp=64)
    sphere = mimarble.render(floor_scene(SPHERE.replace("0.8", "0.2"), size=16), mode="path", spp=64)
    assert abs(sphere[4:12, 4:12].mean() / point[4:12, 4:12].mean() - 1) < 0.05
