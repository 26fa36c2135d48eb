"""Channel expressions and image maps in the scene language: parsing, and errors at
FILE:LINE:COL."""

import pytest

from mimarble.scene import (Add, ColorChannel, ImageChannel, MarbleChannel, Mix, Multiply,
                            SceneError, parse)


@pytest.fixture
def image(tmp_path):
    from PIL import Image
    (tmp_path / "maps").mkdir()
    Image.new("RGB", (4, 2), (200, 100, 50)).save(tmp_path / "maps" / "x.png")
    return tmp_path


def diffuse(body: str) -> str:
    return 'material "m" {\n  diffuse { ' + body + ' }\n}\n'


def parsed(text, folder):
    return parse(text, str(folder / "t.scene"), source=str(folder / "t.scene")).materials["m"].diffuse


def test_expressions_nest_to_any_depth(image):
    channel = parsed(diffuse('mix { image { file "maps/x.png" } multiply { color <1 .95 .9> '
                             'add { marble { } color <0 0 .1> } } weight marble { octaves 2 } }'),
                     image)
    assert isinstance(channel, Mix) and isinstance(channel.b, Multiply)
    assert channel.a == ImageChannel("maps/x.png", str(image / "maps" / "x.png"))
    assert channel.b.operands[1] == Add((MarbleChannel(), ColorChannel((0.0, 0.0, 0.1))))
    assert channel.weight == MarbleChannel(octaves=2)


def test_a_number_is_a_constant_weight(tmp_path):
    channel = parsed(diffuse("mix { color <1 0 0> color <0 0 1> weight 0.25 }"), tmp_path)
    assert channel == Mix(ColorChannel((1.0, 0.0, 0.0)), ColorChannel((0.0, 0.0, 1.0)), 0.25)


def test_python_built_expressions_equal_parsed_ones(tmp_path):
    built = Multiply((ColorChannel((1, 0.95, 0.9)), MarbleChannel(octaves=3)))
    assert parsed(diffuse("multiply { color <1 .95 .9> marble { octaves 3 } }"), tmp_path) == built
    with pytest.raises(ValueError, match="two or more"):
        Add((ColorChannel((1, 1, 1)),))
    with pytest.raises(TypeError, match="weight"):
        Mix(ColorChannel((1, 1, 1)), ColorChannel((0, 0, 0)), "half")


@pytest.mark.parametrize("body, column, words", [
    ("add { color <1 0 0> }", 13, "'add' needs two or more channels, found 1"),
    ("multiply { }", 13, "'multiply' needs two or more channels, found 0"),
    ("add { color <1 0 0> color <0 1 0> weight 0.5 }", 47, "'weight' belongs in a mix block"),
    ("weight 0.5", 13, "'weight' belongs in a mix block"),
    ("mix { color <1 0 0> color <0 1 0> }", 13, "mix has no 'weight'"),
    ("mix { color <1 0 0> color <0 1 0> color <0 0 1> weight 1 }", 47, "exactly two channels"),
    ("mix { weight 0.5 color <1 0 0> color <0 1 0> }", 19, "'weight' comes last"),
    ("blend { color <1 0 0> }", 13, "unknown channel 'blend'"),
    ("add { blend { } }", 19, "unknown channel 'blend'"),
    ("image { }", 13, "image channel has no 'file'"),
    ('image { file "maps/none.png" }', 26, "no such file"),
    ('image { file "t.scene" }', 26, "not a PNG or JPEG"),
])
def test_channel_errors_point_at_file_line_column(tmp_path, body, column, words):
    (tmp_path / "t.scene").write_text("not an image")
    with pytest.raises(SceneError) as info:
        parse(diffuse(body), str(tmp_path / "t.scene"), source=str(tmp_path / "t.scene"))
    e = info.value
    assert (e.line, e.column) == (2, column) and words in e.message, str(e)


def test_a_sixteen_bit_png_is_refused_at_its_file_string(tmp_path):
    from PIL import Image
    Image.new("I;16", (2, 2)).save(tmp_path / "deep.png")
    with pytest.raises(Exception, match="16-bit PNG"):
        parsed(diffuse('image { file "deep.png" }'), tmp_path)
