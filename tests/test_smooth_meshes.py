"""Smooth meshes (issue 42, item 1): ``mesh { … smooth true|false }``, the file's vertex
normals by default, both renderers interpolating the same normals.

A lathe vase (tests/lathe.py: a profile turned about +y, written as PLY and OBJ with and
without normals) is the subject. What is independent of the code under test:

* the reference tracer's normals (its own code, reference/vertex_normals.py) against
  the ones Mitsuba computes and loads (``mi.traverse``'s ``vertex_normals``), and both
  renderers' images against each other (``compare``'s PSNR, ≥ 60 dB as meshes do);
* the look: on the vase's widest row the luminance falls monotonically away from the
  highlight, and no step between neighbouring pixels is a facet's edge (a jump several
  times its neighbours' steps) — which the same vase shaded flat fails, so the measure can
  fail;
* refusals: one sentence at the file string (or the word), exit 2, nothing written.
"""

import numpy as np
import pytest

import mimarble
from mimarble import reference
from mimarble import scene as scene_language
from mimarble.meshes.arrays import read_mesh
from mimarble.mitsuba.translate.scene_dict import to_mitsuba
from mimarble.reference.vertex_normals import angle_weighted_normals, placed_normals
from mimarble.scene import SceneError, parse
from mimarble.tools import bake, export
from mimarble.tools.compare import image_metrics

import lathe
from commands import mimarble_cli

mi = mimarble.mi

#: The mesh statement's line in lathe.scene_text and its file string's column.
MESH_LINE, FILE_COLUMN = 6, 13


@pytest.fixture(scope="module")
def vases(tmp_path_factory):
    """The vase's files: v.ply (no normals), vn.ply (normals), vn.obj, vt.obj, vtn.obj."""
    folder = tmp_path_factory.mktemp("vases")
    positions, normals, triangles = lathe.vase()
    lathe.write_ply(folder / "v.ply", positions, triangles)
    lathe.write_ply(folder / "vn.ply", positions, triangles, normals)
    lathe.write_obj(folder / "vn.obj", positions, triangles, normals)
    lathe.write_obj(folder / "vt.obj", positions, triangles, uv=True)
    lathe.write_obj(folder / "vtn.obj", positions, triangles, normals, uv=True)
    return folder


def load(folder, mesh, smooth="", size=64, extra=""):
    path = folder / f"{mesh}-{len(smooth)}-{len(extra)}.scene"
    path.write_text(lathe.scene_text(mesh, smooth, size, extra))
    return scene_language.load(str(path))


SMOOTH_CASES = {
    "computed normals": ("v.ply", "smooth true", ""),
    "the PLY's normals": ("vn.ply", "", ""),
    "the OBJ's normals": ("vn.obj", "", ""),
    # normals carried by the inverse transpose: a non-uniform scale, a rotation
    "the PLY's normals, scaled": ("vn.ply", "", "transform { scale < 1.3 0.7 1 > "
                                                "rotate < 0 20 0 > translate < 0 0.3 0 > }"),
    "computed normals, scaled": ("v.ply", "smooth true", "transform { scale < 1.3 0.7 1 > "
                                                         "rotate < 0 20 0 > }"),
}


@pytest.mark.parametrize("case", sorted(SMOOTH_CASES))
def test_a_smooth_vase_has_no_facet_bands_and_agrees_with_the_reference(llvm, vases, case):
    mesh, smooth, extra = SMOOTH_CASES[case]
    scene = load(vases, mesh, smooth, extra=extra)
    image = mimarble.render(scene)
    assert image_metrics(image, reference.render(scene))["psnr"] >= 60.0
    profile = lathe.belly_profile(image)
    assert len(profile) > 20
    assert lathe.steps_against_the_slope(profile) <= 1e-6
    assert lathe.band_ratio(profile) < 3.0


@pytest.mark.parametrize("mesh, smooth", [("v.ply", ""), ("vn.ply", "smooth false"),
                                          ("vn.obj", "smooth false")])
def test_the_same_vase_shaded_flat_shows_its_facets(llvm, vases, mesh, smooth):
    scene = load(vases, mesh, smooth)
    image = mimarble.render(scene)
    assert image_metrics(image, reference.render(scene))["psnr"] >= 60.0
    assert lathe.band_ratio(lathe.belly_profile(image)) > 10.0


@pytest.mark.parametrize("mesh, smooth, face_normals", [
    ("v.ply", "", True), ("v.ply", "smooth true", False), ("v.ply", "smooth false", True),
    ("vn.ply", "", False), ("vn.ply", "smooth false", True), ("vn.obj", "", False),
    ("vt.obj", "", True)])
def test_the_default_is_the_files_normals_and_whitted_shades_with_them(vases, mesh, smooth,
                                                                       face_normals):
    scene_dict = to_mitsuba(load(vases, mesh, smooth))
    assert scene_dict["mesh_0"]["face_normals"] is face_normals
    assert scene_dict["integrator"].get("shading_normals", False) is (not face_normals)


def world_positions(path, matrix):
    data = read_mesh(path)
    return data.positions @ matrix[:3, :3].T + matrix[:3, 3], data


def mitsuba_corner_normals(path, matrix):
    """The vertex normal at each triangle corner (T, 3, 3) of the file as Mitsuba loads it
    with ``face_normals`` false (corners, not vertices: an OBJ's vertices are numbered in
    another order there)."""
    shape = mi.load_dict({"type": path.suffix[1:], "filename": str(path),
                          "face_normals": False,
                          "to_world": mi.ScalarTransform4f(matrix.tolist())})
    params = mi.traverse(shape)
    normals = np.array(params["vertex_normals"], dtype=np.float64).reshape(-1, 3)
    return normals[np.array(params["faces"], dtype=np.int64).reshape(-1, 3)]


MATRIX = np.array([[1.3, 0.2, 0.0, 0.1], [0.0, 0.7, 0.1, -0.2], [0.3, 0.0, 1.1, 0.0],
                   [0.0, 0.0, 0.0, 1.0]])


def test_the_references_computed_normals_are_the_ones_mitsuba_computes(llvm, vases):
    world, data = world_positions(vases / "v.ply", MATRIX)
    ours = angle_weighted_normals(world, data.triangles)[data.triangles]
    np.testing.assert_allclose(mitsuba_corner_normals(vases / "v.ply", MATRIX), ours, atol=2e-6)


@pytest.mark.parametrize("mesh", ["vn.ply", "vn.obj"])
def test_the_references_placed_normals_are_the_ones_mitsuba_loads(llvm, vases, mesh):
    world, data = world_positions(vases / mesh, MATRIX)
    ours = placed_normals(data.normals, MATRIX)[data.triangles]
    np.testing.assert_allclose(mitsuba_corner_normals(vases / mesh, MATRIX), ours, atol=2e-6)


def test_a_vertex_no_triangle_gives_a_direction_gets_mitsubas_stand_in():
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5]], dtype=np.float64)
    normals = angle_weighted_normals(positions, np.array([[0, 1, 2]]))
    np.testing.assert_array_equal(normals, [[0, 0, 1], [0, 0, 1], [0, 0, 1], [1, 0, 0]])


def ply_text(vertex_lines, normal_type="float"):
    head = ["ply", "format ascii 1.0", "element vertex 3", "property float x",
            "property float y", "property float z", f"property {normal_type} nx",
            f"property {normal_type} ny", f"property {normal_type} nz", "element face 1",
            "property list uchar int vertex_indices", "end_header"]
    return "\n".join(head + vertex_lines + ["3 0 1 2"]) + "\n"


GOOD = ["0 0 0 0 0 1", "1 0 0 0 0 1", "0 1 0 0 0 1"]

REFUSED = {
    "a NaN normal": ("bad.ply", ply_text(GOOD[:2] + ["0 1 0 nan 0 1"]), "",
                     "a vertex normal is not finite"),
    "a zero normal": ("bad.ply", ply_text(GOOD[:2] + ["0 1 0 0 0 0"]), "",
                      "a vertex normal (0 0 0) has no direction"),
    "a normal too short for float32": ("bad.ply", ply_text(GOOD[:2] + ["0 1 0 1e-20 0 0"]),
                                       "", "has no direction"),
    # Mitsuba's float32 |n|² overflows: (1e30, 0, 0) loads as (0, 0, 0) there
    "a normal too long for float32": ("bad.ply", ply_text(GOOD[:2] + ["0 1 0 1e30 0 0"]),
                                      "", "a vertex normal (1e+30 0 0) is too long"),
    "an OBJ vn too long for float32": (
        "bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 -2e19 0\nf 1//1 2//1 3//1\n",
        "smooth true", "line 4: a vertex normal (0 -2e+19 0) is too long"),
    "integer normals": ("bad.ply", ply_text(["0 0 0 0 0 1", "1 0 0 0 0 1", "0 1 0 0 0 1"],
                                            "int"), "", "normals are float or double"),
    "an OBJ zero vn": ("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nf 1//1 2//1 3//1\n",
                       "", "line 4: a vertex normal (0 0 0) has no direction"),
    "an OBJ face without normals, smooth": (
        "bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\nf 1 2 3\n",
        "smooth true", "line 6: a face whose corners name no normal"),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_bad_normals_are_refused_at_the_file_string(tmp_path, case):
    name, text, smooth, words = REFUSED[case]
    (tmp_path / name).write_text(text)
    with pytest.raises(SceneError) as info:
        parse(lathe.scene_text(name, smooth), str(tmp_path / "s.scene"))
    assert (info.value.line, info.value.column) == (MESH_LINE, FILE_COLUMN)
    assert info.value.message.startswith(f"mesh file '{name}': ")
    assert words in info.value.message, info.value.message


def test_the_normal_limits_are_where_mitsubas_float32_normalisation_holds(llvm, tmp_path):
    """The limits' reason, measured on Mitsuba itself: normals at MIN_NORMAL and at
    MAX_NORMAL load as unit vectors, one whose |n|² overflows float32 as zero (the reader
    refuses it: the reference's float64 normal would be a unit vector)."""
    from mimarble.meshes.limits import MAX_NORMAL, MIN_NORMAL

    def loaded(nx):
        path = tmp_path / "n.ply"
        path.write_text(ply_text(GOOD[:2] + [f"0 1 0 {nx!r} 0 0"], "double"))
        shape = mi.load_dict({"type": "ply", "filename": str(path), "face_normals": False})
        return np.array(mi.traverse(shape)["vertex_normals"], dtype=np.float64)[6:9]

    for nx in (MIN_NORMAL, MAX_NORMAL, -MAX_NORMAL):
        np.testing.assert_array_equal(loaded(nx), [np.sign(nx), 0, 0])
    np.testing.assert_array_equal(loaded(1e30), [0, 0, 0])


def test_an_obj_whose_faces_lack_normals_is_shaded_flat_by_default(tmp_path):
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1 2 3\n")
    scene = parse(lathe.scene_text("m.obj"), str(tmp_path / "s.scene"))
    assert to_mitsuba(scene)["mesh_0"]["face_normals"] is True


@pytest.mark.parametrize("value, found", [("yes", "'yes'"), ("1", "number 1"),
                                          ('"true"', 'string "true"')])
def test_smooth_takes_true_or_false_only(tmp_path, vases, value, found):
    with pytest.raises(SceneError) as info:
        parse(lathe.scene_text(str(vases / "v.ply"), f"smooth {value}"),
              str(tmp_path / "s.scene"))
    assert info.value.message == f"smooth is true or false, found {found}"
    assert info.value.line == MESH_LINE


def test_a_python_built_smooth_mesh_with_incomplete_normals_is_refused_by_both(llvm, tmp_path):
    import dataclasses
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1 2 3\n")
    flat = parse(lathe.scene_text("m.obj"), str(tmp_path / "s.scene"))
    smooth = dataclasses.replace(flat, meshes=(dataclasses.replace(flat.meshes[0],
                                                                   smooth=True),))
    for attempt in (to_mitsuba, reference.render):
        with pytest.raises(SceneError, match="a face whose corners name no normal"):
            attempt(smooth)


def test_the_command_refuses_a_nan_normal_in_one_sentence_and_writes_nothing(tmp_path):
    (tmp_path / "bad.ply").write_text(ply_text(GOOD[:2] + ["0 1 0 0 nan 1"]))
    (tmp_path / "s.scene").write_text(lathe.scene_text("bad.ply", "smooth true"))
    result = mimarble_cli("render", tmp_path / "s.scene", "-o", tmp_path / "out.png")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    first = result.stderr.splitlines()[0]          # then the line and a caret, as every
    assert first.endswith(f"s.scene:{MESH_LINE}:{FILE_COLUMN}: mesh file 'bad.ply': a "
                          f"vertex normal is not finite")          # error at a position
    assert not (tmp_path / "out.png").exists()


@pytest.mark.parametrize("mesh, smooth, tolerance", [
    ("vn.ply", "", 0.0),
    # Mitsuba sums computed normals with atomic adds in JIT variants: two loads of one
    # file may differ in the last bit of a normal (docs/design-decisions.md)
    ("v.ply", "smooth true", 1e-5)])
def test_export_writes_the_smooth_mesh_and_it_renders_as_the_dict(llvm, vases, tmp_path, mesh,
                                                                  smooth, tolerance):
    scene_dict = to_mitsuba(load(vases, mesh, smooth, size=24))
    xml = export.to_xml(scene_dict, tmp_path)
    assert '<boolean name="face_normals" value="false"/>' in xml
    assert '<boolean name="shading_normals" value="true"/>' in xml
    (tmp_path / "scene.xml").write_text(xml, encoding="utf-8")
    from test_export import with_xml_inverses
    np.testing.assert_allclose(
        np.array(mi.render(mi.load_file(str(tmp_path / "scene.xml")), seed=0)),
        np.array(mi.render(mi.load_dict(with_xml_inverses(scene_dict)), seed=0)),
        rtol=0.0, atol=tolerance)


def test_an_objs_normals_leave_its_texture_coordinates_and_bake_as_they_were(vases):
    """The OBJ reader keys vertices on (v, vt, vn) as Mitsuba does: the normals split no
    texture coordinate, so a baked texture is the same with them and without."""
    scenes = []
    for mesh in ("vtn.obj", "vt.obj"):
        text = lathe.scene_text(mesh).replace("diffuse { color < 0.7 0.7 0.7 > }",
                                              "diffuse { marble { scale 3 octaves 4 } }")
        scenes.append(parse(text, str(vases / "marble.scene")))
    assert to_mitsuba(scenes[0])["mesh_0"]["face_normals"] is False
    baked = [bake.bake_image(scene, "mesh_0", size=32, channel="diffuse") for scene in scenes]
    assert np.ptp(baked[0]) > 0.1                    # a pattern, not one colour
    np.testing.assert_array_equal(baked[0], baked[1])


@pytest.mark.parametrize("ranges", [(50, 41, 31), (1 << 21, 1 << 21, 1 << 21)])
def test_an_objs_corners_become_vertices_as_numpys_unique_rows_make_them(ranges):
    """Both ways the OBJ reader numbers its (v, vt, vn) triples — one int64 key, or a sort
    where the key would overflow — give np.unique's rows and inverse."""
    from mimarble.meshes.arrays import _distinct_rows
    rng = np.random.default_rng(7)
    triples = np.stack([rng.integers(0, ranges[0], 5000), rng.integers(-1, ranges[1] - 1, 5000),
                        rng.integers(-1, ranges[2] - 1, 5000)], axis=1)
    rows, inverse = _distinct_rows(triples, ranges)
    expected_rows, expected_inverse = np.unique(triples, axis=0, return_inverse=True)
    np.testing.assert_array_equal(rows, expected_rows)
    np.testing.assert_array_equal(inverse, expected_inverse.reshape(-1))
