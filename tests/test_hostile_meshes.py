"""Hostile and careless mesh files (issue 38, third pass; issue 37 item 1): overlapping
triangles in the reference's hierarchy, mesh files rewritten in place, every route into
Mitsuba checked as the parser checks, and one rule for what both renderers read.

The files are the tests' own, written here; what each test compares against is computed
another way (the hits of stacked planes by hand, a render from nothing kept, SHA-256 of the
bytes written, Mitsuba's own loader).
"""

from __future__ import annotations

import hashlib
import os
import tracemalloc

import numpy as np
import pytest

from mimarble.reference import triangles
from mimarble.reference.triangles import TriangleBVH

# ---------------------------------------------------------------------------
# 38.1: the reference's traversal, bounded whatever the overlap


def stacked_squares(count, step=1e-6):
    """``count`` unit squares' lower-right triangles stacked along z (triangle k at z =
    k·step): every box of the hierarchy overlaps every other, as in a file of one face
    written again and again — but no two are the same triangle (none is dropped as a
    copy)."""
    z = np.arange(count) * step
    v0 = np.stack([np.zeros(count), np.zeros(count), z], axis=1)
    v1 = np.stack([np.ones(count), np.zeros(count), z], axis=1)
    v2 = np.stack([np.ones(count), np.ones(count), z], axis=1)
    return v0, v1, v2


def rays_down(count, seed):
    """Rays straight down (−z) from z = 1 through points inside every triangle."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.2, 0.95, count)
    y = rng.uniform(0.0, 1.0, count) * (x - 0.1)          # y < x: inside (0,0)-(1,0)-(1,1)
    o = np.stack([x, y, np.ones(count)], axis=1)
    return o, np.tile([0.0, 0.0, -1.0], (count, 1))


def test_overlapping_triangles_are_traversed_in_bounded_memory(monkeypatch):
    """2¹² stacked triangles, 2048 rays, each ray meeting every box: the frontier of every
    (ray, node) pair met would be 2048 × 2¹¹ ≈ 4·10⁶ pairs (over 100 MB); in chunks of
    FRONTIER pairs it is at most (depth + 1)·FRONTIER pairs. The hit is the top triangle,
    known by construction."""
    count, rays = 1 << 12, 2048
    monkeypatch.setattr(triangles, "FRONTIER", 1 << 12)
    monkeypatch.setattr(triangles, "LEAF_PAIRS", 1 << 10)
    bvh = TriangleBVH(*stacked_squares(count))
    o, d = rays_down(rays, seed=5)
    tracemalloc.start()
    t, index, _, _ = bvh.closest(o, d, 0.0)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    np.testing.assert_array_equal(index, count - 1)
    np.testing.assert_allclose(t, 1.0 - (count - 1) * 1e-6, rtol=1e-12)
    # (depth + 1)·FRONTIER pairs of two int64, the slab test's and the triangle tests'
    # working arrays: a few MB, against the > 100 MB of the whole frontier
    assert peak < 16e6, peak


def test_any_hit_among_overlapping_triangles_in_bounded_memory(monkeypatch):
    count = 1 << 12
    monkeypatch.setattr(triangles, "FRONTIER", 1 << 12)
    bvh = TriangleBVH(*stacked_squares(count))
    o, d = rays_down(2048, seed=6)
    t_max = np.where(np.arange(2048) % 2 == 0, 2.0, 0.5)     # half stop above the stack
    tracemalloc.start()
    blocked = bvh.any_hit(o, d, t_max)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    np.testing.assert_array_equal(blocked, np.arange(2048) % 2 == 0)
    assert peak < 16e6, peak


def test_copies_of_one_triangle_are_held_once_and_the_lowest_index_is_hit():
    """2¹⁶ copies of one face after a different triangle (index 0, below it): the
    hierarchy holds the two distinct triangles; a ray from above hits copy 1 (the lowest
    index of the copies, as a brute force argmin over all would), one from below index 0."""
    copies = 1 << 16
    v0 = np.array([[0.0, 0.0, -1.0]] + [[0.0, 0.0, 0.0]] * copies)
    v1 = np.array([[1.0, 0.0, -1.0]] + [[1.0, 0.0, 0.0]] * copies)
    v2 = np.array([[1.0, 1.0, -1.0]] + [[1.0, 1.0, 0.0]] * copies)
    bvh = TriangleBVH(v0, v1, v2)
    assert bvh.count == 2
    o = np.array([[0.75, 0.25, 1.0], [0.75, 0.25, -2.0]])
    d = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
    t, index, b1, b2 = bvh.closest(o, d, 0.0)
    assert index.tolist() == [1, 0] and t.tolist() == [1.0, 1.0]
    assert (b1.tolist(), b2.tolist()) == ([0.5, 0.5], [0.25, 0.25])


# ---------------------------------------------------------------------------
# 38.8 (and issue 37 item 1): a mesh file rewritten in place is seen

QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf {face}\n"
MESH_SCENE = """
image    { width 16 height 16 samples 1 }
camera   { eye < 0.5 0.5 3 > lookat < 0.5 0.5 0 > up < 0 1 0 > fov 30 }
ambient  < 0.3 0.3 0.3 >
light    { position < 1 2 5 > color < 1 1 1 > }
material "m" { ambient { color < 1 0.5 0.2 > } diffuse { color < 0.6 0.6 0.6 > } }
mesh { file "quad.obj" material "m" }
"""


def quad_scene(tmp_path, face="1 2 3"):
    """A scene file over ``quad.obj``: one triangle of a unit square, the lower-right
    (1 2 3) or the upper-left (1 3 4) — the same size, counts and bounds."""
    (tmp_path / "quad.obj").write_text(QUAD.format(face=face))
    path = tmp_path / "s.scene"
    path.write_text(MESH_SCENE)
    return path


def rewrite_keeping_times(path, text):
    """``path`` rewritten in place with ``text`` (as long as before), its access and
    modification times put back as ``touch -r`` would."""
    facts = os.stat(path)
    with open(path, "r+") as f:
        f.write(text)
    assert os.stat(path).st_size == facts.st_size
    os.utime(path, ns=(facts.st_atime_ns, facts.st_mtime_ns))


def render_from_nothing_kept(path):
    """The image of the scene file as a first render: nothing loaded or parsed kept."""
    import mimarble
    from mimarble.mitsuba.rendering.loaded_scenes import LOADED
    from mimarble.scene import parser
    LOADED.clear()
    parser._PARSED.clear()
    image = mimarble.render(str(path))
    LOADED.clear()
    return image


def test_a_mesh_rewritten_with_its_old_times_is_seen_by_a_second_render(llvm, tmp_path):
    import mimarble
    path = quad_scene(tmp_path)
    before = mimarble.render(str(path))
    rewrite_keeping_times(tmp_path / "quad.obj", QUAD.format(face="1 3 4"))
    after = mimarble.render(str(path))
    assert not np.array_equal(before, after)
    np.testing.assert_array_equal(after, render_from_nothing_kept(path))


def test_a_model_rendered_again_after_its_mesh_file_changed_renders_the_new_file(llvm,
                                                                               tmp_path):
    """No parse in between: the loaded scene is keyed by the mesh file's size, times and
    inode, as image maps are (the change time moves whatever the modification time)."""
    import mimarble
    from mimarble import scene as scene_language
    path = quad_scene(tmp_path)
    model = scene_language.load(path)
    before = mimarble.render(model)
    rewrite_keeping_times(tmp_path / "quad.obj", QUAD.format(face="1 3 4"))
    after = mimarble.render(model)
    assert not np.array_equal(before, after)
    np.testing.assert_array_equal(after, render_from_nothing_kept(path))


def test_two_parses_of_a_rewritten_mesh_file_are_two_models(tmp_path):
    """The parser's model carries the SHA-256 of the file it read: the same scene text
    over a rewritten mesh (same counts, bounds, size and modification time) is another
    model, for every cache keyed by the model."""
    from mimarble import scene as scene_language
    path = quad_scene(tmp_path)
    first = scene_language.load(path)
    rewrite_keeping_times(tmp_path / "quad.obj", QUAD.format(face="1 3 4"))
    second = scene_language.load(path)
    assert first != second
    digests = [hashlib.sha256(QUAD.format(face=f).encode()).hexdigest()
               for f in ("1 2 3", "1 3 4")]
    assert [first.meshes[0].digest, second.meshes[0].digest] == digests


# ---------------------------------------------------------------------------
# 38.11: one check of mesh files for every route into Mitsuba

TRIANGLE_OBJ = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n"
BAD_MESHES = {
    "face past the vertices (obj)": ("m.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 9\n"),
    "face past the vertices (ply)": ("m.ply", "ply\nformat ascii 1.0\nelement vertex 3\n"
                                     "property float x\nproperty float y\nproperty float z\n"
                                     "element face 1\nproperty list uchar int vertex_indices\n"
                                     "end_header\n0 0 0\n1 0 0\n1 1 0\n3 0 1 7\n"),
    "a polygon (ply)": ("m.ply", "ply\nformat ascii 1.0\nelement vertex 4\n"
                        "property float x\nproperty float y\nproperty float z\n"
                        "element face 1\nproperty list uchar int vertex_indices\n"
                        "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n"),
    "not a number (obj)": ("m.obj", "v 0 0 nan\nv 1 0 0\nv 1 1 0\nf 1 2 3\n"),
    "no faces (obj)": ("m.obj", ""),
}
MATERIAL = 'material "m" { diffuse { color < 0.6 0.6 0.6 > } }\n'


def python_built(mesh_file, material=None):
    from mimarble import scene as S
    return S.Scene(image=S.Image(16, 16), camera=S.Camera(eye=(0.5, 0.5, 3.0),
                                                          lookat=(0.5, 0.5, 0.0)),
                   lights=(S.Light((1.0, 2.0, 5.0)),),
                   materials={"m": material or S.Material("m", diffuse=S.ColorChannel((0.6,) * 3))},
                   meshes=(S.Mesh("m", str(mesh_file)),))


def parser_sentence(tmp_path, name):
    """What the parser says of the mesh file ``name`` in tmp_path (its sentence, no place)."""
    from mimarble.scene import SceneError, parse
    with pytest.raises(SceneError) as info:
        parse(MATERIAL + f'mesh {{ file "{name}" material "m" }}', "s.scene",
              source=str(tmp_path / "s.scene"))
    return info.value.message


@pytest.mark.parametrize("case", sorted(BAD_MESHES))
def test_a_python_built_scene_hears_the_parsers_sentence_about_its_mesh_file(llvm, tmp_path,
                                                                          monkeypatch, case):
    import mimarble
    from mimarble.scene import SceneError
    name, text = BAD_MESHES[case]
    (tmp_path / name).write_text(text)
    monkeypatch.chdir(tmp_path)              # a Python-built mesh's file is from here
    want = parser_sentence(tmp_path, name)
    assert want.startswith(f"mesh file '{name}': ")
    with pytest.raises(SceneError) as info:
        mimarble.render(python_built(name))
    assert info.value.message == want


@pytest.mark.parametrize("case", sorted(BAD_MESHES))
def test_a_mesh_file_broken_after_load_is_refused_in_the_parsers_sentence(llvm, tmp_path, case):
    import mimarble
    from mimarble import scene as scene_language
    from mimarble.scene import SceneError
    name, text = BAD_MESHES[case]
    (tmp_path / name).write_text(TRIANGLE_OBJ if name.endswith(".obj") else
                                 BAD_MESHES["a polygon (ply)"][1].replace(
                                     "element face 1", "element face 2").replace(
                                     "4 0 1 2 3", "3 0 1 2\n3 0 2 3"))
    (tmp_path / "s.scene").write_text(MESH_SCENE.replace("quad.obj", name))
    model = scene_language.load(tmp_path / "s.scene")
    mimarble.render(model)
    (tmp_path / name).write_text(text)
    with pytest.raises(SceneError) as info:
        mimarble.render(model)
    assert info.value.message == parser_sentence(tmp_path, name)
    assert (info.value.filename, info.value.line) == (str(tmp_path / "s.scene"), 7)


def test_an_image_map_on_a_python_built_mesh_without_uv_is_refused(llvm, tmp_path):
    import mimarble
    from PIL import Image
    from mimarble import scene as S
    from mimarble.scene import SceneError
    (tmp_path / "m.obj").write_text(TRIANGLE_OBJ)
    Image.new("RGB", (4, 4), (200, 10, 10)).save(tmp_path / "map.png")
    material = S.Material("m", diffuse=S.ImageChannel(str(tmp_path / "map.png")))
    with pytest.raises(SceneError, match="image map.*this mesh's file"):
        mimarble.render(python_built(tmp_path / "m.obj", material))


# ---------------------------------------------------------------------------
# 38.12, 38.13, 38.26: one rule for what both renderers read — refused at parse, at the
# mesh's file string, or read alike by Mitsuba 3.9.1's loaders and the reference's reader

def ply(body, vertex="property float x\nproperty float y\nproperty float z\n", face="",
        head="", tail="", fmt="ascii"):
    return (f"ply\nformat {fmt} 1.0\n{head}element vertex 3\n{vertex}element face 1\n"
            f"property list uchar int vertex_indices\n{face}{tail}end_header\n{body}").encode(
        "latin-1")


XYZ = "0 0 0\n1 0 0\n1 1 0\n"
REFUSED = {
    # PLY: what Mitsuba's ply plugin refuses or misreads, and the reference read
    "obj_info line": ("m.ply", ply(XYZ + "3 0 1 2\n", head="obj_info made by hand\n"),
                      "PLY header line 3: unknown keyword 'obj_info'"),
    "face index written 2e0": ("m.ply", ply(XYZ + "3 0 1 2e0\n"),
                               "the int value '2e0' is not written as a whole number"),
    "face length written 3.0": ("m.ply", ply(XYZ + "3.0 0 1 2\n"),
                                "the uchar value '3.0' is not written as a whole number"),
    "two lists on a face": ("m.ply", ply(XYZ + "3 0 1 2 3 2 1 0\n",
                                         face="property list uchar int other\n"),
                            "the PLY element 'face' has the list property 'other'"),
    "a list on the vertices": ("m.ply", ply("0 0 0 1 5\n1 0 0 1 5\n1 1 0 1 5\n3 0 1 2\n",
                                            vertex="property float x\nproperty float y\n"
                                                   "property float z\nproperty list uchar "
                                                   "float q\n"),
                               "the PLY element 'vertex' has the list property 'q'"),
    "a list on another element": ("m.ply", ply(XYZ + "3 0 1 2\n2 7 7\n",
                                               tail="element junk 1\nproperty list uchar int q\n"),
                                  "the PLY element 'junk' has the list property 'q'"),
    "half 70000": ("m.ply", ply("70000 0 0\n1 0 0\n1 1 0\n3 0 1 2\n",
                                vertex="property half x\nproperty float y\nproperty float z\n"),
                   "a vertex coordinate 70000 is beyond a half's range"),
    "half 65520 in a skipped property": ("m.ply", ply(
        "0 0 0 65520\n1 0 0 1\n1 1 0 1\n3 0 1 2\n",
        vertex="property float x\nproperty float y\nproperty float z\nproperty half w\n"),
        "a half value 65520 is beyond a half's range"),
    "uchar 256": ("m.ply", ply("0 0 0 256\n1 0 0 1\n1 1 0 1\n3 0 1 2\n",
                               vertex="property float x\nproperty float y\nproperty float z\n"
                                      "property uchar q\n"),
                  "the uchar value 256 is outside a uchar's range"),
    "short 40000": ("m.ply", ply("0 0 0 40000\n1 0 0 1\n1 1 0 1\n3 0 1 2\n",
                                 vertex="property float x\nproperty float y\nproperty float z\n"
                                        "property short q\n"),
                    "the short value 40000 is outside a short's range"),
    "vertex properties u s t": ("m.ply", ply("0 0 0 .1 .2 .3\n1 0 0 .4 .5 .6\n1 1 0 .7 .8 .9\n"
                                             "3 0 1 2\n",
                                             vertex="property float x\nproperty float y\n"
                                                    "property float z\nproperty float u\n"
                                                    "property float s\nproperty float t\n"),
                                "the PLY vertex element has a property u without its pair beside s "
                                "and t"),
    "vertex properties v texture_u texture_v": ("m.ply", ply(
        "0 0 0 .1 .2 .3\n1 0 0 .4 .5 .6\n1 1 0 .7 .8 .9\n3 0 1 2\n",
        vertex="property float x\nproperty float y\nproperty float z\nproperty float v\n"
               "property float texture_u\nproperty float texture_v\n"),
        "the PLY vertex element has a property v without its pair beside texture_u and "
        "texture_v"),
    "a header word split at \\x1c": ("m.ply", ply(XYZ + "3 0 1 2\n").replace(
        b"element face", b"element\x1cface"),
        "PLY header line 7: unknown keyword 'element\x1cface'"),
    # OBJ: lines Mitsuba's OBJ reader drops or refuses, which the reference read
    "a form feed after v": ("m.obj", b"v\x0c0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\n",
                            "line 1: a form feed, vertical tab or carriage return"),
    "a vertical tab between numbers": ("m.obj", b"v 0 0 0\nv 1\x0b0 0\nv 1 1 0\nf 1 2 3\n",
                                       "line 2: a form feed, vertical tab or carriage return"),
    "a bare carriage return between numbers": ("m.obj", b"v 0 0 0\nv 1\r0 0\nv 1 1 0\nf 1 2 3\n",
                                               "line 2: a form feed, vertical tab or carriage"),
    "a carriage return in a face": ("m.obj", b"v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2\r3\n",
                                    "line 4: a form feed, vertical tab or carriage return"),
    "a comment right after a face": ("m.obj", b"v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3#c\n",
                                     "line 4: a comment (#) right after a face's last corner"),
    "a byte order mark before v": ("m.obj", b"\xef\xbb\xbfv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                                   b"f 1 2 3\n", "line 1: the file begins with a UTF-8 byte "
                                                 "order mark"),
    "a byte order mark before f": ("m.obj", b"\xef\xbb\xbf  f 1 2 3\n", "line 1: the file "
                                   "begins with a UTF-8 byte order mark"),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_a_mesh_file_mitsuba_would_refuse_or_misread_is_refused_at_its_file_string(tmp_path,
                                                                                  case):
    from mimarble.scene import SceneError, parse
    name, data, words = REFUSED[case]
    (tmp_path / name).write_bytes(data)
    with pytest.raises(SceneError) as info:
        parse(MATERIAL + f'mesh {{ material "m" file "{name}" }}', str(tmp_path / "s.scene"))
    error = info.value
    assert (error.line, error.column) == (2, 26)                  # the file string
    assert error.message.startswith(f"mesh file '{name}': {words}"), error.message


READ_ALIKE = {
    # what both read: positions of the one triangle (0, 1, 2), as Mitsuba holds them
    "an element of no properties and no records": ("m.ply", ply(
        XYZ + "3 0 1 2\n", tail="element junk 0\n"), None),
    "two of them, one first": ("m.ply", ply(XYZ + "3 0 1 2\n", head="element none 0\n",
                                            tail="element junk 0\n"), None),
    "binary, with an empty element": ("m.ply", ply(
        b"".join(np.array(v, "<f4").tobytes() for v in ([0, 0, 0], [1, 0, 0], [1, 1, 0])).decode(
            "latin-1") + "\x03" + np.array([0, 1, 2], "<i4").tobytes().decode("latin-1"),
        tail="element junk 0\n", fmt="binary_little_endian"), None),
    "half 65519 and 0.1": ("m.ply", ply("65519 0 0\n0.1 0 0\n1 1 0\n3 0 1 2\n",
                                        vertex="property half x\nproperty float y\n"
                                               "property float z\n"), None),
    "indices written +1 and 03": ("m.ply", ply(XYZ + "03 0 +1 2\n"), None),
    "a comment after a space": ("m.obj", b"v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3 # c\n", None),
    "CRLF lines": ("m.obj", b"v 0 0 0\r\nv 1 0 0\r\nv 1 1 0\r\nf 1 2 3\r\n", None),
    "a byte order mark before a comment": ("m.obj", b"\xef\xbb\xbf# made by hand\nv 0 0 0\n"
                                           b"v 1 0 0\nv 1 1 0\nf 1 2 3\n", None),
}


@pytest.mark.parametrize("case", sorted(READ_ALIKE))
def test_what_the_check_accepts_both_readers_read_alike(llvm, tmp_path, case):
    """Mitsuba's own loader (face normals, as the translator asks) and the reference's
    reader give the same triangles, Mitsuba's float32 positions being the reference's
    rounded."""
    import mitsuba as mi
    from mimarble.meshes.arrays import read_mesh
    from mimarble.meshes.facts import mesh_facts
    name, data, _ = READ_ALIKE[case]
    path = tmp_path / name
    path.write_bytes(data.encode("latin-1") if isinstance(data, str) else data)
    assert mesh_facts(str(path)).triangles == 1
    ours = read_mesh(path, relative=False)
    theirs = mi.traverse(mi.load_dict({"type": path.suffix[1:], "filename": str(path),
                                       "face_normals": True}))
    positions = np.array(theirs["vertex_positions"]).reshape(-1, 3)
    faces = np.array(theirs["faces"]).reshape(-1, 3)
    np.testing.assert_array_equal(positions[faces],
                                  ours.positions[ours.triangles].astype(np.float32))
    if "half" in case:                 # the reference holds the half Mitsuba holds
        assert ours.positions[1, 0] == float(np.float16(0.1)) and ours.positions[0, 0] == 65504


# ---------------------------------------------------------------------------
# 38.10: texture coordinates past float32's precision for image maps: a warning

@pytest.mark.parametrize("extent, warned", [(1e4, True), (3e38, True), (2000.0, True),
                                            (1024.0, False), (0.75, False)])
@pytest.mark.parametrize("kind", ["obj", "ply"])
def test_large_texture_coordinates_under_an_image_map_are_warned_of(llvm, tmp_path, kind,
                                                                    extent, warned):
    """Past 2¹⁰ Mitsuba's float32 (u, v) step by a texel of an 8192-wide map or more
    (np.spacing says how much): a Float32RangeWarning naming the file and the extent."""
    import warnings
    from PIL import Image
    from mimarble import scene as S
    from mimarble.mitsuba.translate.scene_dict import Float32RangeWarning, to_mitsuba
    from mimarble.meshes.limits import MAX_PRECISE_UV
    Image.new("RGB", (4, 4), (200, 10, 10)).save(tmp_path / "map.png")
    if kind == "obj":          # Mitsuba stores (u, 1 − v): the extent is u's
        text = f"v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 1\nvt {extent!r} 1\nvt 0.5 0.5\n" \
               f"f 1/1 2/2 3/3\n"
    else:
        text = ply(f"0 0 0 0 0\n1 0 0 {extent!r} 0\n1 1 0 0.5 0.5\n3 0 1 2\n",
                   vertex="property float x\nproperty float y\nproperty float z\n"
                          "property float u\nproperty float v\n").decode()
    (tmp_path / f"m.{kind}").write_text(text)
    (tmp_path / "s.scene").write_text(
        'material "m" { diffuse { image { file "map.png" } } }\n'
        f'mesh {{ file "m.{kind}" material "m" }}\n')
    scene = S.load(tmp_path / "s.scene")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        to_mitsuba(scene)
    said = [str(w.message) for w in caught if issubclass(w.category, Float32RangeWarning)]
    assert bool(said) == warned, said
    step = np.spacing(np.float32(extent))         # float32's step there: a texel of 8192
    assert (step >= 2.0 ** -13 and extent > MAX_PRECISE_UV) if warned else step <= 2.0 ** -13
    if warned:
        written = float(np.float32(extent)) if kind == "ply" else extent   # a PLY's float
        assert said == [f"{tmp_path / 's.scene'}:2:13: mesh file 'm.{kind}' has texture "
                        f"coordinates up to {written:g}, "
                        f"past ±1024: Mitsuba holds them in float32, whose step there "
                        f"({float(np.spacing(np.float32(extent))):.2g}) reaches a texel of a "
                        f"large image map, so its image may differ from the reference's there "
                        f"(docs/rendering-model.md)"]
