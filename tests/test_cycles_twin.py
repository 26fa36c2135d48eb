"""scripts/cycles_twin.py, the Blender Cycles twin of a translucent scene: what it builds from a
scene (lights' power, the Principled inputs, the colour's kind), what it refuses, and — only
where Blender is installed — that a Lambertian twin under path mode's lights and sky renders
what our path mode renders (the units of the lights and the sky, the camera)."""

import importlib.util
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from mimarble import scene as S

ROOT = Path(__file__).resolve().parent.parent

SPHERE = """
image    { width 32 height 32 samples 4 background < 0 0 0 > }
camera   { eye < 0 0 9 > lookat < 0 0 0 > up < 0 1 0 > fov 30 }
AMBIENT
LIGHT
material "m" { MATERIAL }
sphere { center < 0 0 0 > radius 2 material "m" }
"""
SUBSURFACE = "subsurface { albedo color < 0.8 0.6 0.4 > mean_free_path 0.05 ior 1.5 }"


def _twin():
    spec = importlib.util.spec_from_file_location("cycles_twin", ROOT / "scripts" / "cycles_twin.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _scene(ambient="ambient < 0.5 0.5 0.5 >", light="", material=SUBSURFACE):
    return S.parse(SPHERE.replace("AMBIENT", ambient).replace("LIGHT", light)
                   .replace("MATERIAL", material))


def test_a_light_gets_path_modes_radiant_intensity_towards_the_lookat_point():
    twin = _twin()
    spec = twin.twin_spec(_scene(light="light { position < 3 4 0 > color < 2 1 0.5 > }"), 4, 0)
    (light,) = spec["lights"]
    # Cycles: intensity P/(4π); path mode: I·π·d², d = 5.
    assert [p / (4 * math.pi) for p in light["power"]] == pytest.approx(
        [c * math.pi * 25 for c in (2, 1, 0.5)])
    assert light["radius"] == 0.0


def test_the_principled_inputs_follow_the_subsurface():
    twin = _twin()
    spec = twin.twin_spec(_scene(), 4, 3)
    (sphere,) = spec["spheres"]
    assert sphere["specular"] == pytest.approx(0.5)        # F0 = 0.04 at ior 1.5
    assert sphere["subsurface_radius"] == [0.05] * 3
    assert sphere["colour"] == {"kind": "constant", "colour": [0.8, 0.6, 0.4],
                                "mean_colour": [0.8, 0.6, 0.4]}
    assert spec["colour_comparable"] is False              # an albedo, not the colour seen
    assert spec["seed"] == 3 and spec["ambient"] == [0.5, 0.5, 0.5]


def test_a_reflectance_is_taken_as_the_colour_seen():
    # issue 40's `reflectance` (the colour seen, Cycles' Subsurface Color) when the model has
    # it: a stand-in subsurface with one, as the scene model will carry it.
    from types import SimpleNamespace
    from mimarble.scene import model
    twin, scene = _twin(), _scene()
    subsurface = SimpleNamespace(reflectance=model.ColorChannel((0.9, 0.9, 0.9)), albedo=None,
                                 density=None, ior=1.5, mean_free_path=0.05)
    fields = ("planes", "boxes", "meshes", "spheres", "camera", "lights", "image", "ambient")
    stand_in = SimpleNamespace(**{k: getattr(scene, k) for k in fields},
                               materials={"m": SimpleNamespace(subsurface=subsurface)})
    spec = twin.twin_spec(stand_in, 4, 0)
    assert spec["colour_comparable"] is True
    assert spec["spheres"][0]["colour"]["colour"] == [0.9, 0.9, 0.9]


def test_the_matched_radius_gives_cycles_walk_our_mean_free_path():
    twin = _twin()
    (sphere,) = twin.twin_spec(_scene(), 4, 0, radius_rule="matched")["spheres"]
    for colour, radius in zip((0.8, 0.6, 0.4), sphere["subsurface_radius"]):
        alpha = twin.dipole_reduced_albedo(colour, 1.5)
        # Cycles' walk: mean free path = radius·√(3(1 − α′)), α′ the dipole's for the colour.
        assert radius * math.sqrt(3 * (1 - alpha)) == pytest.approx(0.05)
        assert radius > 0.05
    # The dipole's R_d rises with α′: a lighter colour, a higher α′.
    assert twin.dipole_reduced_albedo(0.9, 1.5) > twin.dipole_reduced_albedo(0.5, 1.5)


def test_a_marble_colour_becomes_a_wave_and_a_ramp():
    twin = _twin()
    spec = twin.twin_spec(S.load(ROOT / "scenes" / "translucent" / "fig11a-translucent.scene"),
                          64, 0)
    colour = spec["spheres"][0]["colour"]
    assert colour["kind"] == "wave" and colour["axis"] == "X"
    assert len(colour["stops"]) == twin.RAMP_STOPS
    assert colour["stops"][0][1:] == pytest.approx([0.9, 0.0, 0.0])
    assert colour["stops"][-1][1:] == pytest.approx([0.9, 0.7875, 0.0])


@pytest.mark.parametrize("change, words", [
    ({"light": "light { position < 3 4 0 > area { axis1 < 1 0 0 > axis2 < 0 1 0 > } }"},
     "rectangle"),
    ({"material": "diffuse { color < 1 1 1 > }"}, "no subsurface"),
    ({"material": "subsurface { albedo color < 1 1 1 > density color < 1 1 1 > "
                  "mean_free_path 0.1 }"}, "density"),
])
def test_what_the_twin_cannot_build_is_refused_in_a_sentence(change, words):
    twin = _twin()
    with pytest.raises(twin.Unsupported, match=words):
        twin.twin_spec(_scene(**change), 4, 0)


@pytest.mark.skipif(shutil.which("blender") is None, reason="Blender is not installed")
def test_a_lambertian_twin_renders_what_path_mode_renders(llvm):
    import json
    import subprocess
    import tempfile
    import mimarble
    twin = _twin()
    light = "light { position < -3 4 7 > color < 1 1 1 > }"
    spec = twin.twin_spec(_scene(light=light), 64, 0)
    spec["spheres"][0]["lambertian"] = True
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "spec.json"
        path.write_text(json.dumps(spec))
        out = str(Path(folder) / "out.exr")
        subprocess.run(["blender", "-b", "--factory-startup", "-noaudio", "-P",
                        str(ROOT / "scripts" / "cycles_twin.py"), "--", "--build", str(path),
                        out], check=True, capture_output=True)
        cycles = twin.read_exr(out)
    ours = mimarble.render(_scene(light=light, material="diffuse { color < 0.8 0.6 0.4 > }"),
                           spp=64, mode="path", seed=1)
    assert cycles.shape == ours.shape == (32, 32, 3)
    assert np.mean((cycles.sum(-1) > 0) == (ours.sum(-1) > 0)) > 0.99   # the same silhouette
    assert cycles.mean(axis=(0, 1)) == pytest.approx(ours.mean(axis=(0, 1)), rel=0.03)
