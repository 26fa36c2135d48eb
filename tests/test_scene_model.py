"""The scene model: defaults, immutability, equality, paper scene files, import hygiene."""

from __future__ import annotations

import dataclasses
import pickle
import subprocess
import sys
from pathlib import Path

import pytest

from mimarble import scene as S
from mimarble.scene import (
    FIG5_RAMP,
    Camera,
    ColorChannel,
    Image,
    Light,
    MarbleChannel,
    Material,
    Pos,
    Scene,
    SceneError,
    Sphere,
    load,
    parse,
)

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted((ROOT / "scenes").glob("*.scene"))


def test_defaults_when_statements_are_absent():
    s = parse('material "m" { }\nsphere { material "m" }')
    assert s.image == Image(width=500, height=500, samples=1, background=(0.0, 0.0, 0.0))
    assert s.camera == Camera(eye=(0.0, 0.0, 10.0), lookat=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov=30.0)
    assert s.ambient == (0.0, 0.0, 0.0)
    assert s.lights == ()
    assert s.materials["m"] == Material("m", ambient=None, diffuse=None, specular=None, shininess=32.0)
    assert s.spheres == (Sphere("m", center=(0.0, 0.0, 0.0), radius=1.0),)


def test_defaults_of_empty_blocks_equal_absent_blocks():
    assert parse("image { } camera { }") == parse("")
    assert parse("light { position <1 2 3> }").lights == (Light((1.0, 2.0, 3.0), (1.0, 1.0, 1.0)),)


def test_marble_defaults():
    m = parse('material "m" { diffuse { marble { } } }').materials["m"].diffuse
    assert m == MarbleChannel()
    assert (m.scale, m.period, m.distortion, m.octaves) == (1.0, 1.0, 1.0, 8)
    assert (m.function, m.axis, m.turbulence) == ("abs_sine", "x", False)
    assert m.ramp == FIG5_RAMP == tuple((1.0, k / 8, 0.0) for k in range(8))
    assert m.axis_index == 0


def test_all_marble_keys():
    m = parse(
        'material "m" { ambient { marble { scale 2 period 3 distortion 4 octaves 5 function cosine axis z '
        "turbulence true filter bandlimit ramp { <0 0 0> <1 1 1> } } } }"
    ).materials["m"].ambient
    assert m == MarbleChannel(scale=2.0, period=3.0, distortion=4.0, octaves=5, function="cosine",
                              axis="z", turbulence=True, filter="bandlimit",
                              ramp=((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)))
    assert m.axis_index == 2


def test_all_keys_of_every_block():
    s = parse(
        "image { width 64 height 32 samples 16 background <0.1 0.2 0.3> }\n"
        "camera { eye <1 2 3> lookat <0 1 0> up <0 0 1> fov 45 }\n"
        "ambient <0.5 0.5 0.5>\n"
        "light { position <9 9 9> color <2 2 2> }\n"
        "light { position <-9 9 9> }\n"
        'material "a" { ambient { color <.1 .1 .1> } diffuse { marble { } } specular { color <1 1 1> } shininess 64 }\n'
        'sphere { center <1 0 0> radius 0.5 material "a" }\n'
        'sphere { material "a" }\n'
    )
    assert s.image == Image(64, 32, 16, (0.1, 0.2, 0.3))
    assert s.image.samples_per_axis == 4 and s.image.aspect == 2.0
    assert s.camera == Camera((1.0, 2.0, 3.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), 45.0)
    assert s.ambient == (0.5, 0.5, 0.5)
    assert [l.position for l in s.lights] == [(9.0, 9.0, 9.0), (-9.0, 9.0, 9.0)]
    a = s.materials["a"]
    assert a.ambient == ColorChannel((0.1, 0.1, 0.1)) and a.specular == ColorChannel((1.0, 1.0, 1.0))
    assert a.shininess == 64.0
    assert list(a.channels()) == ["ambient", "diffuse", "specular"]
    assert s.spheres[0] == Sphere("a", (1.0, 0.0, 0.0), 0.5)
    assert s.material_of(s.spheres[1]) is a


def test_value_types_are_plain_python():
    s = load(ROOT / "scenes" / "fig11a.scene")
    m = s.materials["marble"].diffuse
    assert type(m.octaves) is int and type(s.image.width) is int and type(m.turbulence) is bool
    for v in (s.camera.eye, s.ambient, s.spheres[0].center, *m.ramp):
        assert type(v) is tuple and len(v) == 3 and all(type(c) is float for c in v)


def test_model_is_immutable():
    s = parse('material "m" { }\nsphere { material "m" }')
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.image.width = 3  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.spheres[0].radius = 3  # type: ignore[misc]
    with pytest.raises(TypeError):
        s.materials["x"] = Material("x")  # type: ignore[index]
    assert isinstance(s.lights, tuple) and isinstance(s.spheres, tuple)


def test_equality_ignores_layout_comments_and_positions():
    a = parse('material "m" { diffuse { color <1 0 0> } }\nsphere { material "m" radius 2 }', "a.scene")
    b = parse('// other layout\nmaterial   "m"{diffuse{color<1,0,0>}}sphere{radius 2.0 material"m"}', "b.scene")
    assert a == b and hash(a) == hash(b)
    assert a.spheres[0].pos != b.spheres[0].pos
    assert a.source == "a.scene" and b.source == "b.scene"
    assert a != parse('material "m" { diffuse { color <1 0 0> } }\nsphere { material "m" radius 3 }')


def test_positions_point_at_keywords():
    s = parse('\n  material "m" {\n    diffuse { marble { } }\n  }\nsphere { material "m" }')
    assert s.materials["m"].pos == Pos(2, 3)
    assert s.materials["m"].diffuse.pos == (3, 15)
    assert str(s.spheres[0].pos) == "5:1"
    assert "pos" not in repr(s.spheres[0])


def test_programmatic_construction_is_normalised():
    s = Scene(materials={"m": Material("m")}, spheres=[Sphere("m")], lights=[])
    assert isinstance(s.spheres, tuple) and hash(s) == hash(Scene(materials={"m": Material("m")}, spheres=(Sphere("m"),)))
    assert MarbleChannel(ramp=[[0, 0, 0], [1, 1, 1]]).ramp == ((0, 0, 0), (1, 1, 1))
    assert dataclasses.replace(MarbleChannel(), octaves=3).octaves == 3


def test_scene_error_pickles_and_formats():
    e = SceneError("boom", filename="f.scene", line=2, column=3, source_line="abcdef")
    assert str(e) == "f.scene:2:3: boom\nabcdef\n  ^"
    e2 = pickle.loads(pickle.dumps(e))
    assert str(e2) == str(e) and e2.location == "f.scene:2:3"
    assert str(SceneError("gone", filename="x")) == "x: gone"


def test_a_syntax_error_pickles_where_dask_distributed_pickles_exceptions_with_context():
    """dask.distributed registers tblib's reducers for every exception class: they pickle
    an exception's __context__ too, and Lark's (its parser state) does not pickle."""
    pytest.importorskip("distributed")
    import dask.distributed  # noqa: F401   (the registration happens on import)
    from mimarble import scene as S
    with pytest.raises(SceneError) as raised:
        S.parse("camera { angle 46 }", filename="pov.scene")
    again = pickle.loads(pickle.dumps(raised.value))
    assert str(again) == str(raised.value)


# --------------------------------------------------------------------------
#  The paper's scenes
# --------------------------------------------------------------------------

EXPECTED_SCENES = ["fig05"] + [f"fig{n:02d}{c}" for n in (1, 2, 7, 8, 9, 10, 11) for c in "abcd"]


def test_one_scene_file_per_paper_image():
    assert sorted(p.stem for p in SCENES) == sorted(EXPECTED_SCENES)


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.name)
def test_paper_scene_parses_and_validates(path):
    s = load(path)
    assert (s.image.width, s.image.height) == (500, 500)
    assert len(s.lights) == 1 and len(s.spheres) == 1
    assert s.material_of(s.spheres[0]).diffuse is not None
    assert isinstance(s.material_of(s.spheres[0]).diffuse, MarbleChannel)
    header = path.read_text(encoding="utf-8").splitlines()[0]
    assert header.startswith("// Fig. ")


PAPER_TABLES = {
    "fig07": [(0.5, 1.0, 1.0, 8), (1.0, 1.0, 1.0, 8), (2.0, 1.0, 1.0, 8), (4.0, 1.0, 1.0, 8)],
    "fig08": [(1.0, 0.5, 1.0, 8), (1.0, 1.0, 1.0, 8), (1.0, 2.0, 1.0, 8), (1.0, 4.0, 1.0, 8)],
    "fig09": [(1.0, 1.0, 0.5, 8), (1.0, 1.0, 1.0, 8), (1.0, 1.0, 2.0, 8), (1.0, 1.0, 4.0, 8)],
    "fig10": [(1.0, 1.0, 1.0, 1), (1.0, 1.0, 1.0, 2), (1.0, 1.0, 1.0, 4), (1.0, 1.0, 1.0, 8)],
    "fig11": [(1.0, 1.3, 3.0, 12), (1.0, 1.5, 1.7, 32), (0.3, 1.2, 3.0, 8), (2.7, 1.6, 0.6, 8)],
}


@pytest.mark.parametrize("fig", sorted(PAPER_TABLES))
def test_paper_scene_values_match_the_tables(fig):
    for letter, row in zip("abcd", PAPER_TABLES[fig]):
        m = load(ROOT / "scenes" / f"{fig}{letter}.scene").materials["marble"]
        d = m.diffuse
        assert (d.scale, d.period, d.distortion, d.octaves) == row
        assert (d.function, d.axis, d.turbulence, d.ramp) == ("abs_sine", "x", False, FIG5_RAMP)
        assert m.ambient == d


def test_fig1_and_fig2_functions():
    for letter in "abcd":
        d1 = load(ROOT / "scenes" / f"fig01{letter}.scene").materials["marble"].diffuse
        d2 = load(ROOT / "scenes" / f"fig02{letter}.scene").materials["marble"].diffuse
        assert (d1.function, d1.period, d1.turbulence) == ("sine", 20.0, True)
        assert (d2.function, d2.turbulence) == ("cosine", True)
    distortions = [load(ROOT / "scenes" / f"fig01{c}.scene").materials["marble"].diffuse.distortion for c in "abcd"]
    assert distortions == sorted(distortions) and len(set(distortions)) == 4


def test_fig05_scene_holds_the_fig5_materials():
    from test_scene_language import FIG5

    s = load(ROOT / "scenes" / "fig05.scene")
    assert dict(s.materials) == dict(parse(FIG5).materials)


# --------------------------------------------------------------------------
#  Import hygiene
# --------------------------------------------------------------------------


def test_scene_package_imports_without_mitsuba_drjit_numpy():
    # Load mimarble.scene under a stub parent package so that mimarble/__init__.py
    # (which sets up Mitsuba) does not run, then check what got imported.
    code = (
        "import sys, types\n"
        f"pkg = types.ModuleType('mimarble'); pkg.__path__ = [{str(ROOT / 'mimarble')!r}]\n"
        "sys.modules['mimarble'] = pkg\n"
        "import mimarble.scene as s\n"
        "s.parse('material \"m\" { diffuse { marble { } } } sphere { material \"m\" }')\n"
        "bad = sorted(m for m in ('mitsuba', 'drjit', 'numpy') if m in sys.modules)\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_grammar_is_shipped_next_to_the_parser():
    assert S.GRAMMAR_PATH.name == "scene.lark" and S.GRAMMAR_PATH.parent == Path(S.__file__).parent


def test_marble_rules_and_keys_are_written_from_the_parameter_table():
    import re

    # The rows with a key of their own (ramp_positions is written inside the ramp block).
    from mimarble.parameters import KEYWORD_PARAMETERS as PARAMETERS
    from mimarble.scene.grammar import LANGUAGE_MARBLE_KEYS, grammar_text
    names = tuple(p.name for p in PARAMETERS) + LANGUAGE_MARBLE_KEYS     # then transform
    assert S.BLOCK_KEYS["marble"] == names
    assert not re.search(r"^_?marble(_key)?:", S.GRAMMAR_PATH.read_text(), re.M)  # not by hand
    assert re.search(r"^_marble_key: " + re.escape(" | ".join(names)) + "$", grammar_text(), re.M)
    assert S.LIMITS["octaves"] == (0, 64) and S.LIMITS["ramp_colours"] == (1, 256)


PNG = str(Path(__file__).resolve().parent.parent / "scenes" / "future-work" / "maps" / "flagstones.png")


def test_block_keys_table_matches_the_grammar(tmp_path):
    # Every keyword listed for a block is accepted there (a tiny, valid use of each).
    (tmp_path / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    samples = {
        "width": "1", "height": "1", "samples": "1", "background": "<0 0 0>",
        "eye": "<0 0 5>", "lookat": "<0 0 0>", "up": "<0 1 0>", "fov": "30",
        "position": "<0 0 0>", "color": "<0 0 0>", "shininess": "2",
        "ambient": "{ color <0 0 0> }", "diffuse": "{ color <0 0 0> }", "specular": "{ color <0 0 0> }",
        "scale": "1", "period": "1", "distortion": "1", "octaves": "1", "function": "sine", "axis": "y",
        "turbulence": "true", "filter": "prefilter", "tolerance": "0.001", "ramp": "{ <0 0 0> <1 1 1> }",
        "gain": "0.6", "lacunarity": "2.5",
        "center": "<0 0 0>", "radius": "1",
        "area": "{ radius 1 }", "axis1": "<1 0 0> axis2 <0 1 0>", "axis2": "<0 1 0> axis1 <1 0 0>",
        "material": '"m"',
        "transform": "{ }", "translate": "<1 0 0>", "rotate": "<0 0 90>", "space": "object",
        "preset": '"jade"',
        "point": "<0 0 0>", "normal": "<0 0 1>", "min": "<0 0 0>", "max": "<1 1 1>",
        "file": f'"{tmp_path / "a.obj"}"',
        "subsurface": "{ albedo color <1 1 1> mean_free_path 1 }",
        "density": "color <1 1 1>", "ior": "1.3", "grid": "false",
    }
    wrap = {
        "image": "image {{ {} }}", "camera": "camera {{ {} }}", "light": "light {{ position <0 5 0> {} }}",
        "material": 'material "m" {{ {} }}', "marble": 'material "m" {{ diffuse {{ marble {{ {} }} }} }}',
        "area": 'light {{ position <0 5 0> area {{ {} }} }}',
        "transform": 'material "m" {{ diffuse {{ marble {{ transform {{ {} }} }} }} }}',
        "subsurface": 'material "m" {{ subsurface {{ albedo color <1 1 1> mean_free_path 1 {} }} }}',
    }
    # Every kind of shape's block, and a value for each of its keys the table above lacks.
    wrap |= {kind.keyword: f'material "m" {{{{ }}}} {kind.keyword} {{{{ material "m" {{}} }}}}'
             for kind in S.SHAPE_KINDS}
    samples |= {key.name: {"vector": "<0 0 1>", "number": "1", "boolean": "true"}[key.syntax]
                for kind in S.SHAPE_KINDS for key in kind.keys if key.name not in samples}
    one = {"color": "color <0 0 0>", "marble": "marble { }", "weight": "weight 0.5",
           "image": f'image {{ file "{PNG}" }}', "add": "add { color <0 0 0> color <0 0 0> }",
           "multiply": "multiply { color <0 0 0> color <0 0 0> }",
           "mix": "mix { color <0 0 0> color <0 0 0> weight 0.5 }", "texture": 'texture "t"'}
    texture = 'texture "t" { color <0 0 0> } '
    for block, keys in S.BLOCK_KEYS.items():
        if block in ("ambient", "diffuse", "specular", "texture"):
            for ch in keys:
                parse(texture + (f'material "m" {{ {block} {{ {one[ch]} }} }}' if block != "texture"
                                 else f'texture "u" {{ {one[ch]} }}'))
            continue
        if block in ("add", "multiply", "mix", "image_map"):
            for key in keys:
                if block == "image_map":                     # its one key: file
                    inner = one["image"]
                elif key == "weight":
                    inner = one[block]
                else:
                    operands = f"{one[key]} {one[key]}" + (" weight 0.5" if block == "mix" else "")
                    inner = f"{block} {{ {operands} }}"
                parse(texture + f'material "m" {{ diffuse {{ {inner} }} }}')
            continue
        if block == "environment":      # exactly one of file and color; rotate a file's
            alone = {"file": f'file "{PNG}"', "color": "color <1 1 1>",
                     "intensity": "color <1 1 1> intensity 2",
                     "rotate": f'file "{PNG}" rotate <0 90 0>'}
            for key in keys:
                parse(f"environment {{ {alone[key]} }}")
            continue
        for key in keys:
            if (block, key) in (("light", "position"), ("subsurface", "albedo"),
                                ("subsurface", "mean_free_path")) \
                    or (block in S.STATEMENTS and key == "material"):
                continue  # required keys, already in the wrapper
            if block == "mesh" and key != "file":       # a mesh needs its file too
                parse(wrap[block].format(f"{key} {samples[key]} file {samples['file']}"))
                continue
            if (block, key) == ("subsurface", "reflectance"):   # in albedo's place: one of the two
                parse('material "m" { subsurface { reflectance color <1 1 1> mean_free_path 1 } }')
                continue
            if (block, key) == ("area", "samples"):     # with a shape: radius or the axes
                parse(wrap[block].format("radius 1 samples 4"))
                continue
            parse(wrap[block].format(f"{key} {samples[key]}"))


def test_the_documented_marble_keys_are_the_parameter_table():
    """docs/scene-language.md lists the marble's keys by hand: one row per parameter of
    mimarble/parameters.py, in its order, with its default."""
    from pathlib import Path

    from mimarble.parameters import COLOURS
    from mimarble.parameters import KEYWORD_PARAMETERS as PARAMETERS
    from mimarble.scene.grammar import LANGUAGE_MARBLE_KEYS
    text = (Path(__file__).parent.parent / "docs" / "scene-language.md").read_text()
    table = text[text.index("The marble, all keys optional"):]
    rows = [line for line in table.split("\n\n", 2)[1].splitlines() if line.startswith("| `")]
    assert [row.split("`")[1] for row in rows] == [p.name for p in PARAMETERS] + list(LANGUAGE_MARBLE_KEYS)
    for row, p in zip(rows, PARAMETERS):
        default = row.split("|")[3].strip().strip("`")
        if p.kind == COLOURS or p.default is None:
            continue
        expected = str(p.default).lower() if p.kind == "boolean" else \
            f"{p.default:g}" if p.kind == "number" else str(p.default)
        assert default == expected, (p.name, default)
