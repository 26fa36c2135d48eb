"""Block comments nest, as POV-Ray's do; every token keeps its line and column."""

import pytest

from mimarble import scene as S


def error(text) -> S.SceneError:
    with pytest.raises(S.SceneError) as e:
        S.parse(text, filename="c.scene")
    return e.value


def test_a_nested_block_comment_is_one_comment():
    assert S.parse("/* a /* b */ c */ ambient < 1 2 3 >").ambient == (1.0, 2.0, 3.0)
    assert S.parse("/* 1 /* 2 /* 3 */ 2 */ 1 */ ambient < 1 2 3 > /**/").ambient == (1.0, 2.0, 3.0)


def test_a_block_of_scene_holding_a_comment_can_be_commented_out():
    text = """/*
    light { position < 1 2 3 > /* the key light */ }
    */
    ambient < 0.5 0.5 0.5 >"""
    scene = S.parse(text)
    assert scene.lights == () and scene.ambient == (0.5, 0.5, 0.5)


def test_an_unclosed_nested_comment_is_an_error_at_its_opening():
    e = error("ambient < 1 1 1 >\n  /* a /* b */ c\n")
    assert (e.line, e.column) == (2, 3)
    assert e.message == ("unterminated block comment: '/*' has no matching '*/' (block comments "
                         "nest: the '/*' at 2:8 inside it opens one of its own, which the next "
                         "'*/' closes)")
    assert str(e).split("\n")[1:] == ["  /* a /* b */ c", "  ^"]


def test_the_outermost_open_comment_is_the_one_named():
    assert (error("/* a /* b").line, error("/* a /* b").column) == (1, 1)
    e = error("/* closed */ ambient <1 1 1> /* open /* also */")
    assert e.column == 30


def test_tokens_after_comments_keep_their_line_and_column():
    e = error("/* one\n /* two */\n */ camera { eyes < 1 2 3 > } // eyes\n")
    assert (e.line, e.column) == (3, 14) and "unknown keyword 'eyes'" in e.message


def test_line_comments_and_strings_hold_no_block_comment():
    assert S.parse("// a /* here\nambient < 1 2 3 >").ambient == (1.0, 2.0, 3.0)
    scene = S.parse('material "a/*b" { } // */\nmaterial "c//d" { }')
    assert list(scene.materials) == ["a/*b", "c//d"]


def test_inside_a_block_comment_only_its_delimiters_count():
    assert S.parse('/* // */ ambient < 1 2 3 > /* " */').ambient == (1.0, 2.0, 3.0)


def test_a_stray_comment_close_is_still_an_error_at_its_place():
    e = error("/* a */ ambient <1 2 3> */")
    assert (e.line, e.column, e.message) == (1, 25, "'*/' without a matching '/*'")
