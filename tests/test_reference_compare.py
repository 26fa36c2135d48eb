"""Image metrics and error maps (mimarble.compare) on synthetic images."""

import math

import numpy as np
import pytest

from mimarble.compare import error_map, image_metrics


def test_identical_images():
    img = np.random.default_rng(0).uniform(0, 1, (4, 5, 3))
    m = image_metrics(img, img.copy())
    assert m == {"rmse": 0.0, "psnr": math.inf, "max_abs": 0.0, "frac_over_1_255": 0.0}


def test_one_pixel_off_by_0_01():
    H, W = 4, 5
    ref = np.full((H, W, 3), 0.5)
    test = ref.copy()
    test[2, 3, 1] += 0.01
    m = image_metrics(test, ref)
    rmse = math.sqrt(0.01**2 / (H * W * 3))
    assert m["rmse"] == pytest.approx(rmse, rel=1e-9)
    assert m["psnr"] == pytest.approx(20 * math.log10(1 / rmse), rel=1e-9)
    assert m["max_abs"] == pytest.approx(0.01, abs=1e-15)
    assert m["frac_over_1_255"] == 1 / (H * W)


def test_small_errors_are_not_counted_over_1_255():
    ref = np.zeros((3, 3, 3))
    test = ref + 0.9 / 255
    test[0, 0] = [0.0, -2 / 255, 0.0]        # largest channel |diff| exceeds 1/255
    m = image_metrics(test, ref)
    assert m["frac_over_1_255"] == 1 / 9
    assert m["max_abs"] == pytest.approx(2 / 255)


def test_shape_mismatch_raises():
    with pytest.raises(ValueError):
        image_metrics(np.zeros((2, 2, 3)), np.zeros((2, 3, 3)))


def test_error_map_colours():
    ref = np.zeros((1, 4, 3))
    test = ref.copy()
    test[0, 1, 2] = 10 ** -3.5             # middle of the log range 1e-6..1e-1: magenta
    test[0, 2, 0] = 0.5                    # above 1e-1: white
    test[0, 3, 1] = 1e-6                   # at the bottom: black
    em = error_map(test, ref)
    assert em.dtype == np.uint8 and em.shape == (1, 4, 3)
    np.testing.assert_array_equal(em[0], [[0, 0, 0], [255, 0, 255], [255, 255, 255], [0, 0, 0]])


def test_error_map_is_monotone_in_luminance():
    errs = np.logspace(-6, -1, 50)
    ref = np.zeros((1, 50, 3))
    test = ref + errs[None, :, None]
    em = error_map(test, ref).astype(float)[0]
    lum = em @ np.array([0.2126, 0.7152, 0.0722])
    assert np.all(np.diff(lum) >= 0) and lum[-1] > lum[0]
