"""A material's ``subsurface { … }`` (issue 26): its syntax, values, defaults and positions,
each refusal at its FILE:LINE:COL in one sentence; whitted mode's refusal of it, and path
mode's translation (a ``subsurface_boundary`` around a ``marble_medium`` interior, under
``volpath``). The expected values are written out by hand (the model's constructors, the
numbers of the scene text), never taken from the code under test."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

from mimarble import scene as S
from mimarble.mitsuba.translate import scene_dict as translate
from mimarble.mitsuba.translate.scene_dict import to_mitsuba
from mimarble.scene import parse
from mimarble.scene.limits import MAX_CHANNEL_DEPTH

from commands import mimarble_cli
# The scene language's own checks of a refusal (at line:column, one sentence, quoting the
# line) and of where a fragment stands in a text.
from test_scene_shapes import refused_at, where

PNG = str(Path(__file__).resolve().parent.parent / "scenes" / "future-work" / "maps" / "flagstones.png")


def material(inside: str, extra: str = "") -> str:
    return f'material "m" {{ {extra}subsurface {{ {inside} }} }}\n'


# --------------------------------------------------------------------------
#  parsing: values, defaults, positions
# --------------------------------------------------------------------------


def test_a_subsurface_holds_its_channels_and_numbers_at_its_keyword():
    text = ('material "jade" {\n  diffuse { color < 0.5 0.5 0.5 > }\n'
            '  subsurface { albedo color < 0.6 0.9 0.7 > mean_free_path 0.2\n'
            '               density marble { period 2 } ior 1.3 }\n}')
    jade = parse(text).materials["jade"]
    assert jade == S.Material("jade", diffuse=S.ColorChannel((0.5, 0.5, 0.5)),
                              subsurface=S.Subsurface(S.ColorChannel((0.6, 0.9, 0.7)), 0.2,
                                                      ior=1.3,
                                                      density=S.MarbleChannel(period=2.0)))
    assert jade.subsurface.pos == (3, 3)
    assert jade.subsurface.albedo.pos == (3, 23) and jade.subsurface.density.pos == (4, 24)


def test_ior_defaults_to_one_and_a_half_and_the_density_to_none():
    sub = parse(material("albedo color < 1 1 1 > mean_free_path 2")).materials["m"].subsurface
    assert (sub.ior, sub.density, sub.mean_free_path) == (1.5, None, 2.0)


def test_keys_come_in_any_order_and_a_material_without_one_has_no_subsurface():
    a = parse(material("ior 1.2 density color < 1 1 1 > mean_free_path 1 albedo color < 1 0 0 >"))
    b = parse(material("albedo color < 1 0 0 > mean_free_path 1 density color < 1 1 1 > ior 1.2"))
    assert a == b
    assert parse('material "m" { diffuse { color < 1 1 1 > } }').materials["m"].subsurface is None


def test_the_channels_are_full_channels_and_textures_are_substituted():
    text = ('texture "veins" { marble { period 1.3 distortion 3 } }\n'
            + material('albedo mix { color < 1 1 1 > texture "veins" weight 0.25 } '
                       'mean_free_path 0.5 density multiply { texture "veins" color < 2 2 2 > }'))
    sub = parse(text).materials["m"].subsurface
    veins = S.MarbleChannel(period=1.3, distortion=3.0)
    assert sub.albedo == S.Mix(S.ColorChannel((1.0, 1.0, 1.0)), veins, 0.25)
    assert sub.density == S.Multiply((veins, S.ColorChannel((2.0, 2.0, 2.0))))


@pytest.mark.parametrize("shape", ['plane { material "m" }', 'box { material "m" }',
                                   'sphere { material "m" }'])
def test_an_object_space_marble_in_a_subsurface_goes_on_any_shape(shape):
    # (u, v) matter to image maps only: a volume's marbles need none.
    text = material("albedo marble { space object } mean_free_path 1") + shape
    assert parse(text).materials["m"].subsurface.albedo.space == "object"


def test_a_reflectance_stands_in_for_the_albedo():
    text = material("reflectance marble { period 2 } mean_free_path 0.2 ior 1.3")
    sub = parse(text).materials["m"].subsurface
    assert sub == S.Subsurface(reflectance=S.MarbleChannel(period=2.0), mean_free_path=0.2, ior=1.3)
    assert sub.albedo is None and sub.reflectance.pos == where(text, "marble")
    assert sub.channels() == {"reflectance": S.MarbleChannel(period=2.0)}
    textured = parse('texture "veins" { marble { period 1.3 } }\n'
                     + material('reflectance texture "veins" mean_free_path 1'))
    assert textured.materials["m"].subsurface.reflectance == S.MarbleChannel(period=1.3)


@pytest.mark.parametrize("given", [{}, {"albedo": S.ColorChannel((1, 1, 1)),
                                        "reflectance": S.ColorChannel((1, 1, 1))}])
def test_the_model_takes_exactly_one_of_albedo_and_reflectance(given):
    with pytest.raises(ValueError, match="exactly one of albedo"):
        S.Subsurface(mean_free_path=1.0, **given)


def test_every_key_of_a_subsurface_is_accepted():
    # BLOCK_KEYS lists what the grammar takes, in the order the messages list them.
    assert S.BLOCK_KEYS["subsurface"] == ("albedo", "reflectance", "mean_free_path", "density",
                                          "ior", "grid")
    assert S.BLOCK_KEYS["material"][-1] == "subsurface"
    values = {"density": "color < 1 1 1 >", "ior": "1.1", "grid": "false"}
    for key in S.BLOCK_KEYS["subsurface"]:
        extra = f" {key} {values[key]}" if key in values else ""
        colour = "reflectance" if key == "reflectance" else "albedo"   # one of the two
        parse(material(f"{colour} color < 1 1 1 > mean_free_path 1" + extra))


# --------------------------------------------------------------------------
#  parsing: refusals
# --------------------------------------------------------------------------


@pytest.mark.parametrize("inside, missing", [("albedo color < 1 1 1 >", "mean_free_path"),
                                             ("mean_free_path 1 ior 1.2", "albedo"),
                                             ("", "albedo")])
def test_a_missing_required_key_is_refused_at_the_subsurface_keyword(inside, missing):
    text = material(inside)
    refused_at(text, *where(text, "subsurface"), f"subsurface has no '{missing}'",
               "mean_free_path 0.2")


def test_neither_albedo_nor_reflectance_is_refused_at_the_subsurface_keyword():
    text = material("mean_free_path 1 density color < 1 1 1 >")
    refused_at(text, *where(text, "subsurface"), "subsurface has no 'albedo' or 'reflectance'",
               "reflectance color < 0.9 0.9 0.9 > mean_free_path 0.2", "the colour seen")


@pytest.mark.parametrize("first, second", [("albedo", "reflectance"), ("reflectance", "albedo")])
def test_both_albedo_and_reflectance_are_refused_at_the_second(first, second):
    text = material(f"{first} color < 1 1 1 > mean_free_path 1\n  {second} marble {{ }}")
    line, column = where(text, first)
    refused_at(text, *where(text, second), f"subsurface has both '{first}' (at {line}:{column}) "
               f"and '{second}'; give one")


@pytest.mark.parametrize("key, value", [("albedo", "color < 1 1 1 >"), ("mean_free_path", "2"),
                                        ("density", "color < 1 1 1 >"), ("ior", "1.2"),
                                        ("reflectance", "color < 1 1 1 >")])
def test_a_key_given_twice_is_refused_at_the_second(key, value):
    required = {"albedo": "color < 1 1 1 >", "mean_free_path": "1"}
    others = " ".join(f"{k} {v}" for k, v in required.items() if k != key)
    text = material(f"{others} {key} {value} {key} {value}")
    first, second = where(text, f"{key} {value}", 0), where(text, f"{key} {value}", 1)
    refused_at(text, *second, f"duplicate '{key}' in 'subsurface' block (first given at "
                              f"{first[0]}:{first[1]})")


@pytest.mark.parametrize("key, number, rule", [
    ("mean_free_path", "0", "mean_free_path must be > 0 (scene units), found 0"),
    ("mean_free_path", "-0.5", "mean_free_path must be > 0 (scene units), found -0.5"),
    ("ior", "0", "ior must be > 0 (the index inside over outside), found 0"),
    ("ior", "-1.5", "ior must be > 0 (the index inside over outside), found -1.5"),
    ("ior", "1e999", "number 1e999 is not finite"),
])
def test_a_number_out_of_its_range_is_refused_at_the_number(key, number, rule):
    mfp = number if key == "mean_free_path" else "1"
    ior = f" ior {number}" if key == "ior" else ""
    text = material(f"albedo color < 1 1 1 > mean_free_path {mfp}{ior}")
    line, column = where(text, f"{key} {number}")
    refused_at(text, line, column + len(key) + 1, rule)


def test_an_image_map_is_refused_at_its_image_keyword_before_its_file_is_read():
    # The file does not exist: the volume's refusal comes first, at `image`.
    text = material('albedo add { color < 1 1 1 > image { file "no/such.png" } } mean_free_path 1')
    refused_at(text, *where(text, "image"), "an image map has no place in a subsurface",
               "(u, v)")


def test_an_image_map_brought_in_by_a_texture_is_refused_at_the_use():
    text = (f'texture "photo" {{ image {{ file "{PNG}" }} }}\n'
            + material('albedo color < 1 1 1 > mean_free_path 1 density texture "photo"'))
    refused_at(text, *where(text, 'texture "photo"', 1),
               'texture "photo" holds an image map, which has no place in a subsurface')


def test_braces_around_a_channel_are_refused_at_the_brace_with_the_bare_form():
    text = material("albedo { color < 1 1 1 > } mean_free_path 1")
    refused_at(text, *where(text, "{ color"), "expected a channel after 'albedo'",
               "found '{'", "albedo color < 1 1 1 >")


def test_a_second_channel_is_refused_at_its_keyword():
    text = material("density color < 1 1 1 > color < 2 2 2 > albedo color < 1 1 1 > mean_free_path 1")
    refused_at(text, *where(text, "color < 2"), "keyword 'color' is not allowed in 'subsurface' block",
               "exactly one channel")


def test_an_unknown_key_lists_the_subsurface_keys_in_order():
    text = material("albedo color < 1 1 1 > scattering 2")
    refused_at(text, *where(text, "scattering"),
               "unknown keyword 'scattering' in 'subsurface' block; allowed: 'albedo', "
               "'reflectance', 'mean_free_path', 'density', 'ior' or 'grid'")


def test_a_mistake_inside_an_image_map_there_lists_the_image_maps_keys():
    text = material('albedo image { fil "x.png" } mean_free_path 1')
    refused_at(text, *where(text, "fil "), "unknown keyword 'fil' in 'image' block; allowed: 'file'")


def test_a_channel_nested_past_the_depth_limit_is_refused_at_its_keyword():
    deep = "add { " * MAX_CHANNEL_DEPTH + "color < 1 1 1 >" + " color < 0 0 0 > }" * MAX_CHANNEL_DEPTH
    text = material(f"albedo {deep} mean_free_path 1")
    # The channel past the limit is the color at level MAX_CHANNEL_DEPTH + 1.
    refused_at(text, *where(text, "color"), "channels nested too deep",
               f"level {MAX_CHANNEL_DEPTH + 1}")


# --------------------------------------------------------------------------
#  whitted mode refuses it
# --------------------------------------------------------------------------


SCENE = ('image { width 8 height 8 }\nlight { position < 3 3 3 > }\n'
         'material "jade" {\n  diffuse { color < 0.5 0.5 0.5 > }\n'
         '  subsurface { albedo color < 0.9 0.9 0.9 > mean_free_path 0.2 }\n}\n'
         'sphere { material "jade" }\n')


def test_whitted_mode_refuses_a_translucent_material_at_its_subsurface_keyword():
    with pytest.raises(ValueError) as info:
        to_mitsuba(parse(SCENE, "t.scene"))
    e = info.value
    assert isinstance(e, S.SceneError) and (e.line, e.column) == (5, 3)
    first = str(e).splitlines()[0]
    assert first == f"t.scene:5:3: {e.message}" and "\n" not in e.message
    assert 'material "jade" has a subsurface' in e.message and "--mode path" in e.message
    assert e.message.count(". ") == 0       # one sentence
    copy = pickle.loads(pickle.dumps(e))     # as a sweep's worker hands it back
    assert isinstance(copy, ValueError) and str(copy) == str(e)


def test_a_translucent_material_no_shape_uses_is_not_asked_about():
    unused = SCENE.replace('sphere { material "jade" }',
                           'material "grey" { diffuse { color < 1 1 1 > } }\n'
                           'sphere { material "grey" }')
    d = to_mitsuba(parse(unused))
    assert d["integrator"]["type"] == "whitted"


def test_the_command_line_prints_the_sentence_and_exits_2(tmp_path):
    (tmp_path / "x.scene").write_text(SCENE)
    result = mimarble_cli("render", "x.scene", "-o", "x.png", cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.splitlines()[0].startswith("x.scene:5:3: material \"jade\" has a subsurface")
    assert not (tmp_path / "x.png").exists()


# --------------------------------------------------------------------------
#  path mode: the dict
# --------------------------------------------------------------------------


def translucent(inside: str, shapes: str = 'sphere { material "m" }', extra: str = "") -> dict:
    return to_mitsuba(parse("light { position < 3 3 3 > }\n" + material(inside, extra) + shapes),
                      mode="path")


def test_path_mode_makes_a_subsurface_boundary_around_a_marble_medium():
    d = translucent("albedo color < 0.9 0.8 0.7 > mean_free_path 0.25 "
                    "density add { color < 1 1 1 > color < 0.5 2 0 > } ior 1.3")
    sphere = d["sphere_0"]
    assert sphere["bsdf"] == {"type": "subsurface_boundary", "int_ior": 1.3, "ext_ior": 1.0}
    medium = sphere["interior"]
    assert medium["type"] == "marble_medium"
    assert medium["scale"] == 4.0                          # 1 / 0.25
    assert medium["density_bound"] == pytest.approx(1.0 + 2.5 / 3)   # means: 1 + (0.5+2+0)/3
    assert medium["albedo"]["color"] == [0.9, 0.8, 0.7]
    assert d[medium["density"]["id"]]["type"] == "channel_expression"


def test_a_reflectance_goes_to_the_medium_with_the_boundarys_ior():
    d = translucent('reflectance marble { ramp { < 0.9 0.9 0.9 > < 0.3 0.2 0.1 > } } '
                    'mean_free_path 0.05 ior 1.3')
    medium = d["sphere_0"]["interior"]
    assert medium["type"] == "marble_medium" and "albedo" not in medium
    assert medium["ior"] == 1.3 and medium["scale"] == 20.0
    assert d[medium["reflectance"]["id"]]["type"] == "marble"
    assert "ior" not in translucent("albedo color < 1 1 1 > mean_free_path 1")["sphere_0"]["interior"]


def test_without_a_density_the_medium_has_none_and_a_bound_of_one():
    medium = translucent("albedo color < 1 1 1 > mean_free_path 2")["sphere_0"]["interior"]
    assert "density" not in medium and medium["density_bound"] == 1.0 and medium["scale"] == 0.5


def test_a_marble_density_is_bounded_by_its_ramp():
    d = translucent("albedo color < 1 1 1 > mean_free_path 1 "
                    "density marble { ramp { < 0 0 0 > < 4 1 0.5 > } }")
    medium = d["sphere_0"]["interior"]
    assert medium["density_bound"] == pytest.approx(5.5 / 3)   # the mean of < 4 1 0.5 >
    assert d[medium["density"]["id"]]["type"] == "marble"


def test_a_scene_with_a_translucent_material_renders_under_volpath():
    d = translucent("albedo color < 1 1 1 > mean_free_path 1")
    assert d["integrator"] == {"type": "volpath", "max_depth": 256, "rr_depth": 256,
                               "hide_emitters": True}          # albedo 1: no roulette
    assert translate.VOLPATH_MAX_DEPTH == 256
    opaque = to_mitsuba(parse('material "m" { diffuse { color < 1 1 1 > } } sphere { material "m" }'),
                        mode="path")
    assert opaque["integrator"]["type"] == "path"


@pytest.mark.parametrize("albedo, rr_depth", [
    ("color < 0.95 0.9 0.5 >", 5),                                 # at most volpath's 0.95
    ("color < 0.9 0.951 0.5 >", 256),
    ("marble { ramp { < 0.3 0.3 0.3 > < 0.96 0.9 0.9 > } }", 256),
    ("marble { ramp { < 0.3 0.3 0.3 > < 0.9 0.9 0.9 > } }", 5),
    ("add { color < 0.5 0.5 0.5 > color < 0.5 0.5 0.5 > }", 256),  # a bound of 1
])
def test_the_roulette_is_off_where_an_albedo_may_pass_its_cap(albedo, rr_depth):
    # volpath survives a path with min(max β, 0.95): above albedo 0.95 its weights run
    # away (docs/rendering-model.md, "Translucent materials"), so no roulette there.
    d = translucent(f"albedo {albedo} mean_free_path 1")
    assert d["integrator"]["rr_depth"] == rr_depth and d["integrator"]["max_depth"] == 256


def test_an_index_matched_boundary_is_a_subsurface_boundary_of_ior_1():
    d = translucent("albedo color < 1 1 1 > mean_free_path 1 ior 1")
    assert d["sphere_0"]["bsdf"] == {"type": "subsurface_boundary", "int_ior": 1.0, "ext_ior": 1.0}
    assert d["sphere_0"]["interior"]["sample_emitters"] is False


def test_the_surface_channels_are_unused_and_planes_and_boxes_are_not_two_sided():
    d = translucent("albedo color < 1 1 1 > mean_free_path 1",
                    'plane { point < 0 -2 0 > material "m" } box { material "m" }',
                    extra="diffuse { marble { period 7 } } ")
    for shape in ("plane_0", "box_0"):
        assert d[shape]["bsdf"]["type"] == "subsurface_boundary" and "interior" in d[shape]
    assert not [v for v in d.values() if isinstance(v, dict) and v.get("type") == "marble"]


def test_an_object_space_marble_in_a_subsurface_gets_a_texture_per_shape():
    d = translucent("albedo marble { space object } mean_free_path 1",
                    'sphere { center < 2 0 0 > radius 0.5 material "m" } '
                    'sphere { center < -1 1 0 > radius 2 material "m" }')
    ids = [d[f"sphere_{k}"]["interior"]["albedo"]["id"] for k in range(2)]
    assert len(set(ids)) == 2
    for texture_id, (centre, radius) in zip(ids, [((2, 0, 0), 0.5), ((-1, 1, 0), 2.0)]):
        placed = np.array(d[texture_id]["to_world"].matrix, dtype=np.float64)
        expected = np.diag([radius, radius, radius, 1.0])
        expected[:3, 3] = centre
        np.testing.assert_allclose(placed, expected, rtol=1e-7)


def test_a_world_space_marble_in_a_subsurface_is_one_texture_for_every_shape():
    d = translucent("albedo marble { } mean_free_path 1",
                    'sphere { material "m" } sphere { center < 3 0 0 > material "m" }')
    assert d["sphere_0"]["interior"]["albedo"] == d["sphere_1"]["interior"]["albedo"]


def test_a_mirrored_box_keeps_its_medium_inside(tmp_path):
    d = translucent("albedo color < 1 1 1 > mean_free_path 1",
                    'box { min < 0 0 0 > max < 1 2 3 > transform { scale < -1 1 1 > } material "m" }')
    m = np.array(d["box_0"]["to_world"].matrix, dtype=np.float64)
    assert np.linalg.det(m[:3, :3]) > 0          # triangles wound outwards
    corners = {tuple(np.round(m @ [x, y, z, 1.0], 6)[:3]) for x in (-1, 1) for y in (-1, 1)
               for z in (-1, 1)}
    assert corners == {(x, y, z) for x in (0.0, -1.0) for y in (0.0, 2.0) for z in (0.0, 3.0)}


def test_a_mirrored_mesh_gets_its_normals_flipped(tmp_path):
    (tmp_path / "t.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
                                    "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    text = ("light { position < 3 3 3 > }\n" + material("albedo color < 1 1 1 > mean_free_path 1")
            + 'mesh { file "t.obj" transform { scale < 1 -1 1 > } material "m" }\n'
            + 'mesh { file "t.obj" material "m" }')
    d = to_mitsuba(parse(text, source=str(tmp_path / "t.scene")), mode="path")
    assert d["mesh_0"].get("flip_normals") is True and "flip_normals" not in d["mesh_1"]


def test_a_mean_free_path_whose_extinction_passes_float32_is_refused_at_its_number():
    with pytest.raises(S.SceneError) as info:
        translucent("albedo color < 1 1 1 > mean_free_path 1e-39")
    assert info.value.line == 2 and "1/mean_free_path passes 3.4028234663852886e+38" in info.value.message


def test_an_extinction_past_float32_is_refused_at_the_subsurface():
    # A density bound that large, with a mean free path the rule accepts.
    with pytest.raises(ValueError) as info:
        translucent("albedo color < 1 1 1 > mean_free_path 1e-30 density color < 1e10 1e10 1e10 >")
    assert (info.value.line, info.value.column) == (2, 16) and "float32" in info.value.message


# --------------------------------------------------------------------------
#  path mode: loaded and rendered
# --------------------------------------------------------------------------


def test_the_translucent_scene_exports_its_medium_inside_its_shape():
    from mimarble.tools.export import to_xml
    xml = to_xml(translucent("albedo color < 1 1 1 > mean_free_path 1"))
    shape = xml[xml.index('<shape type="sphere"'):xml.index("</shape>")]
    assert '<medium type="marble_medium" name="interior">' in shape
    assert '<bsdf type="subsurface_boundary" name="bsdf">' in shape


def test_point_lights_reach_the_inside_through_the_subsurface_boundary(llvm):
    # volpath connects the walk to the lights where it leaves (docs/rendering-model.md,
    # "Translucent materials"), at ior 1 too: under one point light alone the sphere is
    # lit, and a sky adds to it.
    import mimarble
    text = ('image { width 16 height 16 }\ncamera { eye < 0 0 6 > }\n'
            'light { position < 3 3 3 > }\nSKY'
            'material "m" { subsurface { albedo color < 0.9 0.9 0.9 > mean_free_path 0.2 ior IOR } }\n'
            'sphere { material "m" }\n')
    for ior in ("1.5", "1"):
        scene = text.replace("IOR", ior)
        alone = mimarble.render(parse(scene.replace("SKY", "")), mode="path", spp=16, seed=1)
        lit = mimarble.render(parse(scene.replace("SKY", "ambient < 1 1 1 >\n")), mode="path",
                              spp=16, seed=1)
        assert np.isfinite(alone).all() and alone.mean() > 0.01, ior
        assert np.isfinite(lit).all() and lit.mean() > alone.mean() + 0.05, ior
