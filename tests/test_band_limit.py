"""Band-limited marble: octaves finer than the pixel footprint are left out."""


import numpy as np
import pytest

import mimarble
from mimarble.texture import noise
from mimarble.mitsuba import to_mitsuba
from mimarble.scene.edits import resized, with_marbles

dr, mi = mimarble.dr, mimarble.mi


def band_limited(p, octaves, footprint, turbulence=False):
    return noise.fractal_band(p, octaves, noise.band_limit(footprint, octaves), turbulence)


def points(n=5000, seed=0):
    pts = np.random.default_rng(seed).uniform(-20, 20, (n, 3)).astype(np.float32)
    return mi.Point3f(*(mi.Float(pts[:, a]) for a in range(3)))


def test_zero_footprint_keeps_every_octave_bit_for_bit(jit_variant):
    p = points()
    for octaves in (1, 8, 32):
        full = np.array(noise.fractal3(p, octaves))
        looped = np.array(band_limited(p, octaves, dr.zeros(mi.Float, dr.width(p))))
        np.testing.assert_array_equal(looped, full)


def test_footprint_drops_the_sub_pixel_octaves(jit_variant):
    p = points(seed=1)
    # footprint 2^-5: n = margin − 1 + 5 whole octaves, and no fraction to fade in
    kept = noise.BAND_LIMIT_MARGIN - 1 + 5
    footprint = dr.full(mi.Float, 2.0 ** -5, dr.width(p))
    limited = np.array(band_limited(p, 32, footprint))
    np.testing.assert_array_equal(limited, np.array(noise.fractal3(p, kept)))
    assert not np.array_equal(limited, np.array(noise.fractal3(p, kept + 1)))


def test_unrolled_sum_for_derivatives_equals_the_loop(jit_variant):
    """With derivatives the band-limited sum is unrolled (reverse mode cannot go through
    a symbolic loop): the same weights, the same value."""
    p = points(seed=2)
    footprint = mi.Float(np.random.default_rng(3).uniform(1e-4, 0.3, dr.width(p)).astype(np.float32))
    looped = np.array(band_limited(p, 12, footprint, turbulence=True))
    tracked = mi.Point3f(p)
    dr.enable_grad(tracked)
    unrolled = np.array(dr.detach(band_limited(tracked, 12, footprint, turbulence=True)))
    np.testing.assert_allclose(looped, unrolled, atol=1e-6)


def bandlimited(scene, flag=True):
    return with_marbles(scene, filter="bandlimit" if flag else "none")


def test_band_limited_render_stays_close_to_the_full_one(llvm):
    scene = resized(mimarble.scene.load("scenes/fig11b.scene"), 96)
    full = mimarble.render(scene)
    limited = mimarble.render(bandlimited(scene))
    assert np.all(np.isfinite(limited))
    assert np.sqrt(np.mean((full - limited) ** 2)) < 0.05
    assert not np.array_equal(full, limited)       # something was left out


def test_band_limited_whitted_render_differentiates_like_finite_differences(llvm):
    # whitted provides ray differentials, so the footprint is real and the unrolled,
    # weighted octave sum is what the gradient goes through.
    scene = bandlimited(resized(mimarble.scene.load("scenes/fig11a.scene"), 32))
    mitsuba_scene = mi.load_dict(to_mitsuba(scene, spp=1))
    params = mi.traverse(mitsuba_scene)
    key = "texture_0.scale"

    def mean_image(value, grad=False):
        params[key] = mi.Float(value)
        if grad:
            dr.enable_grad(params[key])
        params.update()
        return dr.mean(mi.render(mitsuba_scene, params, seed=1, seed_grad=2), axis=None)

    dr.backward(mean_image(1.0, grad=True))
    ad = float(dr.grad(params[key])[0])
    # The image is a fast-varying function of scale: a small step (1e-3 is already
    # too coarse: −0.1310 against −0.1349), and float32 is still fine at 1e-4.
    h = 1e-4
    fd = (float(np.array(mean_image(1.0 + h))) - float(np.array(mean_image(1.0 - h)))) / (2 * h)
    assert abs(fd) > 1e-3 and abs(ad - fd) <= 0.01 * abs(fd), (ad, fd)


def test_invalid_footprints_terminate_with_a_defined_octave_count(jit_variant):
    p = points(seed=4)
    full = np.array(noise.fractal3(p, 8))
    for bad in (float("nan"), -1.0):                  # no usable footprint: every octave
        footprint = dr.full(mi.Float, bad, dr.width(p))
        np.testing.assert_array_equal(np.array(band_limited(p, 8, footprint)), full)
    infinite = dr.full(mi.Float, float("inf"), dr.width(p))   # all detail sub-pixel: none
    assert np.all(np.array(band_limited(p, 8, infinite)) == 0)
