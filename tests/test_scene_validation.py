"""Validation after parsing: every check reports FILE:LINE:COL at the offending token."""

from __future__ import annotations

import pytest

from mimarble.scene import SceneError, parse
from mimarble.scene.errors import SHOWN_WIDTH

GOOD_MATERIAL = 'material "m" { diffuse { color < 1 1 1 > } }\n'


def check(text: str, line: int, column: int, fragment: str) -> SceneError:
    with pytest.raises(SceneError) as info:
        parse(text, "v.scene")
    e = info.value
    assert (e.line, e.column) == (line, column), str(e)
    assert fragment in e.message, str(e)
    head, src, caret = str(e).split("\n")
    assert head.startswith(f"v.scene:{line}:{column}: ")
    whole = text.split("\n")[line - 1]
    assert caret.endswith("^") and not caret[:-1].strip()
    if len(whole) <= SHOWN_WIDTH:
        assert src == whole
        assert len(caret) == column
    else:                       # a window around the column, the caret under its character
        assert len(src) <= SHOWN_WIDTH + 6 and src.strip(".") in whole
        if column <= len(whole):
            assert src[len(caret) - 1] == whole[column - 1]
    return e


@pytest.mark.parametrize(
    "text, line, col, fragment",
    [
        # duplicates
        ("sphere { radius 1 radius 2 material \"m\" }\n" + GOOD_MATERIAL, 1, 19, "duplicate 'radius' in 'sphere' block (first given at 1:10)"),
        ('material "m" {\n  shininess 2\n  shininess 3\n}', 3, 3, "duplicate 'shininess'"),
        ('material "m" { diffuse { marble { octaves 2 octaves 3 } } }', 1, 45, "duplicate 'octaves' in 'marble' block"),
        ("camera { }\ncamera { }", 2, 1, "duplicate 'camera' statement (first given at 1:1)"),
        ("image { }\nimage { }", 2, 1, "duplicate 'image' statement"),
        ("ambient <0 0 0>\nambient <1 1 1>", 2, 1, "duplicate 'ambient' statement"),
        ('material "m" { }\nmaterial "m" { }', 2, 10, 'duplicate material "m" (first defined at 1:10)'),
        # references
        ('material "a" { }\nsphere { material "b" }', 2, 19, 'unknown material "b" (defined: "a")'),
        ('sphere { material "b" }', 1, 19, "(defined: none)"),
        ("sphere { radius 1 }", 1, 1, "sphere has no 'material'"),
        ('material "" { }', 1, 10, "material name must not be empty"),
        # arity
        ("ambient < 1 2 >", 1, 9, "needs 3 numbers, found 2"),
        ("camera { eye < 1 2 3 4 > }", 1, 14, "eye needs 3 numbers, found 4"),
        ("light { position < > }", 1, 18, "position needs 3 numbers, found 0"),
        ('material "m" { diffuse { marble { ramp { <1 0 0> <1 1> } } } }', 1, 50, "needs 3 numbers, found 2"),
        # non-finite and too large
        ("image { background < 0 1e999 0 > }", 1, 24, "number 1e999 is not finite"),
        ("camera { eye < 0 0 -1e400 > }", 1, 20, "not finite"),
        ("sphere { center < 4e38 0 0 > material \"m\" }\n" + GOOD_MATERIAL, 1, 19, "too large"),
        # colours
        ("ambient < 0 -0.1 0 >", 1, 13, "colour components must be >= 0, found -0.1"),
        ("light { position <0 0 0> color <1 1 -1> }", 1, 37, "colour components must be >= 0"),
        ('material "m" { specular { color < -1 0 0 > } }', 1, 35, "colour components must be >= 0"),
        ('material "m" { diffuse { marble { ramp { <1 0 0> <0 -1 0> } } } }', 1, 53, "ramp colour"),
        # image
        ("image { width 0 }", 1, 15, "width must be in 1..16384, found 0"),
        ("image { height 16385 }", 1, 16, "height must be in 1..16384"),
        ("image { width 10.5 }", 1, 15, "width must be an integer"),
        ("image { samples 0 }", 1, 17, "samples must be in 1.."),
        ("image { width 16384 height 16384 samples 4 }", 1, 34, "image too large"),
        ("image { width 16384\n height 16385 }", 2, 9, "height must be in 1..16384"),
        # camera
        ("camera { fov 0 }", 1, 14, "fov must be in (0, 180)"),
        ("camera { fov 180 }", 1, 14, "fov must be in (0, 180)"),
        ("camera { fov -30 }", 1, 14, "fov must be in (0, 180)"),
        ("camera { eye <1 2 3> lookat <1 2 3> }", 1, 22, "eye and lookat must be different points"),
        ("camera { eye <0 0 0> }", 1, 10, "eye and lookat must be different points"),
        ("camera { up <0 0 -3> }", 1, 10, "'up' must not be zero or parallel"),
        ("camera { up <0 0 0> }", 1, 10, "'up' must not be zero or parallel"),
        ("camera {\n eye <1 1 1> lookat <2 2 2> up <3 3 3> }", 2, 29, "parallel"),
        # light
        ("light { color <1 1 1> }", 1, 1, "light has no 'position'"),
        # sphere
        ("sphere { radius 0 material \"m\" }\n" + GOOD_MATERIAL, 1, 17, "radius must be > 0, found 0"),
        ("sphere { radius -1 material \"m\" }\n" + GOOD_MATERIAL, 1, 17, "radius must be > 0"),
        # material
        ('material "m" { shininess 0 }', 1, 26, "shininess must be > 0"),
        # marble
        ('material "m" { diffuse { marble { octaves 2.5 } } }', 1, 43, "octaves must be an integer"),
        ('material "m" { diffuse { marble { octaves 65 } } }', 1, 43, "octaves must be in 0..64"),
        ('material "m" { diffuse { marble { octaves -1 } } }', 1, 43, "octaves must be in 0..64"),
        ('material "m" { diffuse { marble { scale 0 } } }', 1, 41, "scale must be > 0"),
        ('material "m" { diffuse { marble { scale -2 } } }', 1, 41, "scale must be > 0"),
        ('material "m" { diffuse { marble { period 1e309 } } }', 1, 42, "not finite"),
        ('material "m" { diffuse { marble { function tan } } }', 1, 44, "function must be one of abs_sine, sine, cosine, triangle or sawtooth, found tan"),
        ('material "m" { diffuse { marble { axis w } } }', 1, 40, "axis must be one of x, y or z, found w"),
        ('material "m" { diffuse { marble { turbulence yes } } }', 1, 46, "turbulence must be true or false, found yes"),
        ('material "m" { diffuse { marble { function 3 } } }', 1, 44, "function must be one of abs_sine, sine, cosine, triangle or sawtooth, found number 3"),
        ('material "m" { diffuse { marble {\n ramp { } } } }', 2, 2, "ramp is empty"),
        ('material "m" { diffuse { marble { filter x } } }', 1, 42, "filter must be one of none, bandlimit or prefilter, found x"),
        ('material "m" { diffuse { marble { axis 1 } } }', 1, 40, "axis must be one of x, y or z, found number 1"),
        ('material "m" { diffuse { marble { tolerance -1 } } }', 1, 45, "tolerance must be ≥ 0, found -1"),
        ('material "m" { diffuse { marble { tolerance 4e38 } } }', 1, 45, "too large"),
        ('material "m" { diffuse { marble { bandlimit true } } }', 1, 35, "(it is now 'filter bandlimit'; filter must be one of"),
    ],
)
def test_validation_error_is_positioned(text, line, col, fragment):
    check(text, line, col, fragment)


def test_ramp_of_257_colours_points_at_the_extra_one():
    ramp = " ".join("<1 1 1>" for _ in range(257))
    text = f'material "m" {{ diffuse {{ marble {{ ramp {{ {ramp} }} }} }} }}'
    col = text.index("<1 1 1>") + 1 + 256 * len("<1 1 1> ")
    check(text, 1, col, "ramp has 257 colours; it holds 1..256")


def test_ramp_limits_are_inclusive():
    for k in (2, 256):
        ramp = " ".join("<1 1 1>" for _ in range(k))
        m = parse(f'material "m" {{ diffuse {{ marble {{ ramp {{ {ramp} }} }} }} }}').materials["m"]
        assert len(m.diffuse.ramp) == k


def test_in_range_edges_are_accepted():
    s = parse(
        'image { width 16384 height 16384 samples 1 }\n'
        "camera { fov 179.9 }\n"
        'material "m" { shininess 1e-6 diffuse { marble { octaves 64 scale 1e-30 period -2 distortion -3 } } }\n'
        'material "n" { diffuse { marble { octaves 0 } } }\n'
        'sphere { radius 1e-20 material "m" }\n'
        "ambient < 0 0 3.4e38 >\n"
    )
    assert s.image.width * s.image.height == 1 << 28
    assert s.materials["m"].diffuse.octaves == 64
    assert s.materials["m"].diffuse.period == -2.0
    assert s.materials["n"].diffuse.octaves == 0


def test_integral_float_literals_count_as_integers():
    s = parse('image { width 5e2 height 500.0 samples 9.0 }\nmaterial "m" { diffuse { marble { octaves 8.0 } } }')
    assert (s.image.width, s.image.height, s.image.samples) == (500, 500, 9)
    assert isinstance(s.image.width, int) and isinstance(s.materials["m"].diffuse.octaves, int)


def test_up_need_not_be_perpendicular():
    assert parse("camera { eye <0 0 10> up <0 1 1> }").camera.up == (0.0, 1.0, 1.0)


def test_a_one_colour_ramp_is_accepted_as_a_constant():
    from mimarble.scene import parse
    s = parse('material "m" { diffuse { marble { ramp { <0.1 0.2 0.3> } } } }')
    assert s.materials["m"].diffuse.ramp == ((0.1, 0.2, 0.3),)
