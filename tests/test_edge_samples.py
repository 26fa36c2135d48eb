"""Edge samples: pixels on a silhouette rendered again with n×n stratum centres."""

import importlib

import numpy as np
import pytest

import mimarble
from mimarble.mitsuba.rendering import silhouettes
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering.pixel_tracer import PassNumbers, PixelTracer
from mimarble.scene.edits import resized

dr, mi = mimarble.dr, mimarble.mi
render_module = importlib.import_module("mimarble.mitsuba.rendering.render")


def test_a_pixel_is_an_edge_when_its_neighbourhood_sees_two_shapes():
    ids = np.zeros((5, 6), dtype=np.uint32)
    ids[:, 3:] = 7                                    # a vertical boundary between columns 2, 3
    shapes = np.stack([ids.ravel(), ids.ravel()])
    edges = silhouettes.silhouette_pixels(shapes, 6, 5)
    mask = np.zeros(30, dtype=bool)
    mask[edges] = True
    expected = np.zeros((5, 6), dtype=bool)
    expected[:, 2:4] = True
    np.testing.assert_array_equal(mask.reshape(5, 6), expected)
    # A pixel whose own samples see two shapes is an edge, and so are its neighbours.
    shapes = np.zeros((2, 30), dtype=np.uint32)
    shapes[1, 14] = 1
    mask = np.zeros(30, dtype=bool)
    mask[silhouettes.silhouette_pixels(shapes, 6, 5)] = True
    assert mask.sum() == 9 and mask.reshape(5, 6)[1:4, 1:4].all()


def loaded(scene, spp):
    return mi.load_dict(to_mitsuba(scene, spp=spp))


def test_edge_pixels_get_exactly_the_supersampled_pixels_and_the_rest_stay(llvm):
    scene = resized(mimarble.scene.load("scenes/fig10d.scene"), 48)
    once = render_module.render_in_passes(loaded(scene, 1), 1)
    sixteen = render_module.render_in_passes(loaded(scene, 16), 16)
    both = render_module.render_in_passes(loaded(scene, 1), 1, edge_spp=16)
    edges = silhouettes.edge_mask(loaded(scene, 1), 1)
    assert 0 < edges.mean() < 0.3
    np.testing.assert_array_equal(both[edges], sixteen[edges])
    np.testing.assert_array_equal(both[~edges], once[~edges])
    # Deterministic, and in passes of any size.
    again = render_module.render_in_passes(loaded(scene, 1), 1, edge_spp=16, pass_samples=100)
    np.testing.assert_array_equal(again, both)


def test_edge_samples_are_validated():
    for bad in (0, 3, 2.0, True):
        with pytest.raises(ValueError, match="perfect square"):
            render_module.check_edge_spp(bad)
    with pytest.raises(ValueError, match="whitted"):
        render_module.check_edge_spp(4, "path")


def test_a_pixel_filter_in_path_mode_is_refused_before_loading(llvm):
    for name in ("bandlimit", "prefilter"):
        with pytest.raises(ValueError, match="needs whitted mode"):
            mimarble.render("scenes/fig11a.scene", mode="path", filter=name)
    render_module.check_filter("none", "path")     # no filter at all is fine


def test_ray_differentials_reach_the_next_pixels_hit(llvm):
    # Mitsuba's perspective camera starts the differential rays at the main ray's near-plane
    # point; from the eye, the footprint on the surface is the step to the next pixel's hit.
    scene = resized(mimarble.scene.load("scenes/fig11a.scene"), 256)
    mitsuba_scene = loaded(scene, 1)
    tracer = PixelTracer(mitsuba_scene, "whitted")
    pixel = mi.UInt32([100 * 256 + 100, 100 * 256 + 101, 101 * 256 + 100])
    ray, _ = tracer.ray(pixel, mi.UInt32([0, 0, 0]), PassNumbers(0, 0, 1, 1, 0, True))
    si = mitsuba_scene.ray_intersect(ray)
    si.compute_uv_partials(ray)
    dp_dx = np.array(si.dp_du * si.duv_dx.x + si.dp_dv * si.duv_dx.y)[:, 0]
    dp_dy = np.array(si.dp_du * si.duv_dy.x + si.dp_dv * si.duv_dy.y)[:, 0]
    p = np.array(si.p)
    np.testing.assert_allclose(dp_dx, p[:, 1] - p[:, 0], rtol=0.03, atol=2e-4)
    np.testing.assert_allclose(dp_dy, p[:, 2] - p[:, 0], rtol=0.03, atol=2e-4)


def test_render_takes_filter_and_edge_samples(llvm):
    scene = resized(mimarble.scene.load("scenes/fig10d.scene"), 32)
    image = mimarble.render(scene, spp=1, filter="prefilter", edge_spp=4)
    assert image.shape == (32, 32, 3) and np.isfinite(image).all()
    with pytest.raises(ValueError, match="filter"):
        mimarble.render(scene, spp=1, filter="blur")
