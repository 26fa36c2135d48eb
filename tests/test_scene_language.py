"""The scene language: syntax, lexical rules, and positioned error messages."""

from __future__ import annotations

import pytest

from mimarble.scene import FIG5_RAMP, ColorChannel, MarbleChannel, SceneError, load, parse

# The paper's Fig. 5 listing, character for character, without the prose line
# ("which will set the diffuse component to a constant red.") that the paper
# prints between the two materials, and without the final stray '}'.
FIG5 = """\
material "red" {
  diffuse { color < 1 0 0 > }
}

material "marble" {
  diffuse {
    marble {
      scale 1.0
      period 1.3
      distortion 3
      octaves 12
      ramp {
        < 1.0 0.000 0.0 >
          < 1.0 0.125 0.0 >
          < 1.0 0.250 0.0 >
          < 1.0 0.375 0.0 >
          < 1.0 0.500 0.0 >
          < 1.0 0.625 0.0 >
          < 1.0 0.750 0.0 >
          < 1.0 0.875 0.0 >
        }
      }
    }
  }
"""
# ... and as printed, with the one closing brace too many (line 25).
FIG5_AS_PRINTED = FIG5 + "}\n    \n"


def error(text: str, filename: str = "t.scene") -> SceneError:
    with pytest.raises(SceneError) as info:
        parse(text, filename)
    return info.value


def assert_error_at(text: str, line: int, column: int, fragment: str, filename: str = "t.scene") -> SceneError:
    """The error is at line:column, says `fragment`, and prints the source line and a caret."""
    e = error(text, filename)
    assert (e.line, e.column) == (line, column), str(e)
    assert fragment in e.message, str(e)
    head, src, caret, *hint = str(e).split("\n")
    assert hint == ([f"hint: {e.hint}"] if e.hint else [])     # a POV-Ray habit's hint line
    assert head == f"{filename}:{line}:{column}: {e.message}"
    # The line as written, a character a terminal would act on shown escaped (issue 38).
    shown = "".join(c if c == "\t" or c.isprintable() else repr(c)[1:-1]
                    for c in text.split("\n")[line - 1])
    assert src == shown.expandtabs(8)
    assert caret.endswith("^") and caret.strip() == "^"
    return e


# --------------------------------------------------------------------------
#  The paper's Fig. 5
# --------------------------------------------------------------------------


def test_fig5_parses_verbatim():
    scene = parse(FIG5, "fig5.scene")
    assert list(scene.materials) == ["red", "marble"]
    red, marble = scene.materials["red"], scene.materials["marble"]
    assert red.diffuse == ColorChannel((1.0, 0.0, 0.0))
    assert red.ambient is None and red.specular is None
    assert marble.diffuse == MarbleChannel(scale=1.0, period=1.3, distortion=3.0, octaves=12, ramp=FIG5_RAMP)
    assert marble.diffuse.ramp[-1] == (1.0, 0.875, 0.0)
    assert marble.ambient is None and marble.specular is None


def test_fig5_stray_brace_is_reported_at_its_line():
    e = assert_error_at(FIG5_AS_PRINTED, 25, 1, "unexpected '}': no block is open here", "fig5.scene")
    assert str(e) == "fig5.scene:25:1: unexpected '}': no block is open here\n}\n^"


def test_fig5_with_the_prose_line_points_at_the_prose():
    text = FIG5.replace("}\n\nmaterial", "}\nwhich will set the diffuse component to a constant red.\n\nmaterial")
    assert_error_at(text, 4, 1, "unknown statement 'which'")


# --------------------------------------------------------------------------
#  Lexical rules
# --------------------------------------------------------------------------


def _ambient(text: str):
    return parse(f"ambient {text}").ambient


@pytest.mark.parametrize("vec", ["<1 2 3>", "< 1 2 3 >", "<1,2,3>", "< 1, 2, 3 >", "<1 2,3>", "<\n1\n2\n3\n>"])
def test_vectors_with_and_without_commas(vec):
    assert _ambient(vec) == (1.0, 2.0, 3.0)


def test_minus_sign_belongs_to_the_number():
    assert parse("camera { eye < 1 -2 3 > }").camera.eye == (1.0, -2.0, 3.0)
    assert parse("camera { eye <-1,-2,-3> }").camera.eye == (-1.0, -2.0, -3.0)
    assert parse("camera { eye <+1 -.5 -0.25> }").camera.eye == (1.0, -0.5, -0.25)


@pytest.mark.parametrize(
    "lit, value",
    [("1e-3", 1e-3), ("2.5E+2", 250.0), (".5", 0.5), ("5.", 5.0), ("7", 7.0), ("1E2", 100.0), ("0.125", 0.125)],
)
def test_number_literals(lit, value):
    assert parse(f"material \"m\" {{ shininess {lit} }}").materials["m"].shininess == value


@pytest.mark.parametrize("bad, col", [("1-2", 1), ("1.2.3", 1), ("3abc", 1), ("1e", 1), ("--1", 1)])
def test_malformed_numbers_are_errors(bad, col):
    assert_error_at(f"ambient < 0 0 {bad} >", 1, 14 + col, "malformed number")


def test_line_and_block_comments():
    text = """// leading comment
    /* block
       comment */ ambient /* inside */ < 1 // the red
    2 3 > // trailing
    /* at end of file */"""
    assert parse(text).ambient == (1.0, 2.0, 3.0)


def test_unterminated_block_comment_at_eof():
    assert_error_at("ambient <1 2 3>\n  /* never closed\n\n", 2, 3, "unterminated block comment")


def test_stray_comment_close():
    assert_error_at("ambient <1 2 3> */", 1, 17, "'*/' without a matching '/*'")


def test_empty_file_is_the_default_scene():
    assert parse("") == parse("// nothing\n/* here */\n")
    assert parse("").spheres == ()


def test_statements_in_any_order():
    a = parse('sphere { material "m" } material "m" { } light { position <1 1 1> } ambient <.1 .1 .1>')
    b = parse('ambient <.1 .1 .1> light { position <1 1 1> } material "m" { } sphere { material "m" }')
    assert a == b


def test_crlf_line_endings_and_bom():
    text = "\ufeffambient <1 2 3>\r\nimage { width 10 }\r\n"
    assert parse(text).image.width == 10
    e = error("ambient <1 2 3>\r\nimage { width 0 }\r\n")
    assert (e.line, e.column) == (2, 15) and e.source_line == "image { width 0 }"


# --------------------------------------------------------------------------
#  Syntax errors: translated, positioned, never a Lark exception
# --------------------------------------------------------------------------


def test_unknown_keyword_lists_the_allowed_ones():
    e = assert_error_at("camera {\n  eye <0 0 5>\n  eyes <1 2 3>\n}", 3, 3, "unknown keyword 'eyes' in 'camera' block")
    for kw in ("eye", "lookat", "up", "fov"):
        assert f"'{kw}'" in e.message


def test_keyword_of_another_block():
    assert_error_at("light { position <1 1 1> radius 2 }", 1, 26, "keyword 'radius' is not allowed in 'light' block")


def test_unknown_keyword_in_marble():
    e = assert_error_at('material "m" {\n diffuse { marble { frequency 2 } } }', 2, 21, "unknown keyword 'frequency'")
    assert "'period'" in e.message and "'ramp'" in e.message


def test_unknown_statement():
    assert_error_at("\n\ncone { }", 3, 1, "unknown statement 'cone'")


def test_missing_closing_brace_at_eof_names_the_opening():
    e = assert_error_at("ambient <0 0 0>\nimage {\n  width 10\n", 3, 11, "missing closing '}' for 'image' block opened at 2:1")
    e = error('material "m" {\n  diffuse {\n    marble { scale 2 }\n')
    assert "missing closing '}' for 'diffuse' block opened at 2:3" in e.message


def test_statement_inside_an_unclosed_block_names_where_it_opened():
    e = assert_error_at('material "m" {\n  diffuse { color < 1 0 0 > }\nsphere { material "m" }\n',
                        3, 1, "keyword 'sphere' is not allowed in material \"m\"")
    assert e.message.endswith("(is the '}' of material \"m\", opened at 1:1, missing?)")


def test_key_of_the_enclosing_block_names_the_unclosed_channel_block():
    e = assert_error_at('material "m" { diffuse { add { color < 1 0 0 > color < 0 1 0 >\n'
                        'specular { color < 1 1 1 > } }\n', 2, 1, "unexpected keyword 'specular'")
    assert "(is the '}' of the 'add' block, opened at 1:26, missing?)" in e.message
    e = assert_error_at('material "m" {\n  diffuse { marble { }\n  specular { color < 1 1 1 > }\n}',
                        3, 3, "expected '}' to close 'diffuse' block opened at 2:3")
    assert "exactly one channel" not in e.message


def test_keyword_that_no_enclosing_block_takes_gets_no_unclosed_note():
    e = error("light { position <1 1 1> radius 2 }")
    assert "missing?" not in e.message


@pytest.mark.parametrize("text, column, hint", [
    ('material "m" { diffuse { color (1, 0, 0) } }', 32, "color < 1 0 0 > or color #ff0000"),
    ("image { background [0 0 0] }", 20, "background < 1 0 0 > or background #ff0000"),
    ("camera { eye (0 0 5) }", 14, "a vector as < x y z >, e.g. eye < 0 0 1 >"),
])
def test_brackets_say_how_colours_and_vectors_are_written(text, column, hint):
    e = assert_error_at(text, 1, column, hint)
    assert "the language has no" in e.message


def test_word_where_a_colour_goes_says_how_to_write_one():
    assert_error_at('material "m" { diffuse { color rgb(1, 0, 0) } }', 1, 32,
                    "expected a colour '< r g b >' or '#rrggbb' after 'color', found 'rgb'")


def test_unexpected_closing_brace_after_a_block():
    assert_error_at("image { width 10 }\n  }\n", 2, 3, "unexpected '}': no block is open here")


def test_expected_a_number():
    assert_error_at("image { width big }", 1, 15, "expected a number after 'width'")


def test_vector_not_closed():
    assert_error_at("ambient < 1 2 3 }", 1, 17, "expected a number or '>'")


def test_expected_a_vector():
    assert_error_at("camera { eye 1 2 3 }", 1, 14, "expected a vector")


def test_material_name_must_be_quoted():
    assert_error_at("material marble { }", 1, 10, "expected a quoted material name")


def test_unterminated_string():
    assert_error_at('sphere { material "m\n}', 1, 19, "unterminated string")


def test_channel_block_takes_exactly_one_channel():
    assert_error_at('material "m" { diffuse { } }', 1, 26, "empty 'diffuse' block")
    assert_error_at(
        'material "m" { diffuse { color <1 0 0> marble { } } }', 1, 40, "expected '}' to close 'diffuse' block"
    )


def test_unexpected_character():
    assert_error_at("ambient <1 2 3> @", 1, 17, "unexpected character '@'")
    assert_error_at("ambient <1 2 3> \x00", 1, 17, "unexpected character U+0000")


def test_tabs_caret_lines_up():
    e = error("image {\n\twidth\t0 }")
    assert (e.line, e.column) == (2, 8)
    _, src, caret = str(e).split("\n")
    assert src == "        width   0 }"
    assert caret == " " * 16 + "^"
    assert src[len(caret) - 1] == "0"


def test_no_lark_exception_escapes():
    import lark

    for text in ["{", "}", "<", ">", "image image", 'material "a" "b"', "sphere { center < > }", "\x7f", "ramp"]:
        try:
            parse(text)
        except SceneError:
            pass
        except lark.exceptions.LarkError as e:  # pragma: no cover
            pytest.fail(f"lark exception escaped for {text!r}: {e!r}")


# --------------------------------------------------------------------------
#  Files
# --------------------------------------------------------------------------


def test_missing_file_is_a_scene_error(tmp_path):
    path = tmp_path / "nope.scene"
    with pytest.raises(SceneError) as info:
        load(path)
    assert str(info.value) == f"{path}: cannot read scene file: no such file (looked for {path})"
    assert info.value.line is None


def test_directory_is_a_scene_error(tmp_path):
    with pytest.raises(SceneError, match="cannot read scene file"):
        load(tmp_path)


def test_non_utf8_bytes_are_positioned(tmp_path):
    path = tmp_path / "latin1.scene"
    path.write_bytes('ambient <0 0 0>\nmaterial "caf\xe9" { }\n'.encode("latin-1"))
    with pytest.raises(SceneError) as info:
        load(path)
    e = info.value
    assert (e.filename, e.line, e.column) == (str(path), 2, 14)
    assert "invalid UTF-8 byte 0xe9" in e.message
    assert str(e).splitlines()[2] == " " * 13 + "^"


def test_load_reads_utf8_and_records_source(tmp_path):
    path = tmp_path / "ok.scene"
    path.write_text('// café\nmaterial "m" { }\nsphere { material "m" }\n', encoding="utf-8")
    scene = load(path)
    assert scene.source == str(path)
    assert scene.spheres[0].pos == (3, 1)


def test_error_message_uses_the_given_filename():
    e = error("image { width 0 }", filename="scenes/x.scene")
    assert str(e).startswith("scenes/x.scene:1:15: width must be in 1..16384")
    assert error("image { width 0 }", filename="<string>").filename == "<string>"
