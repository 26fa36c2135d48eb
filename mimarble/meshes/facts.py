"""What a mesh file holds, for the parser: counts, bounds, (u, v), digest, within the limits.

``mesh_facts(path)`` returns :class:`MeshFacts` (format, vertices, triangles, has_uv,
bounds) or raises :class:`~mimarble.meshes.limits.MeshFileError` with one sentence (no file
name: the caller names the file; an OBJ's sentence begins with its line number, ``line 12:
a face needs 3 or more vertices``), read once per version of the file (its name, inode,
size, modification and change times); ``mesh_bounds(path)`` is its bounds, for the
geometry that places shapes by their extent (scene/geometry.py). The scene language checks
every mesh with mesh_facts while it parses, the translator every mesh of a scene it is
given (:func:`~mimarble.scene.mesh_files.check_mesh_files`: scenes built in Python, files
changed since the parse). The PLY header (ply_header.py) and the OBJ lines (obj_lines.py)
are read by the same code here and for the renderers' arrays (arrays.py, NumPy), so both
see one grammar and one set of limits (limits.py); the PLY body is walked here in pure
Python (ply_body.py), there with NumPy. Standard library only.

What is read (and what is refused, in one sentence each):

* **PLY** (``format ascii``, ``binary_little_endian`` or ``binary_big_endian``, version 1.0,
  the property types Mitsuba 3.9's ``ply`` plugin knows): ``element vertex`` with float or
  double ``x y z`` and optionally ``u v``, ``texture_u texture_v`` or ``s t`` (Mitsuba's
  order of preference; a lone ``u`` or ``v`` beside another pair is refused: Mitsuba
  renames the pair onto it) and ``nx ny nz`` (vertex normals, all three, float or double,
  each finite within float32, neither zero nor overflowing when squared:
  ``limits.MIN_NORMAL``, ``limits.MAX_NORMAL``), other properties
  skipped; ``element face`` with an integer
  ``list`` property ``vertex_index`` or ``vertex_indices`` (Mitsuba's preference), the
  file's only list (Mitsuba reads every list as a length and 3 values, so another list, on
  any element, is refused); other elements skipped. The header's lines are ``ply``,
  ``format``, ``comment``, ``element``, ``property`` and ``end_header`` (``obj_info`` is
  refused, as Mitsuba refuses it), split into words where C++'s ``>>`` splits them. An
  ascii body's every word is read as Mitsuba reads it, with ``>>`` of its property's type:
  integers written as whole numbers within their type's range, floating-point numbers
  finite within their type's (a ``half`` below 65520). Integer coordinates are refused:
  Mitsuba reads an integer property as a fraction of its type's range, so the two
  renderers would place the mesh differently.
  The faces must be **triangles**: Mitsuba's ``ply`` plugin reads a face's list as a
  length checked to be 3 and three indices, so :func:`mesh_facts` walks the body
  (:func:`ply_body`: stepped slices of a binary one, the words of an ascii one) and
  refuses a polygon, which the reference tracer's reader would take as a fan; a face
  index outside 0 … V − 1 (Mitsuba would read past its vertices); a coordinate x, y, z
  (or the u, v read) that is not finite or beyond ±FLT_MAX (float32, where Mitsuba holds
  it); a body ending inside an element or going on past the last.
* **OBJ**: its statements as obj_lines.py reads and refuses them (``v``, ``vt``, ``vn``,
  ``f``; polygons as fans, as Mitsuba splits them), negative (relative) indices refused
  (Mitsuba 3.9 reads indices with ``strtoul``: −1 becomes 2³² − 1, "an invalid vertex"),
  read by the reference tracer's reader (:func:`~mimarble.meshes.obj_lines.obj_statements`
  with ``relative``). ``has_uv`` when every corner of every face names a ``vt``;
  ``has_normals`` when there are ``vn`` lines and every corner names one (some but not
  all: ``normals_problem``, refused where the mesh is shaded smooth).

So the files :func:`mesh_facts` accepts, Mitsuba 3.9.1's ``ply`` and ``obj`` plugins and the
reference tracer read alike in fans, (u, v), indices, coordinates and triangles (checked on
that version's src/shapes/ply.h, ply.cpp and obj.cpp, and by loading such files in it),
up to Mitsuba's float32.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
from dataclasses import dataclass, field

from . import limits
from .limits import MeshFileError, open_mesh
from .obj_lines import obj_statements
from .ply_body import ply_body
from .ply_header import ply_header

__all__ = ["MeshFacts", "mesh_facts", "mesh_bounds"]

#: Mesh files whose facts are kept (mesh_facts): those of a scene at the mesh limit
#: (mimarble.scene.limits.MAX_MESHES, which tests/test_mesh_files.py compares).
FACTS_KEPT = 256


@dataclass(frozen=True)
class MeshFacts:
    """``format`` "ply" or "obj"; ``vertices`` (PLY: vertex records; OBJ: ``v`` lines);
    ``triangles`` (OBJ: polygons split into fans; PLY: the face count, its faces being
    triangles); ``has_uv``: texture coordinates on every vertex (PLY) or
    every face corner (OBJ); ``bounds``: ((x, y, z) min, (x, y, z) max) of every vertex
    position the file lists (used by a face or not), in the file's coordinates (None
    where not known: facts built by hand); ``uv_extent``: the largest |u| or |v| of the
    texture coordinates as Mitsuba stores them (None: none); ``digest``: SHA-256 of the
    file's bytes (hex), what tells two versions of one file apart; ``has_normals``:
    vertex normals Mitsuba reads (PLY: ``nx ny nz``; OBJ: ``vn`` lines and every face
    corner naming one); ``normals_problem``: why the file's normals cannot be used, where
    it has some and they are incomplete (an OBJ face whose corners name no ``vn``: Mitsuba
    would leave those normals unset), a sentence beginning with its line, else None."""

    format: str
    vertices: int
    triangles: int
    has_uv: bool
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    uv_extent: float | None = field(default=None, compare=False)
    digest: str | None = field(default=None, compare=False)
    has_normals: bool = field(default=False, compare=False)
    normals_problem: str | None = field(default=None, compare=False)


def mesh_facts(path: str) -> MeshFacts:
    """What the mesh file at ``path`` holds (module docstring), or MeshFileError. PLY: its
    header, then its body walked (every face a triangle of existing vertices, every
    coordinate finite within float32: :func:`ply_body`); OBJ: all its lines, each checked,
    negative indices refused (Mitsuba reads none).

    Read once per version of the file: the answer (facts or sentence) is kept by the file's
    name, device, inode, size and modification and change times, taken from the open file
    before it is read — a file rewritten since, even with its old modification time put
    back (``touch -r``, ``cp -p``), has another change time and is read again. The parser,
    the translator (:func:`check_mesh_files`), the geometry (:func:`mesh_bounds`) and the
    reference tracer ask for the same file many times."""
    fmt = _format_of(path)
    f, size = open_mesh(path)
    with f:
        st = os.fstat(f.fileno())
        version = (os.fspath(path), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns,
                   st.st_ctime_ns)
        known = _READ.pop(version, None)
        if known is None:
            try:
                known = _read_facts(f, fmt, size)
            except MeshFileError as e:
                known = str(e)
            if len(_READ) >= FACTS_KEPT:
                _READ.pop(next(iter(_READ)))            # the least recently asked for
        _READ[version] = known
    if isinstance(known, str):
        raise MeshFileError(known)
    return known


#: mesh_facts' answers by file version (its docstring), the most recently asked for last.
_READ: dict = {}


def _read_facts(f, fmt: str, size: int) -> MeshFacts:
    """mesh_facts of the file open as ``f`` (binary, at its start) of ``size`` bytes, with
    its content digest: SHA-256 of its bytes, read again after the check (from the
    system's cache: a small part of the check's time, docs/benchmarks.md)."""
    if fmt == "ply":
        header = ply_header(f, size)
        bounds, uv_extent = ply_body(f, header, size)
        facts = MeshFacts("ply", header.element("vertex").count, header.element("face").count,
                          header.uv is not None, bounds, uv_extent=uv_extent,
                          has_normals=header.normals)
    else:
        facts = _obj_facts(f)
    f.seek(0)
    digest = hashlib.sha256()
    for block in iter(lambda: f.read(limits.READ_CHUNK), b""):
        digest.update(block)
    return dataclasses.replace(facts, digest=digest.hexdigest())


def _obj_facts(f) -> MeshFacts:
    vertices = triangles = 0
    has_uv = True
    x0 = y0 = z0 = math.inf
    x1 = y1 = z1 = -math.inf
    uv_extent = 0.0
    normals = 0
    notes: dict = {}
    for kind, value in obj_statements(f, notes=notes):
        if kind == "v":
            vertices += 1
            x, y, z = value                  # plain comparisons: the fastest here
            if x < x0:
                x0 = x
            if x > x1:
                x1 = x
            if y < y0:
                y0 = y
            if y > y1:
                y1 = y
            if z < z0:
                z0 = z
            if z > z1:
                z1 = z
        elif kind == "f":
            triangles += len(value) - 2
            has_uv = has_uv and all(t >= 0 for _, t, _ in value)
        elif kind == "vn":
            normals += 1
        else:                                # vt: as Mitsuba stores it, v flipped (1 − v)
            u, v = value
            uv_extent = max(uv_extent, abs(u), abs(1.0 - v))
    without = notes.get("face_without_normal")
    problem = None if not normals or without is None else (
        f"line {without}: a face whose corners name no normal (v//vn) in a file with vn "
        f"lines; Mitsuba would leave those vertices' normals unset (give every corner a "
        f"normal, or shade the mesh with smooth false)")
    return MeshFacts("obj", vertices, triangles, has_uv, ((x0, y0, z0), (x1, y1, z1)),
                     uv_extent=uv_extent if has_uv else None,
                     has_normals=bool(normals) and without is None, normals_problem=problem)


def mesh_bounds(path):
    """The ``bounds`` of :func:`mesh_facts` for the file at ``path``, or None where it
    cannot be read (the parser says why at the mesh), for the geometry that places shapes
    by their extent (geometry.sphere_bounds, a plane's disk, Mitsuba's float32 checks),
    which asks for them many times over one file (mesh_facts reads each version once)."""
    try:
        return mesh_facts(path).bounds
    except (MeshFileError, OSError, ValueError):
        return None


def _format_of(path) -> str:
    name = os.fspath(path).lower()
    if name.endswith(".ply"):
        return "ply"
    if name.endswith(".obj"):
        return "obj"
    raise MeshFileError("a mesh file is PLY (.ply) or Wavefront OBJ (.obj), by its name's "
                        "ending")
