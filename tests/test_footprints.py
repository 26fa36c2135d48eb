"""Pixel footprints outside mimarble's own renderer: Mitsuba's perspective camera's
differential rays moved back to the eye, and a filter without differentials said once."""

import warnings

import numpy as np
import pytest

import mimarble
from mimarble.texture import filters as pixel_filter
from mimarble.texture.mapping import NoFootprintWarning, differentials_from_the_eye

dr, mi = mimarble.dr, mimarble.mi

SIZE = 64
#: The eye 4 from a unit sphere, its surface 3 away, and the near clip plane at 2.5:
#: Mitsuba's differentials, from the near plane, give (3 − 2.5)/3 of each footprint.
EYE, NEAR = 4.0, 2.5
#: Pixels (x, y) inside the sphere, their neighbours too, at several distances and slopes.
PIXELS = ((32, 32), (24, 40), (41, 26), (20, 30), (37, 45))


def sensor(kind="perspective", eye=(0.0, 0.0, EYE), near=NEAR, **more):
    return {"type": kind, "near_clip": near, **more,
            "to_world": mi.ScalarTransform4f().look_at(list(eye), [0, 0, 0], [0, 1, 0]),
            "film": {"type": "hdrfilm", "width": SIZE, "height": SIZE,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "stratified", "sample_count": 1, "jitter": False}}


def sphere_scene(integrator, bsdf=None, **sensors):
    scene = {"type": "scene", "integrator": integrator,
             "sphere": {"type": "sphere", "bsdf": bsdf or {"type": "diffuse"}}}
    scene.update(sensors or {"sensor": sensor()})
    return mi.load_dict(scene)


def centres(pixels, dx=0.0, dy=0.0):
    """The film positions of the pixels' centres, moved by (dx, dy) pixels."""
    xy = np.array(pixels, dtype=np.float64)
    return mi.Point2f(mi.Float((xy[:, 0] + 0.5 + dx) / SIZE), mi.Float((xy[:, 1] + 0.5 + dy) / SIZE))


def sphere_hits(camera, position):
    """Where the camera's rays through ``position`` meet the unit sphere: in float64,
    from each ray's own origin and direction, independently of Mitsuba's intersection."""
    ray, _ = camera.sample_ray(0.0, 0.0, position, mi.Point2f(0.5))
    o, d = np.array(ray.o, dtype=np.float64).T, np.array(ray.d, dtype=np.float64).T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    b, c = np.sum(o * d, axis=1), np.sum(o * o, axis=1) - 1.0
    return o + d * (-b - np.sqrt(b * b - c))[:, None]


def steps_to_the_next_pixels(camera, pixels):
    """The steps on the surface from one pixel's hit to its neighbours', central
    differences (x ± 1, y ± 1: the sphere's curvature cancels to second order)."""
    step_x = (sphere_hits(camera, centres(pixels, dx=1)) - sphere_hits(camera, centres(pixels, dx=-1))) / 2
    step_y = (sphere_hits(camera, centres(pixels, dy=1)) - sphere_hits(camera, centres(pixels, dy=-1))) / 2
    return step_x, step_y


def surface_differentials(scene, ray):
    si = scene.ray_intersect(ray)
    si.compute_uv_partials(ray)
    return (np.array(si.dp_du * si.duv_dx.x + si.dp_dv * si.duv_dx.y, dtype=np.float64).T,
            np.array(si.dp_du * si.duv_dy.x + si.dp_dv * si.duv_dy.y, dtype=np.float64).T)


def test_differentials_from_the_eye_reach_the_next_pixels_hit_under_a_far_near_plane(jit_variant):
    scene = sphere_scene({"type": "path"})
    camera = scene.sensors()[0]
    # The ray as Mitsuba's SamplingIntegrator makes it (at 1 spp its scale is 1).
    ray, _ = camera.sample_ray_differential(0.0, 0.0, centres(PIXELS), mi.Point2f(0.5))
    ray.scale_differential(1.0)
    expected_x, expected_y = steps_to_the_next_pixels(camera, PIXELS)
    dp_dx, dp_dy = surface_differentials(scene, differentials_from_the_eye(ray, scene))
    np.testing.assert_allclose(dp_dx, expected_x, rtol=0.01, atol=1e-5)
    np.testing.assert_allclose(dp_dy, expected_y, rtol=0.01, atol=1e-5)
    # Mitsuba's own, from the near plane: a fraction of it (so the check above can fail).
    mitsuba_x, _ = surface_differentials(scene, ray)
    ratio = np.linalg.norm(mitsuba_x, axis=1) / np.linalg.norm(expected_x, axis=1)
    assert (ratio < 0.3).all(), ratio


def test_each_ray_gets_its_own_perspective_cameras_eye_and_other_rays_keep_theirs(jit_variant):
    eyes = {"left": (-1.0, 0.5, 4.0), "right": (3.0, 0.0, 3.0)}
    scene = sphere_scene({"type": "path"}, left=sensor(eye=eyes["left"], near=2.0),
                         right=sensor(eye=eyes["right"], near=0.5),
                         flat=sensor("orthographic", near=1.0),
                         lens=sensor("thinlens", aperture_radius=0.1, focus_distance=3.0))
    position = centres(PIXELS)
    for camera in scene.sensors():
        ray, _ = camera.sample_ray_differential(0.0, 0.0, position, mi.Point2f(0.3, 0.8))
        fixed = differentials_from_the_eye(ray, scene)
        assert fixed.has_differentials
        for name in ("o", "d", "maxt", "d_x", "d_y"):
            np.testing.assert_array_equal(np.array(getattr(fixed, name)), np.array(getattr(ray, name)))
        if camera.id() in eyes:
            eye = np.array(eyes[camera.id()])[:, None] + np.zeros((1, len(PIXELS)))
            np.testing.assert_allclose(np.array(fixed.o_x), eye, atol=1e-6)
            np.testing.assert_allclose(np.array(fixed.o_y), eye, atol=1e-6)
        else:   # orthographic and thin lens: their differentials were right already
            np.testing.assert_array_equal(np.array(fixed.o_x), np.array(ray.o_x))
            np.testing.assert_array_equal(np.array(fixed.o_y), np.array(ray.o_y))
        # Rays that start at the eye already (render_in_passes' own) come back bit for bit.
        ray.o_x = ray.o_y = mi.Point3f(camera.world_transform().translation())
        again = np.array(differentials_from_the_eye(ray, scene).o_x)
        np.testing.assert_array_equal(again, np.broadcast_to(np.array(ray.o_x), again.shape))


def footprint_probe(self, phase, point):
    """In place of the prefilter's colour: the footprint the marble was handed."""
    return mi.Color3f(dr.norm(point.dv_dx), dr.norm(point.dv_dy), 0.0)


def unlit_marble_scene(marble_filter, integrator="whitted"):
    marble = {"type": "marble", "id": PROBE, "filter": marble_filter, "octaves": 3}
    if integrator == "whitted":   # the image is the texture: ambient 1, no lights
        return sphere_scene({"type": "whitted", "ambient": {"type": "rgb", "value": 1.0}},
                            {"type": "channel_material", "ambient": marble})
    return sphere_scene({"type": integrator}, {"type": "diffuse", "reflectance": marble})


def test_under_mi_render_the_marble_sees_the_step_to_the_next_pixels_hit(jit_variant,
                                                                         monkeypatch):
    monkeypatch.setattr(pixel_filter.Prefilter, "colour", footprint_probe)
    scene = unlit_marble_scene("prefilter")
    image = np.array(mi.render(scene, spp=1), dtype=np.float64)
    seen = np.array([image[y, x, :2] for x, y in PIXELS])
    expected_x, expected_y = steps_to_the_next_pixels(scene.sensors()[0], PIXELS)
    np.testing.assert_allclose(seen[:, 0], np.linalg.norm(expected_x, axis=1), rtol=0.01)
    np.testing.assert_allclose(seen[:, 1], np.linalg.norm(expected_y, axis=1), rtol=0.01)


PROBE = "probe-marble"


def no_footprint_warnings(record):
    """The warnings about this file's marbles (scenes other tests left loaded may have
    filtered marbles a symbolic call traces too)."""
    return [w for w in record if issubclass(w.category, NoFootprintWarning)
            and repr(PROBE) in str(w.message)]


def test_a_marble_traced_with_footprints_is_not_warned_about_later(jit_variant):
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        whitted = unlit_marble_scene("prefilter")
        mi.render(whitted, spp=1)                     # its marble traced with footprints
        marble = whitted.shapes()[0].bsdf().ambient
        path = {"type": "scene", "integrator": {"type": "path"}, "sensor": sensor(),
                "sphere": {"type": "sphere", "bsdf": {"type": "diffuse", "reflectance": marble}}}
        mi.render(mi.load_dict(path), spp=1)          # the same marble, no footprints now
        assert no_footprint_warnings(record) == []


@pytest.mark.parametrize("marble_filter", ["bandlimit", "prefilter"])
def test_a_filter_without_ray_differentials_says_so_once_per_marble(jit_variant, marble_filter):
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        path = unlit_marble_scene(marble_filter, "path")
        for spp in (1, 2):                     # traced twice, said once
            mi.render(path, spp=spp)
        said = no_footprint_warnings(record)
        assert len(said) == 1, [str(w.message) for w in said]
        assert f"filter='{marble_filter}'" in str(said[0].message)
        assert "'path'" in str(said[0].message) and "'whitted'" in str(said[0].message)
        # Where the integrator computes differentials, or nothing is filtered: silence.
        mi.render(unlit_marble_scene(marble_filter), spp=1)
        mi.render(unlit_marble_scene("none", "path"), spp=1)
        assert len(no_footprint_warnings(record)) == 1


def test_whitted_without_filters_does_not_warn_about_another_scenes_filtered_marble(jit_variant):
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        other = unlit_marble_scene("prefilter")     # kept alive: its marble is a live instance
        two = {"type": "scene", "integrator": {"type": "whitted"},
               "sensor": sensor(),
               "a": {"type": "sphere", "center": [-0.5, 0, 0], "radius": 0.4,
                     "bsdf": {"type": "channel_material", "ambient": {"type": "marble"}}},
               "b": {"type": "sphere", "center": [0.5, 0, 0], "radius": 0.4,
                     "bsdf": {"type": "channel_material",
                              "ambient": {"type": "rgb", "value": 0.5}}}}
        mi.render(mi.load_dict(two), spp=1)       # a symbolic call over every live material
        assert no_footprint_warnings(record) == []
        del other
