"""Habits of POV-Ray's language: each gets its usual error at FILE:LINE:COL and one more
line, ``hint: …``, naming this language's way (syntax_errors.POVRAY_HINTS)."""

import pickle

import pytest

from mimarble import scene as S
from mimarble.scene.syntax_errors import POVRAY_HINTS

MARBLE = 'material "m" {{ diffuse {{ marble {{ {} }} }} }}'

#: One scene a POV-Ray user might write for each entry of the table, and where its
#: error is (line, column).
HABITS = {
    "#declare": ("#declare R = 1;", (1, 1)),
    "#local": ("#local R = 1;", (1, 1)),
    "#include": ('#include "colors.inc"', (1, 1)),
    "#version": ("#version 3.7;", (1, 1)),
    ";": ("ambient < 1 1 1 >;", (1, 18)),
    "pigment": ('material "m" { pigment { color < 1 0 0 > } }', (1, 16)),
    "texture": ("sphere { center < 0 0 0 > texture { } }", (1, 27)),
    "finish": ('material "m" { finish { phong 1 } }', (1, 16)),
    "rgb": ('material "m" { diffuse { color rgb <1,0,0> } }', (1, 32)),
    "srgb": ('material "m" { diffuse { color srgb <1,0,0> } }', (1, 32)),
    "light_source": ("light_source { <10, 10, -10> color rgb <1, 1, 1> }", (1, 1)),
    "light <": ("light { <10, 10, -10> }", (1, 9)),
    "area_light": ("light { position < 1 2 3 > area_light <1 0 0>, <0 0 1>, 4, 4 }", (1, 28)),
    "location": ("camera { location <0, 0, -9> }", (1, 10)),
    "look_at": ("camera { look_at <0, 0, 0> }", (1, 10)),
    "angle": ("camera { angle 46 }", (1, 10)),
    "sky": ("camera { sky <0, 1, 0> }", (1, 10)),
    "sphere <": ("sphere { <0,0,0>, 2 }", (1, 10)),
    "ramp ,": (MARBLE.format("ramp { <1 0 0>, <0 0 1> }"), (1, 49)),
    "color_map": (MARBLE.format("color_map { }"), (1, 35)),
    "turbulence <number>": (MARBLE.format("turbulence 0.8"), (1, 46)),
    "omega": (MARBLE.format("omega 0.5"), (1, 35)),
    "lambda": (MARBLE.format("lambda 2"), (1, 35)),
    "marble translate": (MARBLE.format("translate <1 0 0>"), (1, 35)),
    "marble rotate": (MARBLE.format("rotate <0 0 30>"), (1, 35)),
    "translate": ("sphere { translate <1, 0, 0> }", (1, 10)),
    "rotate": ("sphere { rotate <0, 0, 30> }", (1, 10)),
    "global_settings": ("global_settings { assumed_gamma 1 }", (1, 1)),
    "background": ("background { color <0 0 0> }", (1, 1)),
    **{name: (f'material "m" {{ diffuse {{ {name} }} }}', (1, 26))
       for name in ("White_Marble", "Red_Marble", "Blood_Marble", "Jade")},
}


def refusal(text) -> S.SceneError:
    with pytest.raises(S.SceneError) as e:
        S.parse(text, filename="pov.scene")
    return e.value


def test_every_hint_has_a_habit_here():
    assert set(HABITS) == set(POVRAY_HINTS)


@pytest.mark.parametrize("key", sorted(POVRAY_HINTS))
def test_each_povray_habit_gets_its_hint_under_its_error(key):
    text, where = HABITS[key]
    e = refusal(text)
    assert (e.line, e.column) == where and e.hint == POVRAY_HINTS[key]
    head, source, caret, hint = str(e).split("\n")
    assert head.startswith(f"pov.scene:{where[0]}:{where[1]}: ") and source == text
    assert caret == " " * (where[1] - 1) + "^" and hint == f"hint: {POVRAY_HINTS[key]}"


def test_a_hint_is_one_line_naming_this_languages_way():
    for key, hint in POVRAY_HINTS.items():
        assert "\n" not in hint and len(hint) < 200, key


def test_hints_name_the_gain_and_lacunarity_keywords_and_the_vertical_fov():
    assert "gain" in POVRAY_HINTS["omega"] and "lacunarity" in POVRAY_HINTS["lambda"]
    assert "distortion" in POVRAY_HINTS["turbulence <number>"]
    assert "vertical" in POVRAY_HINTS["angle"] and "horizontal" in POVRAY_HINTS["angle"]
    assert "light { … } in docs/scene-language.md" in POVRAY_HINTS["area_light"]
    assert 'marble { preset "white_marble" }' in POVRAY_HINTS["White_Marble"]


def test_errors_that_are_no_povray_habit_get_no_hint():
    e = refusal("camera { eyes < 1 2 3 > }")
    assert e.hint is None and "hint" not in str(e)
    assert refusal("ambient < 1 2 >").hint is None


def test_the_hint_survives_pickling():
    e = refusal("camera { angle 46 }")
    again = pickle.loads(pickle.dumps(e))
    assert again.hint == e.hint and str(again) == str(e)
