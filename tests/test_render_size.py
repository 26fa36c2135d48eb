"""``mimarble.render(..., width=, height=)``: the command line's --width/--height from Python."""

import numpy as np
import pytest

import mimarble
from mimarble.cli import main as cli
from mimarble.scene.edits import with_image_size

SCENE = "scenes/fig10a.scene"


def test_width_and_height_give_the_image_the_command_line_renders(llvm):
    image = mimarble.render(SCENE, width=12, height=8, spp=1)
    assert image.shape == (8, 12, 3)
    args = cli.build_parser().parse_args(["render", SCENE, "--width", "12", "--height", "8"])
    expected = mimarble.render(cli.load_scene(args), spp=1)
    assert np.array_equal(image, expected)


def test_one_of_them_keeps_the_scenes_other_side(llvm):
    scene = mimarble.scene.load(SCENE)
    image = mimarble.render(scene, height=10, spp=1)
    assert image.shape == (10, scene.image.width, 3)
    assert np.array_equal(image, mimarble.render(with_image_size(scene, height=10), spp=1))


@pytest.mark.parametrize("size, error, words", [
    ({"width": 0}, ValueError, "render: width must be in 1..16384, found 0"),
    ({"height": 16385}, ValueError, "render: height must be in 1..16384"),
    ({"width": True}, TypeError, "render: width must be an integer"),
    ({"width": "64"}, TypeError, "render: width must be an integer"),
    ({"width": 8.5}, ValueError, "render: width must be an integer"),
])
def test_a_size_out_of_the_rules_is_one_sentence(size, error, words):
    with pytest.raises(error) as info:
        mimarble.render(SCENE, **size)
    assert str(info.value).startswith(words)


def test_a_loaded_mitsuba_scene_keeps_its_films_size(llvm):
    loaded = mimarble.mi.load_dict(mimarble.to_mitsuba(mimarble.scene.load(SCENE)))
    with pytest.raises(ValueError, match="film's size"):
        mimarble.render(loaded, width=16)
