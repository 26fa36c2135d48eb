"""Mesh files: mimarble.meshes.facts (what a file holds, its limits: meshes.limits) and the
renderers' reader (mimarble.meshes.arrays), on small files written here.

The same mesh is written in every encoding by hand (struct for the binary PLYs, text for the
others), so each reader is checked against the triangles it was given, not against another
reader."""

import math
import os
import struct
import tracemalloc

import numpy as np
import pytest

from mimarble.meshes import arrays as mesh_file
from mimarble.meshes.arrays import read_mesh
from mimarble.meshes import facts as meshes_facts
from mimarble.meshes import limits as mesh_limits
from mimarble.meshes import obj_lines
from mimarble.meshes.facts import mesh_facts
from mimarble.meshes.limits import MeshFileError
from mimarble.scene.limits import LIMITS, MAX_MESH_TRIANGLES

# A unit square split into a quad and, beside it, a triangle, each corner with its (u, v) = (x, y).
POSITIONS = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0), (2.0, 0.5, 0.25)]
FACES = [(0, 1, 2, 3), (1, 4, 2)]
#: The fans of FACES, (v0, vi, vi+1), as Mitsuba's OBJ reader makes them.
FANS = [(0, 1, 2), (0, 2, 3), (1, 4, 2)]
#: The same triangles as faces: the PLY files Mitsuba's ply plugin reads (triangles only).
TRIANGLES = FANS


def uv_of(p):
    return (p[0] / 2.0, p[1])


def ply_header(fmt, faces=len(FACES), uv=("u", "v"), extra_vertex="", face_list="vertex_indices"):
    lines = ["ply", f"format {fmt} 1.0", "comment written by the test",
             f"element vertex {len(POSITIONS)}",
             "property float x", "property float y", "property double z"]
    if uv:
        lines += [f"property float {uv[0]}", f"property float {uv[1]}"]
    lines += [extra_vertex] if extra_vertex else []
    lines += [f"element face {faces}", f"property list uchar int {face_list}", "end_header"]
    return "\n".join(lines) + "\n"


def write_ply_ascii(path, uv=("u", "v"), faces=FACES):
    rows = [" ".join(f"{c:g}" for c in p + (uv_of(p) if uv else ())) for p in POSITIONS]
    rows += [" ".join(str(i) for i in (len(f),) + f) for f in faces]
    path.write_text(ply_header("ascii", faces=len(faces), uv=uv) + "\n".join(rows) + "\n")
    return path


def write_ply_binary(path, order, faces=FACES):
    fmt = "binary_little_endian" if order == "<" else "binary_big_endian"
    body = b"".join(struct.pack(order + "ffdff", *p, *uv_of(p)) for p in POSITIONS)
    body += b"".join(struct.pack(f"{order}B{len(f)}i", len(f), *f) for f in faces)
    path.write_bytes(ply_header(fmt, faces=len(faces)).encode() + body)
    return path


def write_obj(path, relative=True):
    """v from 1, vt flipped (Mitsuba stores (u, 1 − v) for ``vt u v``), the quad with
    positive indices, the triangle with negative (relative) ones and normals."""
    lines = ["# the test mesh", "o square"]
    lines += [f"v {p[0]:g} {p[1]:g} {p[2]:g}" for p in POSITIONS]
    lines += [f"vt {uv_of(p)[0]:g} {1.0 - uv_of(p)[1]:g}" for p in POSITIONS]
    lines += ["vn 0 0 1", "s off", "usemtl stone"]
    lines += ["f 1/1/1 2/2/1 3/3/1 4/4/1"]
    lines += ["f -4/-4/-1 -1/-1/-1 -3/-3/-1   # relative" if relative else "f 2/2/1 5/5/1 3/3/1"]
    path.write_text("\n".join(lines) + "\n")
    return path


def corners(mesh):
    """Each triangle as its three corner positions and (u, v): independent of vertex order."""
    return mesh.positions[mesh.triangles], mesh.uv[mesh.triangles]


EXPECTED_POSITIONS = np.array(POSITIONS)[np.array(FANS)]
#: The written positions' least and greatest x, y, z (written exactly in every encoding).
POSITION_BOUNDS = (tuple(min(c) for c in zip(*POSITIONS)), tuple(max(c) for c in zip(*POSITIONS)))
EXPECTED_UV = np.array([uv_of(p) for p in POSITIONS])[np.array(FANS)]


@pytest.mark.parametrize("kind", ["ply-ascii", "ply-le", "ply-be", "obj"])
def test_every_encoding_reads_the_written_fans_and_uv(tmp_path, kind):
    writers = {"ply-ascii": lambda: write_ply_ascii(tmp_path / "m.ply"),
               "ply-le": lambda: write_ply_binary(tmp_path / "m.ply", "<"),
               "ply-be": lambda: write_ply_binary(tmp_path / "m.ply", ">"),
               "obj": lambda: write_obj(tmp_path / "m.obj")}
    mesh = read_mesh(writers[kind]())
    assert mesh.positions.dtype == np.float64 and mesh.triangles.dtype == np.int64
    positions, uv = corners(mesh)
    np.testing.assert_array_equal(positions, EXPECTED_POSITIONS)
    np.testing.assert_allclose(uv, EXPECTED_UV, rtol=0, atol=1e-7)      # written as float32


def test_relative_indices_read_the_same_as_absolute_ones(tmp_path):
    a, b = read_mesh(write_obj(tmp_path / "a.obj")), read_mesh(write_obj(tmp_path / "b.obj", False))
    for x, y in zip(corners(a), corners(b)):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("kind", ["ply-ascii", "ply-le", "ply-be", "obj"])
def test_facts_count_the_written_mesh(tmp_path, kind):
    path = {"ply-ascii": lambda: write_ply_ascii(tmp_path / "m.ply", faces=TRIANGLES),
            "ply-le": lambda: write_ply_binary(tmp_path / "m.ply", "<", faces=TRIANGLES),
            "ply-be": lambda: write_ply_binary(tmp_path / "m.ply", ">", faces=TRIANGLES),
            "obj": lambda: write_obj(tmp_path / "m.obj", relative=False)}[kind]()
    assert mesh_facts(str(path)) == meshes_facts.MeshFacts(
        "obj" if kind == "obj" else "ply", len(POSITIONS), len(FANS), True, POSITION_BOUNDS)


@pytest.mark.parametrize("kind", ["ply-ascii", "ply-le", "ply-be"])
def test_ply_polygons_read_as_fans_but_refused_for_mitsuba(tmp_path, kind):
    """Mitsuba 3.9's ply plugin reads triangles only: the scene language's check refuses
    the quad (the reader's fans are above)."""
    path = {"ply-ascii": lambda: write_ply_ascii(tmp_path / "m.ply"),
            "ply-le": lambda: write_ply_binary(tmp_path / "m.ply", "<"),
            "ply-be": lambda: write_ply_binary(tmp_path / "m.ply", ">")}[kind]()
    np.testing.assert_array_equal(corners(read_mesh(path))[0], EXPECTED_POSITIONS)
    with pytest.raises(MeshFileError) as e:
        mesh_facts(str(path))
    assert str(e.value) == ("a face of 4 vertices: Mitsuba 3.9's ply plugin reads triangles "
                            "only (split the faces into triangles)")


def test_obj_relative_indices_refused_for_mitsuba(tmp_path):
    with pytest.raises(MeshFileError) as e:
        mesh_facts(str(write_obj(tmp_path / "m.obj")))
    assert str(e.value) == ("line 17: a negative (relative) index -4; Mitsuba 3.9's OBJ "
                            "reader takes indices counted from 1 only")


@pytest.mark.parametrize("names", [("s", "t"), ("texture_u", "texture_v")])
def test_ply_texture_coordinates_under_mitsubas_other_names(tmp_path, names):
    mesh = read_mesh(write_ply_ascii(tmp_path / "m.ply", uv=names, faces=TRIANGLES))
    np.testing.assert_allclose(corners(mesh)[1], EXPECTED_UV, rtol=0, atol=1e-7)
    assert mesh_facts(str(tmp_path / "m.ply")).has_uv


def test_ply_without_uv_has_none(tmp_path):
    mesh = read_mesh(write_ply_ascii(tmp_path / "m.ply", uv=None, faces=TRIANGLES))
    assert mesh.uv is None and not mesh_facts(str(tmp_path / "m.ply")).has_uv
    np.testing.assert_array_equal(mesh.positions[mesh.triangles], EXPECTED_POSITIONS)


def test_a_pentagon_is_the_fan_from_its_first_corner(tmp_path):
    path = tmp_path / "p.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nf 1 2 3 4 5\n")
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.positions[mesh.triangles],
                                  mesh.positions[[[0, 1, 2], [0, 2, 3], [0, 3, 4]]])
    assert mesh_facts(str(path)).triangles == 3


def test_binary_ply_with_faces_of_several_sizes(tmp_path):
    """Lists of differing lengths take the record-by-record path; the fans are the same."""
    assert len({len(f) for f in FACES}) > 1
    mesh = read_mesh(write_ply_binary(tmp_path / "m.ply", "<"))
    np.testing.assert_array_equal(mesh.positions[mesh.triangles], EXPECTED_POSITIONS)


def test_obj_vertex_is_a_distinct_position_uv_pair(tmp_path):
    """Two faces sharing a position with different vt make two vertices (Mitsuba's keys)."""
    path = tmp_path / "seam.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 0.5 0.5\n"
                    "f 1/1 2/2 3/3\nf 1/4 3/3 2/2\n")
    mesh = read_mesh(path)
    assert len(mesh.positions) == 4                    # (v1, vt1) and (v1, vt4) differ
    uv = mesh.uv[mesh.triangles]
    np.testing.assert_array_equal(uv[0, 0], [0.0, 1.0])       # vt 0 0 -> (0, 1 - 0)
    np.testing.assert_array_equal(uv[1, 0], [0.5, 0.5])


def test_obj_without_vt_on_every_corner_has_no_uv(tmp_path):
    path = tmp_path / "m.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1 2//1 3\n")
    assert read_mesh(path).uv is None
    assert not mesh_facts(str(path)).has_uv


# ---------------------------------------------------------------------------
# Refusals: one sentence each, a line number for OBJ, from the header for PLY counts

def ascii_ply(header_edit=None, body=None):
    text = ply_header("ascii")
    if header_edit:
        text = header_edit(text)
    rows = [" ".join(f"{c:g}" for c in p + uv_of(p)) for p in POSITIONS]
    rows += [" ".join(str(i) for i in (len(f),) + f) for f in FACES]
    return text + (body if body is not None else "\n".join(rows) + "\n")


PLY_REFUSALS = {
    "bad magic": ("PLY\n" + ascii_ply()[4:], "does not begin with the line \"ply\""),
    "unknown format": (ascii_ply(lambda t: t.replace("format ascii", "format utf8")),
                       "unknown PLY format 'utf8 1.0'"),
    "version": (ascii_ply(lambda t: t.replace("ascii 1.0", "ascii 2.0")), "PLY version 2.0"),
    "no x y z": (ascii_ply(lambda t: t.replace("property float y", "property float w")),
                 "no x, y and z properties"),
    "integer coordinates": (ascii_ply(lambda t: t.replace("property float x", "property int x")),
                            "vertex property x is int"),
    "no faces": (ascii_ply(lambda t: t.replace("element face 2", "element face 0"), body=""),
                 "has no faces"),
    "no face list": (ascii_ply(lambda t: t.replace("vertex_indices", "corners")),
                     "no list property vertex_indices"),
    "float indices": (ascii_ply(lambda t: t.replace("uchar int", "uchar float")),
                      "holds floating-point numbers"),
    "unknown type": (ascii_ply(lambda t: t.replace("property double z", "property real z")),
                     "unknown PLY property type 'real'"),
    "unknown keyword": (ascii_ply(lambda t: t.replace("comment", "remark")),
                        "unknown keyword 'remark'"),
    "no end_header": ("ply\nformat ascii 1.0\n" + "comment x\n" * 10000,
                      "no end_header line within its first 65536 bytes"),
    "10^12 faces": (ascii_ply(lambda t: t.replace("element face 2", "element face 1000000000000")),
                    "declares 1000000000000 faces"),
    "more than the file holds": (ascii_ply(lambda t: t.replace("element vertex 5",
                                                               "element vertex 900000")),
                                 "declares more than the file holds"),
    "index past the vertices": (ascii_ply(body="0 0 0 0 0\n" * 5 + "3 0 1 5\n3 0 1 2\n"),
                                "refers to vertex 5, which does not exist"),
    "negative index": (ascii_ply(body="0 0 0 0 0\n" * 5 + "3 0 -1 2\n3 0 1 2\n"),
                       "refers to vertex -1"),
    "not finite": (ascii_ply(body="0 0 0 0 0\n" * 4 + "nan 0 0 0 0\n3 0 1 2\n3 0 1 2\n"),
                   "a vertex coordinate is not finite"),
    "not a number": (ascii_ply(body="0 0 0 0 0\n" * 4 + "zero 0 0 0 0\n3 0 1 2\n3 0 1 2\n"),
                     "not a number"),
    "two corners": (ascii_ply(body="0.5 0.5 0.5 0.5 0.5\n" * 5 + "2 0 1\n3 0 1 2\n"),
                    "a face needs 3 or more"),
    "trailing numbers": (ascii_ply(body="0 0 0 0 0\n" * 5 + "3 0 1 2\n3 0 1 2\n7\n"),
                         "goes on past the elements its header declares (1 more number)"),
    "ends early": (ascii_ply(body="0 0 0 0 0\n" * 5 + "3 0 1 2\n4 0 1 2\n"),
                   "ends inside its face element"),
}


def assert_one_sentence(message):
    assert message and "\n" not in message and "Traceback" not in message
    assert len(message) < 300


@pytest.mark.parametrize("case", sorted(PLY_REFUSALS))
def test_malformed_ply_refused_in_one_sentence(tmp_path, case):
    text, expected = PLY_REFUSALS[case]
    path = tmp_path / "bad.ply"
    path.write_text(text)
    with pytest.raises(MeshFileError) as e:
        read_mesh(path)                     # the header's checks, then the body's
    assert_one_sentence(str(e.value))
    assert expected in str(e.value)


def test_binary_ply_truncated_and_padded(tmp_path):
    good = write_ply_binary(tmp_path / "m.ply", "<").read_bytes()
    for data, expected in ((good[:-3], "ends inside its face element"),
                           (good + b"\0\0", r"goes on past .* \(2 more bytes\)")):
        (tmp_path / "bad.ply").write_bytes(data)
        with pytest.raises(MeshFileError, match=expected):
            read_mesh(tmp_path / "bad.ply")


def test_a_header_claiming_huge_counts_is_refused_without_allocating(tmp_path):
    """10¹² faces, or as many vertices as the limit allows in a 300-byte file: refused
    from the header, with no allocation in proportion (peak well under a megabyte)."""
    cases = (("element face 2", "element face 1000000000000"),
             ("element face 2", f"element face {MAX_MESH_TRIANGLES}"),
             ("element vertex 5", f"element vertex {3 * MAX_MESH_TRIANGLES}"))
    for old, new in cases:
        for fmt in ("ascii", "binary_little_endian"):
            path = tmp_path / "huge.ply"
            path.write_text(ply_header(fmt).replace(old, new) + "0 " * 20)
            tracemalloc.start()
            with pytest.raises(MeshFileError):
                read_mesh(path)
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            assert peak < 1 << 20, (old, new, fmt, peak)


def test_a_small_ascii_header_over_a_large_body_allocates_little(tmp_path):
    """5 vertices and 2 faces declared over 8 MB of numbers: refused once more numbers are
    read than such a body can hold, not after converting all of them (4 million)."""
    path = tmp_path / "long.ply"
    path.write_text(ascii_ply(body="0 " * (4 << 20)))
    tracemalloc.start()
    with pytest.raises(MeshFileError, match="goes on past the elements its header declares"):
        read_mesh(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 8.5e6 + 40e6           # the body read, and one megabyte's words


OBJ_REFUSALS = {
    "two corners": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "line 4: a face needs 3 or more vertices"),
    "index 0": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "line 4: vertex 0 does not exist"),
    "past the vertices": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "line 4: vertex 4 does not exist"),
    "relative too far": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", "line 4: "),
    "vertex defined later": ("v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n", "line 3: vertex 3 does not exist"),
    "missing vt": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n",
                   "line 5: texture coordinate 2 does not exist"),
    "missing vn": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\n", "line 4: normal 1 does not exist"),
    "short vertex": ("v 0 0\n", "line 1: a vertex (v) needs 3 numbers"),
    "short vt": ("v 0 0 0\nvt 0.5\n", "line 2: a texture coordinate (vt) needs 2 numbers"),
    "zero normal": ("vn 0 0 0\n", "line 1: a vertex normal (0 0 0) has no direction"),
    "not a number": ("v 0 0 0\nv 1 zero 0\n", "line 2: 'v' is followed by something that is not a number"),
    "underscore": ("v 1_0 0 0\n", "line 1: 'v' is followed by something that is not a number"),
    "not finite": ("v 0 0 0\nv inf 0 0\n", "line 2: a number that is not finite"),
    "corner syntax": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n", "line 4: a face corner is v"),
    "corner not a number": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "line 4: a face index is a whole number"),
    "long line": ("v 0 0 0" + " " * 1100 + "\n", "line 1 is longer than 1023 bytes"),
    "no faces": ("v 0 0 0\nv 1 0 0\n", "the OBJ file has no faces"),
}


@pytest.mark.parametrize("case", sorted(OBJ_REFUSALS))
def test_malformed_obj_refused_at_its_line(tmp_path, case):
    text, expected = OBJ_REFUSALS[case]
    path = tmp_path / "bad.obj"
    path.write_text(text)
    for read in (read_mesh, lambda p: mesh_facts(str(p))):
        with pytest.raises(MeshFileError) as e:
            read(path)
        assert_one_sentence(str(e.value))
        assert expected in str(e.value)


def test_obj_triangles_refused_the_line_they_pass_the_limit(tmp_path, monkeypatch):
    monkeypatch.setattr(obj_lines, "MAX_MESH_TRIANGLES", 4)
    path = tmp_path / "many.obj"
    # a quad (2) + a triangle (1) = 3, then a quad (2) = 5 > 4 at line 6
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3 3\nf 1 2 3\nf 3 2 1 1\nf 1 2 3\n")
    with pytest.raises(MeshFileError, match="^line 6: the faces pass 4 triangles"):
        mesh_facts(str(path))


def test_ply_polygons_refused_past_the_limit_as_they_are_counted(tmp_path, monkeypatch):
    """The header's face count (2) is within the limit; their fans (3) are not."""
    monkeypatch.setattr(mesh_file, "MAX_MESH_TRIANGLES", 2)
    with pytest.raises(MeshFileError, match="triangles"):
        read_mesh(write_ply_binary(tmp_path / "m.ply", "<"))
    with pytest.raises(MeshFileError, match="triangles"):
        read_mesh(write_ply_ascii(tmp_path / "m.ply"))


def test_files_that_are_not_meshes(tmp_path, monkeypatch):
    with pytest.raises(MeshFileError, match="no such file"):
        mesh_facts(str(tmp_path / "missing.ply"))
    (tmp_path / "dir.obj").mkdir()
    with pytest.raises(MeshFileError, match="it is a directory"):
        read_mesh(tmp_path / "dir.obj")
    with pytest.raises(MeshFileError, match="PLY .* or Wavefront OBJ"):
        mesh_facts(str(write_obj(tmp_path / "m.stl")))
    if hasattr(os, "mkfifo"):
        os.mkfifo(tmp_path / "pipe.obj")
        with pytest.raises(MeshFileError, match="FIFO"):
            mesh_facts(str(tmp_path / "pipe.obj"))    # refused unopened: no blocking read
    monkeypatch.setattr(mesh_limits, "MAX_MESH_BYTES", 64)
    with pytest.raises(MeshFileError, match="mesh files hold at most 64 bytes"):
        read_mesh(write_obj(tmp_path / "m.obj"))


@pytest.mark.parametrize("count_type", ["uchar", "ushort", "int"])
def test_the_first_polygon_among_many_triangles_is_found(tmp_path, count_type):
    """Binary lengths of any integer type, the polygon after 999 triangles: found at its
    own offset (every record before it is a triangle, so it is where a triangle would be)."""
    code = {"uchar": "B", "ushort": "H", "int": "i"}[count_type]
    faces = [(0, 1, 2)] * 999 + [(0, 1, 2, 3, 4)] + [(0, 1, 2)] * 20
    text = ply_header("binary_big_endian", faces=len(faces)).replace("uchar int", f"{count_type} int")
    body = b"".join(struct.pack(">ffdff", *p, *uv_of(p)) for p in POSITIONS)
    body += b"".join(struct.pack(f">{code}{len(f)}i", len(f), *f) for f in faces)
    (tmp_path / "m.ply").write_bytes(text.encode() + body)
    with pytest.raises(MeshFileError, match="^a face of 5 vertices"):
        mesh_facts(str(tmp_path / "m.ply"))
    assert len(read_mesh(tmp_path / "m.ply").triangles) == 999 + 3 + 20


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_elements_in_any_order_and_others_skipped(tmp_path, fmt):
    """An element of its own before the faces, the faces (with properties around their
    list) before the vertices: read, and the checks walk past them too. (A list on
    another element is refused: tests/test_hostile_meshes.py.)"""
    head = ("ply\nformat {fmt} 1.0\nelement material 2\nproperty float k\n"
            "property uchar id\nelement face 2\nproperty uchar flags\n"
            "property list uchar uint vertex_index\nproperty float w\nelement vertex 4\n"
            "property double x\nproperty double y\nproperty double z\nproperty uchar red\n"
            "end_header\n").format(fmt=fmt)
    square, faces = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [(0, 1, 2), (0, 2, 3)]
    path = tmp_path / "e.ply"
    if fmt == "ascii":
        path.write_text(head + "0.5 7\n2.5 8\n"
                        + "".join(f"5 3 {a} {b} {c} 0.5\n" for a, b, c in faces)
                        + "".join(f"{x} {y} {z} 200\n" for x, y, z in square))
    else:
        body = struct.pack("<fB", 0.5, 7) + struct.pack("<fB", 2.5, 8)
        body += b"".join(struct.pack("<BB3If", 5, 3, *f, 0.5) for f in faces)
        body += b"".join(struct.pack("<3dB", *p, 200) for p in square)
        path.write_bytes(head.encode() + body)
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.positions[mesh.triangles], np.array(square)[np.array(faces)])
    assert mesh_facts(str(path)) == meshes_facts.MeshFacts("ply", 4, 2, False,
                                                          ((0, 0, 0), (1, 1, 0)))


# ---------------------------------------------------------------------------
# What mesh_facts walks in a PLY body, for Mitsuba's sake: every face a triangle of
# existing vertices, every coordinate finite within float32, every element bounded.

def ply_with(fmt, positions, faces, index_type="int", types="fff", uv=None):
    """A PLY of ``positions`` (x y z of the given float types, then u v as float) and
    triangles ``faces`` in format ``fmt``, written here with struct or text."""
    names = dict(f="float", d="double")
    lines = ["ply", f"format {fmt} 1.0", f"element vertex {len(positions)}"]
    lines += [f"property {names[t]} {c}" for t, c in zip(types, "xyz")]
    lines += ["property float u", "property float v"] if uv else []
    lines += [f"element face {len(faces)}", f"property list uchar {index_type} vertex_indices",
              "end_header"]
    head = ("\n".join(lines) + "\n").encode()
    rows = [tuple(p) + (tuple(uv[k]) if uv else ()) for k, p in enumerate(positions)]
    if fmt == "ascii":
        text = [" ".join(repr(float(c)) for c in r) for r in rows]
        text += [" ".join(map(str, (3,) + tuple(f))) for f in faces]
        return head + ("\n".join(text) + "\n").encode()
    order = "<" if fmt == "binary_little_endian" else ">"
    code = {"int": "i", "uint": "I", "short": "h", "uchar": "B"}[index_type]
    body = b"".join(struct.pack(order + types + ("ff" if uv else ""), *r) for r in rows)
    body += b"".join(struct.pack(f"{order}B3{code}", 3, *f) for f in faces)
    return head + body


FORMATS = ["ascii", "binary_little_endian", "binary_big_endian"]
TRIANGLE = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]


def facts_refusal(tmp_path, data, name="m.ply"):
    path = tmp_path / name
    (path.write_bytes if isinstance(data, bytes) else path.write_text)(data)
    with pytest.raises(MeshFileError) as e:
        mesh_facts(str(path))
    assert_one_sentence(str(e.value))
    return str(e.value)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_an_element_of_no_properties_or_past_the_limit_is_refused_from_the_header(tmp_path, fmt):
    """10¹⁵ records of nothing fit any file: refused at once (it was walked record by
    record); any element past MAX_MESH_VERTICES records is refused before it is walked."""
    good = ply_with(fmt, TRIANGLE, [(0, 1, 2)])
    for junk, words in [(b"element junk 1000000000000000\n",
                         "the PLY element 'junk' declares 1000000000000000 records of no "
                         "properties"),
                        (f"element junk {mesh_limits.MAX_MESH_VERTICES + 1}\nproperty uchar a\n"
                         .encode(), "an element of a mesh file holds at most"),
                        (b"element junk " + b"9" * 5000 + b"\n", "more than a mesh file holds")]:
        data = good.replace(b"element vertex", junk + b"element vertex")
        assert words in facts_refusal(tmp_path, data)
        with pytest.raises(MeshFileError, match=words.split("(")[0]):
            read_mesh(tmp_path / "m.ply")


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("index_type, bad", [("int", 3), ("int", -1), ("uint", 2 ** 32 - 1),
                                             ("short", 7)])
def test_a_face_index_outside_the_vertices_is_refused_in_the_readers_words(tmp_path, fmt,
                                                                           index_type, bad):
    faces = [(0, 1, 2)] * 10 + [(0, bad, 2)] + [(0, 1, 2)] * 3
    message = facts_refusal(tmp_path, ply_with(fmt, TRIANGLE, faces, index_type))
    assert message == (f"a face refers to vertex {bad}, which does not exist (the file has 3, "
                       f"numbered from 0)")
    with pytest.raises(MeshFileError, match=f"a face refers to vertex {bad}, which does not"):
        read_mesh(tmp_path / "m.ply")                 # the reference reader's sentence


def test_obj_face_indices_past_the_vertices_are_refused_at_their_line(tmp_path):
    message = facts_refusal(tmp_path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n", "m.obj")
    assert message.startswith("line 5: vertex 9 does not exist")


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("value, words", [(1e39, "a vertex coordinate 1e+39 is beyond float32's"),
                                          (-4e38, "a vertex coordinate -4e+38 is beyond"),
                                          (math.inf, "a vertex coordinate is not finite"),
                                          (math.nan, "a vertex coordinate is not finite")])
def test_ply_coordinates_not_finite_or_past_float32_are_refused(tmp_path, fmt, value, words):
    positions = [(0.0, 0.0, 0.0), (1.0, 0.0, value), (0.0, 1.0, 0.0)]
    assert words in facts_refusal(tmp_path, ply_with(fmt, positions, [(0, 1, 2)], types="ffd"))


@pytest.mark.parametrize("fmt", FORMATS)
def test_ply_texture_coordinates_not_finite_are_refused(tmp_path, fmt):
    uv = [(0, 0), (1, math.nan), (0, 1)]
    assert "a texture coordinate is not finite" in facts_refusal(
        tmp_path, ply_with(fmt, TRIANGLE, [(0, 1, 2)], uv=uv))


def test_ascii_texture_coordinates_past_float32_are_refused(tmp_path):
    data = ply_with("ascii", TRIANGLE, [(0, 1, 2)], uv=[(0, 0), (1, 0), (0, 1)])
    data = data.replace(b"\n1.0 0.0 0.0 1.0 0.0\n", b"\n1.0 0.0 0.0 1e39 0.0\n")
    assert "a texture coordinate 1e+39 is beyond float32's range" in facts_refusal(tmp_path, data)


@pytest.mark.parametrize("line, words", [("v 1 0 1e39", "line 2: the number 1e+39 is beyond"),
                                         ("v -1e39 0 0", "line 2: the number -1e+39 is beyond"),
                                         ("vt 0 3.5e38", "line 2: the number 3.5e+38 is beyond"),
                                         ("v 1 0 inf", "line 2: a number that is not finite")])
def test_obj_coordinates_past_float32_are_refused_at_their_line(tmp_path, line, words):
    text = f"v 0 0 0\n{line}\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1 3 4\n"
    message = facts_refusal(tmp_path, text, "m.obj")
    assert words in message
    assert "float32's range (±3.4028234663852886e+38)" in message or "finite" in words


def test_float32s_largest_is_taken(tmp_path):
    big = 3.4028234663852886e38                   # FLT_MAX itself, exact in float32
    positions = [(0.0, 0.0, 0.0), (big, 0.0, 0.0), (0.0, -big, 0.0)]
    path = tmp_path / "m.ply"
    path.write_bytes(ply_with("binary_little_endian", positions, [(0, 1, 2)]))
    assert mesh_facts(str(path)).bounds == ((0.0, -big, 0.0), (big, 0.0, 0.0))


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_polygon_short_body_or_trailing_data_is_refused_by_the_walk(tmp_path, fmt):
    good = ply_with(fmt, TRIANGLE, [(0, 1, 2)] * 4)
    if fmt == "ascii":
        polygon = good.replace(b"\n3 0 1 2\n3 0 1 2\n", b"\n3 0 1 2\n4 0 1 2 1\n", 1)
        short, trailing = good[:-8], good + b"7\n"
        short_words = "the file ends inside its face element"
    else:
        polygon = good.replace(b"\x03" + good[-12:], b"\x04" + good[-12:] + good[-4:])
        trailing = good + b"\0"
        # Lists only a face's, of 3 indices: the header's sizes say the body is short.
        short = good[:-5]
        short_words = "the PLY header declares more than the file holds"
    assert facts_refusal(tmp_path, polygon).startswith("a face of 4 vertices")
    assert facts_refusal(tmp_path, short).startswith(short_words)
    assert "goes on past the elements its header declares" in facts_refusal(tmp_path, trailing)


# ---------------------------------------------------------------------------
# The bounds of a mesh's file, and the shapes placed by them (scene.geometry)

@pytest.mark.parametrize("fmt", FORMATS + ["obj"])
@pytest.mark.parametrize("chunk", [None, 64])
def test_bounds_are_the_least_and_greatest_coordinates_written(tmp_path, monkeypatch, fmt, chunk):
    """Random float32 positions (exact in every encoding), read a chunk at a time (64 bytes
    or words: many chunks), against NumPy's min and max of what was written."""
    if chunk:
        monkeypatch.setattr(mesh_limits, "READ_CHUNK", chunk)
    rng = np.random.default_rng(25)
    positions = rng.normal(0, 100, (500, 3)).astype(np.float32).astype(np.float64)
    faces = rng.integers(0, len(positions), (300, 3))
    if fmt == "obj":
        lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in positions.tolist()]
        lines += ["f " + " ".join(str(i + 1) for i in f) for f in faces]
        (tmp_path / "m.obj").write_text("\n".join(lines) + "\n")
        path = tmp_path / "m.obj"
    else:
        path = tmp_path / "m.ply"
        path.write_bytes(ply_with(fmt, positions.tolist(), faces.tolist()))
    facts = mesh_facts(str(path))
    assert (facts.vertices, facts.triangles) == (500, 300)
    assert facts.bounds == (tuple(positions.min(axis=0)), tuple(positions.max(axis=0)))


def test_mesh_bounds_are_looked_up_again_when_the_file_changes(tmp_path):
    path = tmp_path / "m.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert meshes_facts.mesh_bounds(str(path)) == ((0, 0, 0), (1, 1, 0))
    path.write_text("v 0 0 0\nv 10 0 0\nv 0 -1 0\nf 1 2 3\n")        # another size
    assert meshes_facts.mesh_bounds(str(path)) == ((0, -1, 0), (10, 0, 0))
    path.write_text("v 0 0 0\n")
    assert meshes_facts.mesh_bounds(str(path)) is None                  # refused: unknown
    assert meshes_facts.mesh_bounds(str(tmp_path / "missing.obj")) is None


def test_a_meshs_bounding_sphere_is_around_its_transformed_bounds(tmp_path):
    """Vertices within x 1..3, y −1..1, z 0..4 (a corner of each kind), scaled by 2 and
    moved by (10, 0, −5): the box 2..6 × −2..2 × 0..8 moved, whose centre is (14, 0, −1)
    and whose half diagonal is √(4² + 4² + 8²)/2 = √24."""
    from mimarble.scene import geometry, model
    vertices = [(1, -1, 0), (3, 1, 4), (2, 0, 1), (1, 1, 4)]
    path = tmp_path / "m.obj"
    path.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in vertices) + "f 1 2 3 4\n")
    steps = (("scale", (2.0, 2.0, 2.0)), ("translate", (10.0, 0.0, -5.0)))
    mesh = model.Mesh("g", str(path), transform=steps)
    centre, radius = geometry.sphere_bounds(mesh)
    assert centre == pytest.approx((14.0, 0.0, -1.0)) and radius == pytest.approx(math.sqrt(24))
    corners = geometry.mesh_corners(mesh)
    assert sorted(corners) == sorted((x, y, z) for x in (12, 16) for y in (-2, 2)
                                     for z in (-5, 3))
    missing = model.Mesh("g", str(tmp_path / "missing.obj"), transform=steps)
    assert geometry.sphere_bounds(missing) == ((10.0, 0.0, -5.0), 0.0)   # its origin alone
    assert geometry.mesh_corners(missing) is None


def test_a_planes_disk_reaches_past_a_far_mesh(tmp_path):
    """A mesh whose vertices lie 1000 to 1001 from the eye (none at its transform's origin):
    the plane's disk is PLANE_REACH times (1 + its farthest corner's distance) at least."""
    from mimarble.scene import geometry, model
    path = tmp_path / "far.obj"
    path.write_text("v 1000 0 0\nv 1001 0 0\nv 1000 1 0\nf 1 2 3\n")
    g = model.Material("g", diffuse=model.ColorChannel((0.5, 0.5, 0.5)))
    plane = model.Plane("g", (0.0, -1.0, 0.0), (0.0, 1.0, 0.0))
    scene = model.Scene(image=model.Image(8, 8, 1),
                        camera=model.Camera(eye=(0.0, 0.0, 0.0), lookat=(0.0, 0.0, -1.0)),
                        lights=(model.Light((0.0, 5.0, 0.0)),), materials={"g": g},
                        planes=(plane,), meshes=(model.Mesh("g", str(path)),))
    _, radius = geometry.plane_disk(scene, plane)
    farthest = math.dist((0.0, -1.0, 0.0), (1001.0, 1.0, 0.0))    # from the disk's centre
    assert radius >= geometry.PLANE_REACH * (1 + farthest)
    assert radius <= geometry.PLANE_REACH * (1 + farthest + 2.0)   # the bounding sphere's slack


def test_the_facts_of_a_scene_at_the_mesh_limit_are_kept():
    """mesh_facts keeps the facts of as many files as a scene may name meshes."""
    assert meshes_facts.FACTS_KEPT == LIMITS["max_meshes"]
