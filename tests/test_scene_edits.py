"""Scene edits: sizes, marbles, the camera, and one value by key path."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from mimarble import scene as S
from mimarble.scene.edits import (KeyPathError, filling_the_view, resized, with_constant_colours,
    with_image_size, with_marbles, with_value)

ROOT = Path(__file__).resolve().parent.parent


def veins_scene():
    return S.Scene(materials={"veins": S.Material("veins", ambient=S.MarbleChannel(),
                                                  diffuse=S.Multiply((S.ColorChannel((1, 1, 1)),
                                                                      S.MarbleChannel())))},
                   lights=(S.Light((1, 2, 3)),))


def test_sizes_change_only_what_is_given():
    scene = S.load(ROOT / "scenes" / "fig11a.scene")
    assert with_image_size(scene) is scene
    wide = with_image_size(scene, width=64)
    assert (wide.image.width, wide.image.height) == (64, scene.image.height)
    assert wide.image.samples == scene.image.samples and wide.camera == scene.camera
    square = resized(scene, 32)
    assert (square.image.width, square.image.height) == (32, 32)
    assert square == with_image_size(scene, 32, 32)


def test_marble_edits_reach_marbles_inside_expressions():
    scene = with_marbles(veins_scene(), octaves=3, filter="bandlimit")
    veins = scene.materials["veins"]
    assert veins.ambient.octaves == 3 and veins.diffuse.operands[1].filter == "bandlimit"
    constant = with_constant_colours(S.load(ROOT / "scenes" / "fig11a.scene"))
    assert not any(isinstance(c, S.MarbleChannel)
                   for m in constant.materials.values() for c in m.channels().values())


def test_the_sphere_fills_the_view():
    scene = S.load(ROOT / "scenes" / "fig11a.scene")
    narrowed = filling_the_view(scene)
    assert 0 < narrowed.camera.fov < scene.camera.fov
    assert narrowed.camera.eye == scene.camera.eye


def test_keys_name_every_marble_one_material_or_one_channel():
    scene = veins_scene()
    every = with_value(scene, "marble.period", 2.0).materials["veins"]
    assert every.ambient.period == 2.0 and every.diffuse.operands[1].period == 2.0
    one = with_value(scene, "veins.diffuse.period", 3.0).materials["veins"]
    assert one.ambient.period == 1.0 and one.diffuse.operands[1].period == 3.0
    assert with_value(scene, "camera.fov", 20).camera.fov == 20.0
    assert with_value(scene, "light.0.intensity", 0.5).lights[0].color == (0.5, 0.5, 0.5)
    assert with_value(scene, "marble.octaves", 3.0).materials["veins"].ambient.octaves == 3
    for key, words in (("marble.perod", "unknown key"), ("stone.period", "no material"),
                       ("veins.glossy.period", "not a channel"), ("veins.specular.period", "no specular"),
                       ("light.3.intensity", "does not exist")):
        with pytest.raises(KeyPathError, match=f"^{key}: .*{words}"):
            with_value(scene, key, 1.0)


def test_marble_values_are_checked_by_the_parameter_table():
    scene = veins_scene()
    for key, value, words in (("marble.scale", 0.0, "scale must be > 0, found 0.0"),
                              ("marble.octaves", 2.5, "octaves must be an integer"),
                              ("marble.octaves", 70, "octaves must be in 0..64"),
                              ("marble.turbulence", "yes", "turbulence must be true or false"),
                              ("marble.axis", "w", "axis must be one of x, y or z"),
                              ("marble.period", float("nan"), "period must be a finite number")):
        with pytest.raises(KeyPathError, match=f"^{key}: {words}"):
            with_value(scene, key, value)
    assert with_value(scene, "marble.turbulence", "true").materials["veins"].ambient.turbulence


def test_the_module_loads_without_drjit_mitsuba_or_numpy():
    """The command line edits the scene (--width) before they load."""
    code = ("import sys; sys.orig_argv = [sys.executable, '-m', 'mimarble']; "   # as the command
            "import mimarble.scene.edits; "
            "print(sorted(m for m in ('drjit', 'mitsuba', 'numpy') if m in sys.modules))")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT),
                                                                    os.environ.get("PYTHONPATH")])))
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"
