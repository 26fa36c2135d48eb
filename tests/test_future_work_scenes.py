"""The paper's future work end to end: every operator and the image map, Mitsuba against
the float64 reference tracer; the scenes in scenes/future-work/ and the image they use."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import mimarble
from mimarble import reference
from mimarble import scene as S
from mimarble.tools.compare import image_metrics
from mimarble.scene.edits import resized

ROOT = Path(__file__).resolve().parent.parent
SCENES = sorted((ROOT / "scenes" / "future-work").glob("*.scene"))
MAP = ROOT / "scenes" / "future-work" / "maps" / "flagstones.png"

RED, BLUE = S.ColorChannel((0.8, 0.1, 0.1)), S.ColorChannel((0.1, 0.2, 0.9))
MARBLE = S.MarbleChannel(octaves=6, period=1.3, distortion=2.0)
GREY_MARBLE = S.MarbleChannel(octaves=4, period=2.0, axis="y",
                              ramp=((0.1, 0.1, 0.1), (1.0, 1.0, 1.0)))
IMAGE = S.ImageChannel("flagstones.png", str(MAP))


def scene_with(diffuse, ambient=None, size=48):
    return S.Scene(image=S.Image(size, size, samples=4), camera=S.Camera(eye=(0, -9, 0.5),
                                                                         up=(0, 0, 1)),
                   ambient=(0.2, 0.2, 0.2), lights=(S.Light((10, -10, 10)),),
                   materials={"m": S.Material("m", ambient=ambient, diffuse=diffuse,
                                              specular=S.ColorChannel((0.3, 0.3, 0.3)))},
                   spheres=(S.Sphere("m", radius=2.0),))


def agreement(scene):
    return image_metrics(mimarble.render(scene), reference.render(scene))


@pytest.mark.parametrize("channel", [
    S.Add((RED, MARBLE)),
    S.Multiply((S.ColorChannel((1.0, 0.95, 0.9)), MARBLE)),
    S.Multiply((MARBLE, GREY_MARBLE)),
    S.Mix(RED, MARBLE, 0.3),
    S.Mix(RED, BLUE, GREY_MARBLE),
    S.Add((S.Multiply((RED, GREY_MARBLE)), S.Mix(MARBLE, BLUE, S.ColorChannel((0.2, 0.5, 0.9))))),
], ids=["add", "multiply-colour", "multiply-marbles", "mix-number", "mix-marble-weight", "nested"])
def test_every_operator_agrees_with_the_reference(llvm, channel):
    metrics = agreement(scene_with(channel, ambient=channel))
    assert metrics["psnr"] >= 100 and metrics["frac_over_1_255"] == 0, metrics


@pytest.mark.parametrize("channel", [
    IMAGE,
    S.Mix(IMAGE, MARBLE, GREY_MARBLE),
    S.Multiply((IMAGE, GREY_MARBLE)),
], ids=["image", "veins-over-image", "image-times-marble"])
def test_image_maps_agree_with_the_reference(llvm, channel):
    metrics = agreement(scene_with(channel))
    assert metrics["psnr"] >= 50 and metrics["frac_over_1_255"] <= 0.002, metrics


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_future_work_scenes_agree_with_the_reference(llvm, path):
    scene = resized(S.load(path), 64)
    metrics = agreement(scene)
    floor = 50 if any(isinstance(c, S.ImageChannel) for m in scene.materials.values()
                      for ch in m.channels().values() for c in S.walk(ch)) else 100
    assert metrics["psnr"] >= floor and metrics["frac_over_1_255"] <= 0.002, metrics


def test_there_are_three_future_work_scenes():
    assert {p.stem for p in SCENES} >= {"base-times-marble", "veins-over-image", "two-pass-marble"}


def test_the_image_map_is_the_scripts_output(tmp_path):
    from PIL import Image
    result = subprocess.run([sys.executable, str(ROOT / "scripts" / "make_maps.py"), str(tmp_path)],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    made = np.asarray(Image.open(tmp_path / "flagstones.png"))
    committed = np.asarray(Image.open(MAP))
    assert made.shape == committed.shape == (128, 256, 3)
    assert np.array_equal(made, committed)


def test_a_missing_image_is_exit_2_at_its_file_string_with_no_output(tmp_path):
    scene = tmp_path / "s.scene"
    scene.write_text('material "m" {\n  diffuse { image { file "gone.png" } }\n}\n'
                     'sphere { material "m" }\n')
    out = tmp_path / "out.png"
    env = dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb")
    result = subprocess.run([sys.executable, "-m", "mimarble", "render", str(scene), "-o", str(out)],
                            cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith(f"{scene}:2:26: image file 'gone.png': no such file")
    assert "Traceback" not in result.stderr and not out.exists()


def test_a_python_built_expression_renders(llvm):
    scene = scene_with(S.Multiply((S.ColorChannel((1, 0.95, 0.9)), S.MarbleChannel(octaves=3))),
                       size=16)
    image = mimarble.render(scene)
    assert image.shape == (16, 16, 3) and np.isfinite(image).all() and image.max() > 0


@pytest.mark.parametrize("command", ["render", "reference"])
def test_an_image_that_does_not_decode_is_exit_2_at_its_file_string(tmp_path, command):
    good = MAP.read_bytes()
    (tmp_path / "broken.png").write_bytes(good[:200])      # a valid header, then nothing
    scene = tmp_path / "s.scene"
    scene.write_text('material "m" {\n  diffuse { image { file "broken.png" } }\n}\n'
                     'sphere { material "m" }\nimage { width 8 height 8 }\n'
                     'light { position < 5 5 5 > }\n')
    out = tmp_path / "out.png"
    env = dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb")
    result = subprocess.run([sys.executable, "-m", "mimarble", command, str(scene), "-o", str(out)],
                            cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith(f"{scene}:2:26: image file 'broken.png' cannot be decoded")
    assert "Traceback" not in result.stderr and not out.exists()
