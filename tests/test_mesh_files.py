"""Mesh files: mimarble.scene.mesh_header (what a file holds, its limits) and the reference
tracer's reader (mimarble.reference.mesh_file), on small files written here.

The same mesh is written in every encoding by hand (struct for the binary PLYs, text for the
others), so each reader is checked against the triangles it was given, not against another
reader."""

import os
import struct
import tracemalloc

import numpy as np
import pytest

from mimarble.reference import mesh_file
from mimarble.reference.mesh_file import read_mesh
from mimarble.scene import mesh_header
from mimarble.scene.limits import MAX_MESH_TRIANGLES
from mimarble.scene.mesh_header import MeshFileError, mesh_facts

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
    assert mesh_facts(str(path)) == mesh_header.MeshFacts(
        "obj" if kind == "obj" else "ply", len(POSITIONS), len(FANS), True)


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
    "zero normal": ("vn 0 0 0\n", "line 1: a normal (vn) needs three numbers, not all 0"),
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
    monkeypatch.setattr(mesh_header, "MAX_MESH_TRIANGLES", 4)
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
    monkeypatch.setattr(mesh_header, "MAX_MESH_BYTES", 64)
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
    """An element of its own (a list of floats among its properties) before the faces,
    the faces (with properties around their list) before the vertices: read, and the
    checks walk past them too."""
    head = ("ply\nformat {fmt} 1.0\nelement material 2\nproperty list uchar float k\n"
            "property uchar id\nelement face 2\nproperty uchar flags\n"
            "property list uchar uint vertex_index\nproperty float w\nelement vertex 4\n"
            "property double x\nproperty double y\nproperty double z\nproperty uchar red\n"
            "end_header\n").format(fmt=fmt)
    square, faces = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [(0, 1, 2), (0, 2, 3)]
    path = tmp_path / "e.ply"
    if fmt == "ascii":
        path.write_text(head + "1 0.5 7\n3 1 2.5 3 8\n"
                        + "".join(f"5 3 {a} {b} {c} 0.5\n" for a, b, c in faces)
                        + "".join(f"{x} {y} {z} 200\n" for x, y, z in square))
    else:
        body = struct.pack("<BfB", 1, 0.5, 7) + struct.pack("<B3fB", 3, 1, 2.5, 3, 8)
        body += b"".join(struct.pack("<BB3If", 5, 3, *f, 0.5) for f in faces)
        body += b"".join(struct.pack("<3dB", *p, 200) for p in square)
        path.write_bytes(head.encode() + body)
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.positions[mesh.triangles], np.array(square)[np.array(faces)])
    assert mesh_facts(str(path)) == mesh_header.MeshFacts("ply", 4, 2, False)
