"""``.jpg``/``.jpeg`` output: the PNG's 8-bit pixels, compressed at ``--quality`` (issue 30)."""

import numpy as np
import pytest
from commands import mimarble_cli  # noqa: E402
from PIL import Image

import mimarble
from mimarble.mitsuba.rendering.image_output import write_image

SCENE = """image { width 48 height 36 samples 4 }
camera { eye < 0 0 6 > lookat < 0 0 0 > up < 0 1 0 > fov 30 }
light { position < 5 5 5 > color < 1 1 1 > }
material "m" { diffuse { marble { octaves 4 } } }
sphere { center < -0.5 0 0 > radius 1 material "m" }
sphere { center < 0.9 0.4 1 > radius 0.5 material "m" }
"""


@pytest.fixture(scope="module")
def image():
    previous = mimarble.mi.variant()
    mimarble.mi.set_variant("llvm_ad_rgb")
    try:
        return mimarble.render(mimarble.scene.parse(SCENE))
    finally:
        mimarble.mi.set_variant(previous)


def pixels(path):
    return np.asarray(Image.open(path).convert("RGB")).astype(int)


def test_a_jpeg_at_95_decodes_to_the_pngs_pixels_within_jpegs_error(tmp_path, image):
    write_image(tmp_path / "x.png", image)
    write_image(tmp_path / "x.jpg", image)
    error = np.abs(pixels(tmp_path / "x.jpg") - pixels(tmp_path / "x.png"))
    # Measured (Pillow 13's libjpeg-turbo, this 48×36 image): max 17 code values, 2.44 RMS.
    assert error.max() <= 24 and np.sqrt((error ** 2).mean()) <= 3.0
    with Image.open(tmp_path / "x.jpg") as jpeg:
        assert jpeg.format == "JPEG"
        assert {layer[1:3] for layer in jpeg.layer} == {(1, 1)}     # 4:4:4: colour not halved


def test_a_higher_quality_is_closer_to_the_png(tmp_path, image):
    write_image(tmp_path / "x.png", image)
    errors = []
    for quality in (20, 60, 100):
        write_image(tmp_path / f"q{quality}.jpeg", image, quality=quality)
        errors.append(np.abs(pixels(tmp_path / f"q{quality}.jpeg") - pixels(tmp_path / "x.png")).mean())
    assert errors == sorted(errors, reverse=True) and errors[-1] < 1.0


@pytest.mark.parametrize("name", ["x.jpg", "x.jpeg", "X.JPG"])
def test_render_writes_a_jpeg_where_it_said_use_png_or_exr(tmp_path, name):
    (tmp_path / "s.scene").write_text(SCENE)
    result = mimarble_cli("render", "s.scene", "-o", name, "--quality", "90", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert pixels(tmp_path / name).shape == (36, 48, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["s.scene", name])   # no temp


@pytest.mark.parametrize("args, words", [
    (["-o", "x.jpg", "--quality", "0"], "mimarble: --quality 0: must be in 1..100, found 0"),
    (["-o", "x.jpg", "--quality", "101"], "mimarble: --quality 101: must be in 1..100"),
    (["-o", "x.png", "--quality", "90"], "mimarble: --quality 90: applies to .jpg or .jpeg "
                                         "output, not .png"),
    (["-o", "x.tif"], "mimarble: x.tif: unsupported image format '.tif'; use .png, .exr, "
                      ".jpg or .jpeg"),
])
def test_a_bad_quality_or_format_is_one_sentence_exit_2_and_no_file(tmp_path, args, words):
    (tmp_path / "s.scene").write_text(SCENE)
    result = mimarble_cli("render", "s.scene", *args, cwd=tmp_path)
    assert result.returncode == 2 and result.stderr.startswith(words), result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.scene"]


@pytest.mark.parametrize("name, quality, words", [
    ("x.jpg", 0, "quality must be in 1..100, found 0"),
    ("x.jpg", 95.0, "quality must be an integer in 1..100"),
    ("x.jpg", True, "quality must be an integer in 1..100"),
    ("x.png", 90, "quality applies to .jpg or .jpeg images, not .png"),
])
def test_write_image_refuses_a_bad_quality(tmp_path, image, name, quality, words):
    with pytest.raises(ValueError, match=words):
        write_image(tmp_path / name, image, quality=quality)
    assert list(tmp_path.iterdir()) == []


def test_the_reference_command_writes_a_jpeg_too(tmp_path):
    (tmp_path / "s.scene").write_text(SCENE.replace("width 48 height 36", "width 12 height 9"))
    result = mimarble_cli("reference", "s.scene", "-o", "r.jpg", "--spp", "1", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert pixels(tmp_path / "r.jpg").shape == (9, 12, 3)
