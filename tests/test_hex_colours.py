"""Colours written #rrggbb: sRGB-encoded, decoded to linear, the same in the marble plugin,
the scene language, the scene model and both renderers (issue 28, item 7)."""

import numpy as np
import pytest

import mimarble
from mimarble.parameters import MarbleParameters, ParameterError, hex_colour, parse_ramp
from mimarble.mitsuba.translate.scene_dict import texture_dict
from mimarble.reference.channels import channel_color
from mimarble.scene import ColorChannel, MarbleChannel, SceneError, parse

dr, mi = mimarble.dr, mimarble.mi


def iec_61966_2_1(byte: int) -> float:
    """The sRGB decoding of IEC 61966-2-1, written out here, independent of the package."""
    c = byte / 255
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def marble_of(text: str) -> MarbleChannel:
    return parse(text).materials["m"].diffuse


def test_808080_is_srgb_0_2159_not_linear_0_502():
    value = hex_colour("#808080")
    assert value == (iec_61966_2_1(128),) * 3
    assert value[0] == pytest.approx(0.21586, abs=1e-5)


def test_every_byte_decodes_by_the_iec_formula_in_either_case():
    for byte in (0, 1, 10, 11, 12, 100, 128, 200, 254, 255):   # both sides of the 0.04045 knee
        code = f"{byte:02x}"
        assert hex_colour(f"#{code}0000")[0] == iec_61966_2_1(byte)
        assert hex_colour(f"#0000{code.upper()}")[2] == iec_61966_2_1(byte)
    assert hex_colour("#000000") == (0.0, 0.0, 0.0) and hex_colour("#ffffff") == (1.0, 1.0, 1.0)


def test_language_and_plugin_read_the_same_ramp():
    ramp = "#808080, 1 0.5 0, #FF8000"
    plugin = MarbleParameters.from_properties({"ramp": ramp}).ramp
    language = marble_of('material "m" { diffuse { marble { ramp { #808080 < 1 0.5 0 > '
                         '#FF8000 } } } }').ramp
    assert language == plugin == parse_ramp(ramp)
    assert language[2] == (1.0, iec_61966_2_1(128), 0.0)


def test_plugin_texture_holds_the_decoded_ramp(llvm):
    texture = mi.load_dict({"type": "marble", "ramp": "#808080, #ffffff"})
    ramp = np.array([np.asarray(mi.traverse(texture)["ramp"][k]) for k in range(3)]).T
    np.testing.assert_allclose(ramp, [[iec_61966_2_1(128)] * 3, [1, 1, 1]], rtol=1e-7)


def test_translated_scene_marble_gets_the_decoded_numbers():
    channel = marble_of('material "m" { diffuse { marble { ramp { #808080 } } } }')
    assert parse_ramp(texture_dict(channel)["ramp"]) == ((iec_61966_2_1(128),) * 3,)


@pytest.mark.parametrize("text, read", [
    ("ambient #808080", lambda s: s.ambient),
    ("image { background #808080 }", lambda s: s.image.background),
    ("light { position < 1 1 1 > color #808080 }", lambda s: s.lights[0].color),
    ('material "m" { diffuse { color #808080 } }', lambda s: s.materials["m"].diffuse.rgb),
    ('material "m" { diffuse { marble { ramp { #808080 } } } }',
     lambda s: s.materials["m"].diffuse.ramp[0]),
])
def test_hex_is_taken_wherever_a_colour_goes(text, read):
    assert read(parse(text)) == (iec_61966_2_1(128),) * 3


def test_reference_tracer_reads_the_decoded_colour():
    channel = parse('material "m" { diffuse { color #808080 } }').materials["m"].diffuse
    assert channel == ColorChannel((iec_61966_2_1(128),) * 3)
    np.testing.assert_array_equal(channel_color(channel, np.zeros((2, 3))),
                                  np.full((2, 3), iec_61966_2_1(128)))


def test_marble_channel_built_with_a_ramp_string_decodes_hex_as_the_plugin():
    assert MarbleChannel(ramp="#808080, 1 0 0").ramp == parse_ramp("#808080, 1 0 0")


@pytest.mark.parametrize("text, column", [
    ("ambient #12345", 9),
    ("ambient #ggg000", 9),
    ("ambient #fff", 9),
    ("ambient #ff00001", 9),
    ('material "m" { diffuse { marble { ramp { < 1 0 0 > #12345 } } } }', 52),
    ("ambient #ff0000.5", 9),
])
def test_bad_hex_is_an_error_at_its_file_line_column(text, column):
    with pytest.raises(SceneError) as info:
        parse("\n" + text, "t.scene")
    e = info.value
    assert (e.line, e.column) == (2, column), str(e)
    assert str(e).startswith(f"t.scene:2:{column}: colour '#")
    assert "#rrggbb (six hexadecimal digits" in e.message and "< r g b >" in e.message


def test_hash_comment_is_refused_saying_how_comments_are_written():
    with pytest.raises(SceneError) as info:
        parse("# a note\n", "t.scene")
    assert (info.value.line, info.value.column) == (1, 1)
    assert "comments are // … or /* … */" in info.value.message


def test_hex_is_refused_where_a_point_goes():
    with pytest.raises(SceneError) as info:
        parse("camera { eye #ff0000 }", "t.scene")
    assert (info.value.line, info.value.column) == (1, 14)
    assert "< x y z >" in info.value.message and "not points" in info.value.message


@pytest.mark.parametrize("ramp", ["#12345", "#ggg000", "1 0 0, #fff", "#-1-1-1", "#+f+f+f"])
def test_plugin_refuses_bad_hex_items_naming_them(ramp):
    with pytest.raises(ParameterError, match="is not #rrggbb"):
        MarbleParameters.from_properties({"ramp": ramp})
