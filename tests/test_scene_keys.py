"""The registry of a scene's keys (mimarble/scene/keys.py): named textures, ramps and their
stops, the camera's vectors, light positions; the unknown key's sentence; ``mimarble sweep
--keys``. Expected scenes are written by hand as text and parsed: the parser, not the
registry, says what the edited scene is."""

import pytest

from mimarble import parameters
from mimarble.parameters import hex_colour
from mimarble.scene import parse
from mimarble.scene.keys import KeyPathError, key_of, keys_listing, scene_keys, with_value
from mimarble.sweeps.settings import parse_setting

from commands import mimarble_cli

# A texture used by two materials, one inline marble, one light.
TEXT = """
image { width 8 height 8 }
texture "carrara" { marble { period 1.3 ramp { < 1 1 1 > < 0.5 0.5 0.5 > < 0 0 0 > } } }
material "stone" { diffuse { texture "carrara" } }
material "vase" { ambient { color < 0.1 0.1 0.1 > }
                  diffuse { mix { texture "carrara" marble { scale 2 } weight 0.5 } } }
light { position < 1 2 3 > }
sphere { material "stone" }
sphere { center < 2 0 0 > material "vase" }
"""


def scene_with(old: str, new: str, text: str = TEXT):
    """The scene of ``text`` with ``old`` written ``new`` (once)."""
    assert text.count(old) == 1, old
    return parse(text.replace(old, new))


def test_a_named_texture_is_a_key_and_changes_every_use():
    scene = parse(TEXT)
    edited = with_value(scene, "carrara.period", 2.5)
    assert edited == scene_with("period 1.3", "period 2.5")
    assert edited.materials["stone"].diffuse.period == 2.5
    assert edited.materials["vase"].diffuse.a.period == 2.5
    assert edited.materials["vase"].diffuse.b.period == 1.0     # the inline marble: not carrara


def test_every_marble_one_material_and_one_channel():
    scene = parse(TEXT)
    every = with_value(scene, "marble.distortion", 4)
    assert every == parse(TEXT.replace("marble { period 1.3", "marble { distortion 4 period 1.3")
                          .replace("marble { scale 2", "marble { scale 2 distortion 4"))
    vase = with_value(scene, "vase.diffuse.octaves", 3).materials["vase"].diffuse
    assert vase.a.octaves == vase.b.octaves == 3
    assert with_value(scene, "vase.octaves", 3).materials["stone"].diffuse.octaves == 8


def test_keys_carry_their_row_of_the_parameter_table_and_their_value():
    keys = scene_keys(parse(TEXT))
    period = keys["carrara.period"]
    assert period.parameter is parameters.BY_NAME["period"]
    assert (period.value, period.text, period.group) == (1.3, "1.3", 'texture "carrara"')
    assert keys["marble.octaves"].parameter.bounds == (0, parameters.MAX_OCTAVES)
    assert keys["marble.function"].parameter.choices == parameters.FUNCTIONS
    assert keys["marble.scale"].count == 2
    assert keys["carrara.ramp.1"].value == (None, (0.5, 0.5, 0.5))
    assert keys["carrara.ramp"].value == (((1.0,) * 3, (0.5,) * 3, (0.0,) * 3), None)
    assert keys["light.0.position"].value == (1.0, 2.0, 3.0)
    assert keys["camera.eye"].parameter.requirement == "must be three finite numbers 'x y z'"
    assert (keys["camera.fov"].parameter.above, keys["camera.fov"].parameter.below) == (0, 180)
    assert "vase.ambient.period" not in keys          # a colour has no marble keys
    groups = list(dict.fromkeys(k.group for k in keys.values()))
    assert groups == ["every marble", 'texture "carrara"', 'material "stone"',
                      'material "stone", diffuse', 'material "vase"', 'material "vase", diffuse',
                      "camera", "light 0", "image"]


def test_a_ramp_stop_takes_a_colour_and_maybe_a_position():
    scene = parse(TEXT)
    assert with_value(scene, "carrara.ramp.1", "#d0d0d0") == \
        scene_with("< 0.5 0.5 0.5 >", "#d0d0d0")
    assert with_value(scene, "carrara.ramp.1", "0.25 0.5 0.5 0.5") == scene_with(
        "ramp { < 1 1 1 > < 0.5 0.5 0.5 > < 0 0 0 > }",
        "ramp { 0 < 1 1 1 > 0.25 < 0.5 0.5 0.5 > 1 < 0 0 0 > }")
    edited = with_value(scene, "carrara.ramp.2", "#ffffff")
    assert edited.textures["carrara"].ramp[2] == hex_colour("#ffffff") == (1.0, 1.0, 1.0)
    for value, words in (("#12345", "#rrggbb"), ("1.5 #000000", r"in \[0, 1\]"),
                         ("-1 0 0", ">= 0"), ("1 2", "is not a colour")):
        with pytest.raises(KeyPathError, match="^carrara.ramp.1: .*" + words):
            with_value(scene, "carrara.ramp.1", value)
    with pytest.raises(KeyPathError, match="^carrara.ramp.0: .*must not decrease"):
        with_value(scene, "carrara.ramp.0", "0.9 #000000")      # past stop 1's 0.5
    with pytest.raises(KeyPathError, match=r"^carrara.ramp.3: unknown key .*carrara\.K"):
        with_value(scene, "carrara.ramp.3", "#ffffff")


def test_a_whole_ramp_is_a_ramp_string():
    scene = parse(TEXT)
    assert with_value(scene, "carrara.ramp", "#ffffff, 0.2 0.2 0.2") == scene_with(
        "ramp { < 1 1 1 > < 0.5 0.5 0.5 > < 0 0 0 > }", "ramp { #ffffff < 0.2 0.2 0.2 > }")
    assert with_value(scene, "carrara.ramp", "0 #ffffff, 1 #000000") == scene_with(
        "ramp { < 1 1 1 > < 0.5 0.5 0.5 > < 0 0 0 > }", "ramp { 0 #ffffff 1 #000000 }")
    with pytest.raises(KeyPathError, match="^carrara.ramp: .*position"):
        with_value(scene, "carrara.ramp", "0 #ffffff, #000000")


def test_camera_vectors_and_light_positions():
    scene = parse(TEXT)
    assert with_value(scene, "camera.eye", "< 0 1 12 >").camera.eye == (0.0, 1.0, 12.0)
    assert with_value(scene, "camera.lookat", (0, 0.5, 0)).camera.lookat == (0.0, 0.5, 0.0)
    assert with_value(scene, "light.0.position", "4 5 6") == \
        scene_with("position < 1 2 3 >", "position < 4 5 6 >")
    assert with_value(scene, "light.0.color", "#808080").lights[0].color == hex_colour("#808080")
    with pytest.raises(KeyPathError, match="^camera.up: .*parallel"):
        with_value(scene, "camera.up", "0 0 1")
    with pytest.raises(KeyPathError, match="^camera.eye: .* is not a vector"):
        with_value(scene, "camera.eye", "1 2")
    with pytest.raises(KeyPathError, match="^light.0.position: .* is not a number"):
        with_value(scene, "light.0.position", "1 nan 2")


def test_an_unknown_key_lists_the_scene_keys_grouped_in_one_sentence():
    with pytest.raises(KeyPathError) as info:
        key_of(parse(TEXT), "carrara.peroid")
    said = str(info.value)
    assert "\n" not in said and said.startswith("carrara.peroid: unknown key (did you mean "
                                                "carrara.period?)")
    for words in ("marble.K", "texture carrara.K", "material stone.K, stone.diffuse.K",
                  "ramp.N", "camera.fov|eye|lookat|up", "light.N.intensity|color|position",
                  "image.samples"):
        assert words in said, words
    with pytest.raises(KeyPathError, match="^granite.period: no material or texture 'granite'"):
        key_of(parse(TEXT), "granite.period")


def test_a_name_that_is_a_material_and_a_texture_or_a_reserved_word_is_written_in_full():
    scene = parse('texture "m" { marble { } } material "m" { diffuse { texture "m" } }\n'
                  'material "camera" { diffuse { marble { scale 3 } } }')
    keys = scene_keys(scene)
    assert "texture.m.scale" in keys and keys["m.scale"].group == 'material "m"'
    assert keys["material.camera.scale"].value == 3.0


def test_sweep_settings_take_ramps_and_name_stops():
    whole = parse_setting("marble.ramp=#ffffff, #000000;#ff0000, #000000")
    assert whole.values == ("#ffffff, #000000", "#ff0000, #000000")
    stop = parse_setting("marble.ramp.2=#ffffff,#d0d0d0")
    assert stop.values == ("#ffffff", "#d0d0d0") and stop.name == "ramp.2"


def test_sweep_keys_prints_them_and_an_unknown_key_is_one_line(tmp_path):
    (tmp_path / "s.scene").write_text(TEXT)
    done = mimarble_cli("sweep", "--keys", "s.scene", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == keys_listing(parse(TEXT)).splitlines()
    assert 'texture "carrara"' in done.stdout and "carrara.ramp.2" in done.stdout
    bad = mimarble_cli("sweep", "s.scene", "--set", "carrara.peroid=1,2", "-o", "out",
                       cwd=tmp_path)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
    assert "did you mean carrara.period" in bad.stderr and not (tmp_path / "out").exists()


def test_a_sweep_of_a_texture_and_a_ramp_stop_renders_each_frame_as_its_scene(llvm, tmp_path):
    """Each frame is the image of the scene written by hand with that frame's values,
    rendered on its own, bit for bit."""
    import numpy as np
    from PIL import Image

    import mimarble
    from mimarble.mitsuba.rendering.image_output import srgb8
    index = mimarble.sweep(parse(TEXT), {"carrara.period": [1.3, 2.0],
                                         "carrara.ramp.1": ["#d0d0d0"]}, tmp_path, spp=1)
    assert [f["status"] for f in index["frames"]] == ["done"] * 2
    for frame, period in zip(index["frames"], ("1.3", "2.0")):
        text = TEXT.replace("period 1.3", f"period {period}").replace("< 0.5 0.5 0.5 >",
                                                                      "#d0d0d0")
        alone = mimarble.render(parse(text), spp=1)
        image = np.asarray(Image.open(tmp_path / frame["file"]).convert("RGB"))
        assert np.array_equal(image, srgb8(alone))
