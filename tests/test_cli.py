"""The command line: renders, user errors (FILE:LINE:COL, exit 2, no traceback, no file)."""

import os
import subprocess
import sys

import numpy as np
import pytest
from commands import mimarble_cli  # noqa: E402

import mimarble

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SMALL = """image { width 8 height 6 samples 4 }
camera { eye < 0 0 5 > lookat < 0 0 0 > up < 0 1 0 > fov 30 }
light { position < 5 5 5 > color < 1 1 1 > }
material "m" { diffuse { marble { octaves 3 } } }
sphere { center < 0 0 0 > radius 1 material "m" }
"""




@pytest.fixture
def small_scene(tmp_path):
    path = tmp_path / "small.scene"
    path.write_text(SMALL)
    return path


@pytest.mark.parametrize("suffix", [".png", ".exr"])
def test_render_writes_the_image(tmp_path, small_scene, suffix):
    out = tmp_path / f"out{suffix}"
    result = mimarble_cli("render", small_scene, "-o", out)
    assert result.returncode == 0, result.stderr
    bitmap = mimarble.mi.Bitmap(str(out))
    assert (bitmap.width(), bitmap.height()) == (8, 6)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []   # no temp left


def test_png_is_the_srgb_encoding_of_the_linear_render(tmp_path, small_scene):
    out = tmp_path / "out.png"
    assert mimarble_cli("render", small_scene, "-o", out).returncode == 0
    png = np.array(mimarble.mi.Bitmap(str(out)), dtype=np.float64) / 255
    linear = np.clip(mimarble.render(small_scene), 0, 1)
    srgb = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)
    assert np.abs(png - srgb).max() <= 1 / 255 + 1e-6


@pytest.mark.parametrize("text, where, words", [
    (SMALL.replace("radius 1", "radius -1"), ":5:", "radius"),
    (SMALL.replace('material "m" }', 'material "nope" }'), ":5:", "nope"),
    (SMALL.replace("octaves 3", "octaves 99"), ":4:", "octaves"),
    (SMALL + "}\n", ":6:1:", "}"),
    (SMALL.replace("< 5 5 5 >", "< 5 5 >"), ":3:", "3 numbers"),
])
def test_scene_errors_point_at_file_line_column(tmp_path, text, where, words):
    path = tmp_path / "bad.scene"
    path.write_text(text)
    out = tmp_path / "bad.png"
    result = mimarble_cli("render", path, "-o", out)
    assert result.returncode == 2
    first = result.stderr.splitlines()[0]
    assert first.startswith(str(path) + where) and words in first
    assert "^" in result.stderr and "Traceback" not in result.stderr
    assert not out.exists()


@pytest.mark.parametrize("args, words", [
    (["--spp", "3"], "perfect square"),
    (["--edge-spp", "3"], "perfect square"),
    (["--edge-spp", "4", "--mode", "path"], "whitted mode"),
    (["--filter", "prefilter", "--mode", "path"], "needs whitted mode"),
    (["--filter", "blur"], "invalid choice"),
    (["-o", "x.tif"], "unsupported image format"),
    (["-o", "missing/x.png"], "does not exist"),
])
def test_argument_errors_exit_2_without_traceback(tmp_path, small_scene, args, words):
    result = mimarble_cli("render", small_scene, *args, cwd=tmp_path)
    assert result.returncode == 2 and words in result.stderr
    assert "Traceback" not in result.stderr
    assert list(tmp_path.glob("*.png")) == []


def test_missing_scene_file_is_a_clear_error(tmp_path):
    result = mimarble_cli("render", tmp_path / "nowhere.scene")
    assert result.returncode == 2 and "nowhere.scene" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize("command", [
    ["render", "./nosuch.scene", "-o", "x.png"],
    ["render", "nosuch.scene", "-o", "x.png"],           # a bare name: a packaged scene's?
    ["reference", "./nosuch.scene", "-o", "x.png"],
    ["compare", "./nosuch.scene", "--diff", "d.png"],
    ["bench", "./nosuch.scene", "--no-targets"],
    ["sweep", "./nosuch.scene", "--set", "marble.period=1,2", "-o", "sw"],
    ["gallery", "./nosuch.scene"],
    ["doctor", "--warm", "./nosuch.scene"],
], ids=lambda command: "-".join(command[:2]))
def test_every_command_prefixes_a_missing_scene_file_error(tmp_path, command):
    result = mimarble_cli(*command, cwd=tmp_path)
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1, result.stderr
    assert lines[0].startswith(f"mimarble: {command[-1] if command[0] == 'doctor' else command[1]}: ")
    assert list(tmp_path.rglob("*")) == []          # no file, no folder made


def test_path_mode_renders(tmp_path, small_scene):
    out = tmp_path / "p.exr"
    result = mimarble_cli("render", small_scene, "--mode", "path", "--spp", "2", "-o", out)
    assert result.returncode == 0, result.stderr
    assert np.isfinite(np.array(mimarble.mi.Bitmap(str(out)))).all()


def test_prefilter_with_edge_samples_renders(tmp_path, small_scene):
    out = tmp_path / "f.exr"
    result = mimarble_cli("render", small_scene, "--filter", "prefilter", "--edge-spp", "9",
                          "-o", out)
    assert result.returncode == 0, result.stderr
    assert np.isfinite(np.array(mimarble.mi.Bitmap(str(out)))).all()


def test_written_image_has_the_usual_file_mode(tmp_path, small_scene):
    out = tmp_path / "mode.png"
    assert mimarble_cli("render", small_scene, "-o", out).returncode == 0
    mask = os.umask(0)
    os.umask(mask)
    assert (out.stat().st_mode & 0o777) == (0o666 & ~mask)


@pytest.mark.parametrize("args, words", [
    (["bench", "--spp", "2"], "perfect square"),
    (["bench", "--converged-spp", "8"], "perfect square"),
    (["bench", "--repeats", "0"], "at least 1"),
    (["bench", "--size", "0"], "--size 0"),
    (["bench", "--plot", "out.foo"], "unsupported plot format"),
    (["bench", "--json", "missing/b.json"], "does not exist"),
    (["stress", "--points", "0"], "at least 1"),
    (["stress", "--json", "missing/s.json"], "does not exist"),
    (["gallery", "--size", "-3"], "--size -3"),
])
def test_command_arguments_are_checked_before_any_work(tmp_path, args, words):
    result = mimarble_cli(*args, cwd=ROOT if args[0] != "stress" else tmp_path)
    assert result.returncode == 2 and words in result.stderr, result.stderr
    assert "Traceback" not in result.stderr


def test_bench_reports_a_bad_scene_before_measuring(tmp_path, small_scene):
    bad = tmp_path / "bad.scene"
    bad.write_text(SMALL.replace("radius 1", "radius 0"))
    result = mimarble_cli("bench", small_scene, bad, "--no-targets", "--no-paper")
    assert result.returncode == 2 and str(bad) + ":5:" in result.stderr
    assert "Traceback" not in result.stderr and "[" not in result.stdout


def test_gallery_into_a_file_is_a_clear_error(tmp_path, small_scene):
    target = tmp_path / "not-a-folder"
    target.write_text("")
    result = mimarble_cli("gallery", small_scene, "-o", target)
    assert result.returncode == 2 and "not a folder" in result.stderr


def test_a_whitted_gallery_in_a_spectral_variant_is_one_sentence_and_makes_no_folder(
        tmp_path, small_scene):
    result = mimarble_cli("--variant", "llvm_ad_spectral", "gallery", small_scene,
                          "-o", tmp_path / "g")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    line, = result.stderr.strip().splitlines()
    assert "computes in RGB" in line and "could not write" not in line
    assert not (tmp_path / "g").exists()


def test_too_many_samples_are_refused(small_scene):
    result = mimarble_cli("render", small_scene, "--spp", str(2 ** 40))
    assert result.returncode == 2 and "samples" in result.stderr
    assert "Traceback" not in result.stderr


def test_reference_command_writes_an_exr(tmp_path, small_scene):
    out = tmp_path / "ref.exr"
    result = mimarble_cli("reference", small_scene, "-o", out)
    assert result.returncode == 0, result.stderr
    ours = np.array(mimarble.mi.Bitmap(str(out)))
    assert ours.shape == (6, 8, 3) and np.isfinite(ours).all()


@pytest.mark.parametrize("name", ["folder", "looks-like.png"])
def test_output_naming_a_folder_says_so(tmp_path, small_scene, name):
    (tmp_path / name).mkdir()
    result = mimarble_cli("render", small_scene, "-o", tmp_path / name)
    assert result.returncode == 2 and "is a folder" in result.stderr
    assert "Traceback" not in result.stderr and ".tmp" not in result.stderr
    assert list((tmp_path / name).iterdir()) == []


def test_missing_scene_file_says_where_it_looked(tmp_path):
    result = mimarble_cli("render", "nowhere.scene", cwd=tmp_path)
    assert str(tmp_path / "nowhere.scene") in result.stderr


def test_a_binary_file_as_scene_is_not_echoed(tmp_path):
    binary = tmp_path / "binary.scene"
    binary.write_bytes(b"\x7fELF\x02\x01\x01\x00\x00\x00\xd0\xff\x00\x01garbage\n")
    result = mimarble_cli("render", binary, "-o", tmp_path / "b.png")
    assert result.returncode == 2 and "UTF-8" in result.stderr
    assert "ELF" not in result.stderr and "\x00" not in result.stderr


def test_variant_width_and_height_also_after_the_command(tmp_path, small_scene):
    out = tmp_path / "sized.exr"
    result = mimarble_cli("render", small_scene, "--variant", "llvm_ad_rgb", "--width", "12",
                          "--height", "7", "-o", out)
    assert result.returncode == 0, result.stderr
    assert "12x7" in result.stdout
    assert np.array(mimarble.mi.Bitmap(str(out))).shape[:2] == (7, 12)
    result = mimarble_cli("reference", small_scene, "--width", "0", "-o", tmp_path / "r.exr")
    assert result.returncode == 2 and "--width 0" in result.stderr


def test_an_empty_scene_renders_with_a_warning(tmp_path):
    empty = tmp_path / "empty.scene"
    empty.write_text("image { width 4 height 4 }\n")
    result = mimarble_cli("render", empty, "-o", tmp_path / "e.png")
    assert result.returncode == 0 and "warning" in result.stderr and "no spheres" in result.stderr
    unlit = tmp_path / "unlit.scene"
    unlit.write_text(SMALL.replace("light { position < 5 5 5 > color < 1 1 1 > }\n", ""))
    result = mimarble_cli("render", unlit, "-o", tmp_path / "u.png")
    assert result.returncode == 0 and "no lights" in result.stderr


def test_go_keeps_paths_relative_to_where_the_user_stands(tmp_path, small_scene):
    """`path/to/go render my.scene` from any folder: the scene and the image are here."""
    (tmp_path / "my.scene").write_text(SMALL)
    result = subprocess.run([os.path.join(ROOT, "go"), "render", "my.scene", "--spp", "1"],
                            cwd=tmp_path, capture_output=True, text=True, timeout=300,
                            env=dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb"))
    sys.stderr.write(result.stderr)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "my.png").exists()
    assert not os.path.exists(os.path.join(ROOT, "my.png"))


def test_a_non_square_sample_count_renders_in_path_mode_only(tmp_path):
    scene = tmp_path / "three.scene"
    scene.write_text(SMALL.replace("samples 4", "samples 3"))
    whitted = mimarble_cli("render", scene, "-o", tmp_path / "w.png")
    assert whitted.returncode == 2 and f"{scene}:1:1: samples 3" in whitted.stderr
    assert "--mode path" in whitted.stderr and "Traceback" not in whitted.stderr
    path = mimarble_cli("render", scene, "--mode", "path", "-o", tmp_path / "p.png")
    assert path.returncode == 0, path.stderr and "3 spp" in path.stdout
    reference = mimarble_cli("reference", scene, "-o", tmp_path / "r.png")
    assert reference.returncode == 2 and "perfect square" in reference.stderr
