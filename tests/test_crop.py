"""``render --crop X0 Y0 X1 Y1`` and ``mimarble.render(..., crop=)``: a window of the image,
the full render's pixels there (issue 30)."""

import importlib

import numpy as np
import pytest
from commands import mimarble_cli  # noqa: E402

import mimarble
from mimarble.cli import main as cli
from mimarble.mitsuba.rendering import image_output
from mimarble.scene.edits import with_image_size

dr, mi = mimarble.dr, mimarble.mi
render_module = importlib.import_module("mimarble.mitsuba.rendering.render")   # the module, not the function

# Two spheres, one partly in front of the other: silhouettes against the background and
# between the spheres. 4:3, small.
SCENE = """image { width 24 height 18 samples 4 }
camera { eye < 0 0 6 > lookat < 0 0 0 > up < 0 1 0 > fov 30 }
light { position < 5 5 5 > color < 1 1 1 > }
material "m" { diffuse { marble { octaves 4 } } }
sphere { center < -0.5 0 0 > radius 1 material "m" }
sphere { center < 0.9 0.4 1 > radius 0.5 material "m" }
"""

WINDOWS = [
    (5, 4, 17, 13),      # inside, across both spheres' silhouettes
    (0, 0, 24, 1),       # the top row
    (23, 17, 24, 18),    # the bottom-right pixel
    (0, 9, 7, 18),       # the bottom-left corner
    (0, 0, 24, 18),      # the whole image
]


@pytest.fixture(scope="module")
def scene():
    return mimarble.scene.parse(SCENE)


def window(image, crop):
    x0, y0, x1, y1 = crop
    return image[y0:y1, x0:x1]


@pytest.mark.parametrize("options", [
    {"spp": 4},
    {"spp": 1, "edge_spp": 16},
    {"spp": 4, "filter": "prefilter", "edge_spp": 16},
], ids=["plain", "edge-samples", "prefilter-edges"])
@pytest.mark.parametrize("crop", WINDOWS, ids=lambda c: "-".join(map(str, c)))
def test_a_whitted_window_is_the_full_renders_pixels_bit_for_bit(llvm, scene, crop, options):
    full = mimarble.render(scene, **options)
    part = mimarble.render(scene, crop=crop, **options)
    assert part.shape == (crop[3] - crop[1], crop[2] - crop[0], 3) and part.dtype == np.float32
    assert np.array_equal(part, window(full, crop))


def test_a_one_pixel_window_on_a_silhouette_gets_its_edge_samples(llvm, scene):
    """At 1 spp a pixel's one sample cannot see a silhouette: its neighbours, outside a
    1×1 window, must be traced for it to be found (the ring around the window)."""
    plain = mimarble.render(scene, spp=1)
    edges = mimarble.render(scene, spp=1, edge_spp=16)
    y, x = np.argwhere((plain != edges).any(axis=2))[0]
    part = mimarble.render(scene, spp=1, edge_spp=16, crop=(x, y, x + 1, y + 1))
    assert np.array_equal(part[0, 0], edges[y, x]) and not np.array_equal(part[0, 0], plain[y, x])


@pytest.mark.parametrize("pass_samples", [3, 7, 40])   # split pixels, ragged passes, several pixels
def test_a_window_in_small_passes_is_the_full_renders(llvm, scene, pass_samples):
    loaded = mi.load_dict(mimarble.to_mitsuba(scene, spp=4))
    full = render_module.render_in_passes(loaded, 4, pass_samples=pass_samples)
    crop = (5, 4, 17, 13)
    part = render_module.render_in_passes(loaded, 4, pass_samples=pass_samples, crop=crop)
    assert np.array_equal(part, window(full, crop))


def test_a_path_mode_window_is_deterministic_and_the_whole_image_is_the_full_render(llvm, scene):
    """Path mode draws a window's samples in its own passes, so a window's noise is not the
    full render's there (Mitsuba's film crop differs too; docs/rendering-model.md, "Output");
    what holds: the same window renders the same, and the whole image as a window is the
    full render."""
    crop = (5, 4, 17, 13)
    first = mimarble.render(scene, mode="path", spp=4, crop=crop)
    assert first.shape == (9, 12, 3) and np.isfinite(first).all() and first.max() > 0
    assert np.array_equal(first, mimarble.render(scene, mode="path", spp=4, crop=crop))
    whole = mimarble.render(scene, mode="path", spp=4, crop=(0, 0, 24, 18))
    assert np.array_equal(whole, mimarble.render(scene, mode="path", spp=4))


def test_a_scalar_window_is_the_full_renders(scene):
    previous = mi.variant()
    mi.set_variant("scalar_rgb")
    try:
        small = with_image_size(scene, 8, 6)
        full = mimarble.render(small, spp=1)
        part = mimarble.render(small, spp=1, crop=(2, 1, 7, 5))
    finally:
        mi.set_variant(previous)
    assert np.array_equal(part, full[1:5, 2:7])


@pytest.mark.parametrize("crop, error, words", [
    ((0, 0, 25, 18), ValueError, "render: crop ends outside the 24x18 image: x1 must be at most 24"),
    ((0, 0, 24, 19), ValueError, "render: crop ends outside the 24x18 image"),
    ((-1, 0, 5, 5), ValueError, "render: crop starts outside the 24x18 image"),
    ((3, 0, 3, 5), ValueError, "render: crop is empty"),
    ((0, 5, 4, 2), ValueError, "render: crop is empty"),
    ((1, 2, 3), TypeError, "render: crop must be four integers"),
    ((0, 0, 2.0, 2), TypeError, "render: crop must be four integers"),
    ((True, 0, 2, 2), TypeError, "render: crop must be four integers"),
    ("0 0 2 2", TypeError, "render: crop must be four integers"),
])
def test_a_window_out_of_the_image_is_one_sentence(scene, crop, error, words):
    with pytest.raises(error) as info:
        mimarble.render(scene, crop=crop)
    assert str(info.value).startswith(words) and "\n" not in str(info.value)


def test_a_window_is_taken_after_width_and_height(llvm, scene):
    part = mimarble.render(scene, width=12, height=9, spp=1, crop=np.array([2, 3, 12, 9]))
    assert np.array_equal(part, mimarble.render(scene, width=12, height=9, spp=1)[3:9, 2:12])
    with pytest.raises(ValueError, match="the 12x9 image"):
        mimarble.render(scene, width=12, height=9, crop=(0, 0, 13, 9))


def test_a_loaded_mitsuba_scene_refuses_a_window(llvm, scene):
    loaded = mi.load_dict(mimarble.to_mitsuba(scene))
    with pytest.raises(ValueError, match="render: crop applies to a scene model or file"):
        mimarble.render(loaded, crop=(0, 0, 2, 2))


@pytest.mark.parametrize("x0, y0, width, height", [
    (5, 7, 100, 90), (300, 260, 200, 300), (3, 250, 10, 300), (0, 256, 600, 10), (599, 559, 1, 1),
])
def test_a_windows_8_bit_pixels_are_the_full_conversions(x0, y0, width, height):
    """Mitsuba's dither is a 256×256 pattern laid from the image's top-left corner: a window
    converted with its origin gets the pattern as the whole image does there."""
    image = np.random.default_rng(3).random((560, 600, 3), dtype=np.float32) * 1.2 - 0.1
    full = image_output.srgb8(image)
    part = image[y0:y0 + height, x0:x0 + width]
    assert np.array_equal(image_output.srgb8(part, origin=(x0, y0)),
                          full[y0:y0 + height, x0:x0 + width])


def test_render_crop_writes_the_full_pngs_window(tmp_path):
    (tmp_path / "s.scene").write_text(SCENE)
    assert mimarble_cli("render", "s.scene", "-o", "full.png", cwd=tmp_path).returncode == 0
    result = mimarble_cli("render", "s.scene", "--crop", "5", "4", "17", "13", "-o", "w.png",
                          cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("w.png: 12x9 (--crop 5 4 17 13 of 24x18), 4 spp")
    full = np.array(mi.Bitmap(str(tmp_path / "full.png")))
    part = np.array(mi.Bitmap(str(tmp_path / "w.png")))
    assert np.array_equal(part, full[4:13, 5:17])


@pytest.mark.parametrize("crop, words", [
    (["0", "0", "25", "18"], "--crop 0 0 25 18: ends outside the 24x18 image"),
    (["0", "0", "8", "8", "--width", "6"], "--crop 0 0 8 8: ends outside the 6x18 image"),
    (["-2", "0", "5", "5"], "--crop -2 0 5 5: starts outside the 24x18 image"),
    (["4", "4", "4", "8"], "--crop 4 4 4 8: is empty"),
])
def test_a_bad_crop_is_one_sentence_exit_2_and_no_file(tmp_path, crop, words):
    (tmp_path / "s.scene").write_text(SCENE)
    result = mimarble_cli("render", "s.scene", "--crop", *crop, "-o", "w.png", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [result.stderr.strip()]
    assert result.stderr.startswith(f"mimarble: {words}") and "exclusive" in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.scene"]


def test_the_help_says_how_the_window_is_numbered():
    text = " ".join(cli.build_parser()._subparsers._group_actions[0].choices["render"]
                    .format_help().split())
    assert "--crop X0 Y0 X1 Y1" in text and "from 0" in text and "exclusive" in text
    assert "--crop a-1 c-1 b d" in text                     # POV-Ray's +SC +EC +SR +ER
