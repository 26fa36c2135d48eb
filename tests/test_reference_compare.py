"""Image metrics and error maps (mimarble.tools.compare) on synthetic images."""

import math

import numpy as np
import pytest

from mimarble.tools.compare import error_map, image_metrics


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


# The legend under the error map (compare --diff)

def test_legend_bar_shows_the_maps_own_colours_along_the_log_scale():
    from mimarble.tools.compare import LEGEND_BAR_ROWS, error_map_legend, legend_bar_columns
    strip = error_map_legend(400)
    x0, x1 = legend_bar_columns(400)
    fractions = (np.arange(x0, x1) - x0 + 0.5) / (x1 - x0)
    errors = 10.0 ** (-6 + 5 * fractions)           # the default scale, 1e-6 .. 1e-1
    expected = error_map(errors[None, :, None] * np.ones((1, 1, 3)), np.zeros((1, x1 - x0, 3)))
    top, bottom = LEGEND_BAR_ROWS
    for row in range(top, bottom):
        np.testing.assert_allclose(strip[row, x0:x1].astype(int), expected[0].astype(int), atol=1)


def test_legend_labels_every_decade_under_its_tick():
    from mimarble.tools.compare import LEGEND_BAR_ROWS, error_map_legend, legend_bar_columns
    strip = error_map_legend(400).astype(int)
    x0, x1 = legend_bar_columns(400)
    bottom = LEGEND_BAR_ROWS[1]
    for k in range(6):                               # 1e-6, 1e-5, … 1e-1
        x = min(x0 + round(k / 5 * (x1 - x0)), x1 - 1)
        assert (strip[bottom:bottom + 4, x] == 0).all()               # the tick
        label = strip[bottom + 4:bottom + 18, max(x - 10, 0):x + 11]
        assert (label.sum(axis=-1) < 150).sum() >= 10                 # dark text there
    between = strip[bottom:bottom + 4, x0 + (x1 - x0) // 10]
    assert (between == 128).all()                                      # no tick between


def test_map_with_legend_keeps_the_map_and_pads_a_narrow_one():
    from mimarble.tools.compare import LEGEND_HEIGHT, LEGEND_MIN_WIDTH, error_map_with_legend
    rng = np.random.default_rng(1)
    ref = rng.uniform(0, 1, (10, 16, 3))
    test = ref + rng.uniform(0, 1e-2, ref.shape)
    picture = error_map_with_legend(test, ref)
    assert picture.dtype == np.uint8
    assert picture.shape == (10 + LEGEND_HEIGHT, LEGEND_MIN_WIDTH, 3)
    np.testing.assert_array_equal(picture[:10, :16], error_map(test, ref))
    assert (picture[:10, 16:] == 128).all()
    wide = error_map_with_legend(np.zeros((3, 500, 3)), np.zeros((3, 500, 3)))
    assert wide.shape == (3 + LEGEND_HEIGHT, 500, 3)


def test_error_map_scale_names_both_ends():
    from mimarble.tools.compare import error_map_scale
    assert "black <= 1e-6" in error_map_scale() and "white >= 1e-1" in error_map_scale()
    assert "log scale" in error_map_scale(1e-4, 1.0) and "white >= 1e0" in error_map_scale(1e-4, 1.0)
