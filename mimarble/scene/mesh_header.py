"""What a mesh file holds, read from its header (PLY) or its lines (OBJ), within the limits.

``mesh_facts(path)`` returns :class:`MeshFacts` (format, vertices, triangles, has_uv,
bounds) or raises :class:`MeshFileError` with one sentence (no file name: the caller names
the file; an OBJ's sentence begins with its line number, ``line 12: a face needs 3 or more
vertices``), read once per version of the file (its name, inode, size, modification and
change times); ``mesh_bounds(path)`` is its bounds, for the geometry that places shapes by
their extent (scene/geometry.py). The scene language checks every mesh with mesh_facts
while it parses, the translator every mesh of a scene it is given
(:func:`check_mesh_files`: scenes built in Python, files changed since the parse); the
reference tracer's reader (mimarble/meshes/arrays.py) reads the PLY header with
:func:`ply_header` and the OBJ lines with :func:`obj_statements`, so both see one grammar
and one set of limits. Standard library only.

Limits, each checked before anything in proportion to it is read or allocated:

* the file is a regular file (reading.py) of at most
  :data:`~mimarble.scene.limits.MAX_MESH_BYTES`, from its size, before it is read;
* **PLY**: the header ends (``end_header``) within :data:`MAX_PLY_HEADER_BYTES`; its face
  count is at most :data:`~mimarble.scene.limits.MAX_MESH_TRIANGLES`, its vertex count and
  every other element's at most :data:`MAX_MESH_VERTICES`, an element of no properties has
  no records (its records would take no bytes: 10¹⁵ of them fit any file), and the file is
  large enough for what the header declares (the fewest bytes each record can take), so a
  100-byte file claiming 10¹² faces is refused from its header. Its faces are then
  triangles (below), so the face count is the triangle count; the reference tracer's
  reader, which also takes polygons (a fan of n − 2 triangles for n corners), counts them
  and refuses past the limit;
* **OBJ**: the lines are streamed; the triangles (Σ (n − 2) over the faces) are refused the
  line they pass the limit, the ``v`` and ``vt`` lines past :data:`MAX_MESH_VERTICES`.

What is read (and what is refused, in one sentence each):

* **PLY** (``format ascii``, ``binary_little_endian`` or ``binary_big_endian``, version 1.0,
  the property types Mitsuba 3.9's ``ply`` plugin knows): ``element vertex`` with float or
  double ``x y z`` and optionally ``u v``, ``texture_u texture_v`` or ``s t`` (Mitsuba's
  order of preference; a lone ``u`` or ``v`` beside another pair is refused: Mitsuba
  renames the pair onto it), other properties skipped; ``element face`` with an integer
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
  (:func:`_ply_body`: stepped slices of a binary one, the words of an ascii one) and
  refuses a polygon, which the reference tracer's reader would take as a fan; a face
  index outside 0 … V − 1 (Mitsuba would read past its vertices); a coordinate x, y, z
  (or the u, v read) that is not finite or beyond ±FLT_MAX (float32, where Mitsuba holds
  it); a body ending inside an element or going on past the last.
* **OBJ**: ``v x y z`` (further numbers ignored), ``vt u v`` (each finite, within
  ±FLT_MAX), ``vn x y z``, ``f`` with 3 or more corners ``v``, ``v/vt``, ``v//vn`` or
  ``v/vt/vn``, indices from 1, each referring to an element defined before the face;
  polygons are fans, as Mitsuba splits them. Negative (relative) indices, which the OBJ
  format allows, are refused by :func:`mesh_facts` (Mitsuba 3.9 reads indices with
  ``strtoul``: −1 becomes 2³² − 1, "an invalid vertex") and read by the reference tracer's
  reader (:func:`obj_statements` with ``relative``). Everything after ``#`` is a comment;
  other statements (``o``, ``g``, ``s``, ``usemtl``, ``mtllib``, ``l``, …) are ignored. A
  line is at most :data:`MAX_OBJ_LINE_BYTES` bytes (Mitsuba's OBJ reader refuses longer
  ones). Mitsuba separates a statement's words by spaces and tabs only and ends a face's
  corner at a space, tab or carriage return, so a statement line holding a form feed, a
  vertical tab or a carriage return before its end, a face's last corner followed at once
  by ``#``, and a UTF-8 byte order mark before the first line's ``v``, ``vt``, ``vn`` or
  ``f`` (Mitsuba would drop that line) are refused. ``has_uv`` when every corner of every
  face names a ``vt``.

So the files :func:`mesh_facts` accepts, Mitsuba 3.9.1's ``ply`` and ``obj`` plugins and the
reference tracer read alike in fans, (u, v), indices, coordinates and triangles (checked on
that version's src/shapes/ply.h, ply.cpp and obj.cpp, and by loading such files in it),
up to Mitsuba's float32.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import math
import os
import re
import struct
import sys
from dataclasses import dataclass, field

from mimarble.scene.limits import FLT_MAX, MAX_MESH_BYTES, MAX_MESH_TRIANGLES, MAX_MESHES
from mimarble.scene.reading import open_failure, open_regular
from mimarble.scene.rules import shortened

__all__ = ["MeshFacts", "MeshFileError", "mesh_facts", "mesh_bounds", "check_mesh_files",
           "MAX_PRECISE_UV", "MAX_PLY_HEADER_BYTES",
           "MAX_MESH_VERTICES", "MAX_OBJ_LINE_BYTES", "PLY_TYPES", "PlyProperty", "PlyElement",
           "PlyHeader", "ply_header", "obj_statements", "open_mesh"]

#: A PLY header's size, bytes: a header lists a few elements and properties, so 64 KiB is
#: far past any real one, and a file without ``end_header`` is not read on and on.
MAX_PLY_HEADER_BYTES = 1 << 16

#: Vertices of a mesh file (PLY vertex records, OBJ ``v`` and ``vt`` lines): three per
#: triangle of :data:`~mimarble.scene.limits.MAX_MESH_TRIANGLES`, the most a mesh within that
#: limit can use.
MAX_MESH_VERTICES = 3 * MAX_MESH_TRIANGLES

#: An OBJ line's length, bytes, without its newline: Mitsuba's OBJ reader copies each line
#: into a buffer of 1025 bytes and refuses a line of 1024 or more.
MAX_OBJ_LINE_BYTES = 1023

#: PLY property types (Mitsuba 3.9's names, src/shapes/ply.h) -> (kind, bytes): kind "i"
#: signed integer, "u" unsigned, "f" floating point (NumPy's type codes).
PLY_TYPES: dict[str, tuple[str, int]] = {
    "char": ("i", 1), "uchar": ("u", 1), "short": ("i", 2), "ushort": ("u", 2),
    "int": ("i", 4), "uint": ("u", 4), "float": ("f", 4), "double": ("f", 8),
    "int8": ("i", 1), "uint8": ("u", 1), "int16": ("i", 2), "uint16": ("u", 2),
    "int32": ("i", 4), "uint32": ("u", 4), "long": ("i", 8), "ulong": ("u", 8),
    "half": ("f", 2), "float16": ("f", 2), "float32": ("f", 4), "float64": ("f", 8),
}

_PLY_FORMATS = ("ascii", "binary_little_endian", "binary_big_endian")
#: The texture coordinate pairs of a PLY vertex, in Mitsuba's order of preference.
_PLY_UV_NAMES = (("u", "v"), ("texture_u", "texture_v"), ("s", "t"))
#: The face's list of vertex indices, in Mitsuba's order of preference.
_PLY_FACE_LISTS = ("vertex_index", "vertex_indices")


class MeshFileError(ValueError):
    """A mesh file that cannot be used, in one sentence (no file name, no position)."""


@dataclass(frozen=True)
class MeshFacts:
    """``format`` "ply" or "obj"; ``vertices`` (PLY: vertex records; OBJ: ``v`` lines);
    ``triangles`` (OBJ: polygons split into fans; PLY: the face count, its faces being
    triangles); ``has_uv``: texture coordinates on every vertex (PLY) or
    every face corner (OBJ); ``bounds``: ((x, y, z) min, (x, y, z) max) of every vertex
    position the file lists (used by a face or not), in the file's coordinates (None
    where not known: facts built by hand); ``uv_extent``: the largest |u| or |v| of the
    texture coordinates as Mitsuba stores them (None: none); ``digest``: SHA-256 of the
    file's bytes (hex), what tells two versions of one file apart."""

    format: str
    vertices: int
    triangles: int
    has_uv: bool
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    uv_extent: float | None = field(default=None, compare=False)
    digest: str | None = field(default=None, compare=False)


@dataclass(frozen=True)
class PlyProperty:
    """One property of a PLY element: ``type`` a key of :data:`PLY_TYPES`; a list has the
    type of its length in ``count_type`` (None: a scalar)."""

    name: str
    type: str
    count_type: str | None = None


@dataclass(frozen=True)
class PlyElement:
    name: str
    count: int
    properties: tuple[PlyProperty, ...]

    def property(self, name: str) -> PlyProperty | None:
        return next((p for p in self.properties if p.name == name), None)


@dataclass(frozen=True)
class PlyHeader:
    """A PLY header, checked: ``format`` one of ascii, binary_little_endian,
    binary_big_endian; ``elements`` in file order; ``size`` the header's bytes (the body
    starts there); ``uv`` the vertex properties read as (u, v) or None; ``face_list`` the
    face's list of vertex indices."""

    format: str
    elements: tuple[PlyElement, ...]
    size: int
    uv: tuple[str, str] | None
    face_list: str

    def element(self, name: str) -> PlyElement:
        return next(e for e in self.elements if e.name == name)


def open_mesh(path):
    """``path`` opened for binary reading, with its size: a regular file of at most
    MAX_MESH_BYTES, else MeshFileError (the sentences of image maps' checks)."""
    where = shortened(os.fspath(path), 1024)
    try:
        f = open_regular(path)
    except OSError as e:
        raise MeshFileError(open_failure(e, where)) from None
    size = os.fstat(f.fileno()).st_size
    if size > MAX_MESH_BYTES:
        f.close()
        raise MeshFileError(f"a mesh file of {size} bytes; mesh files hold at most "
                            f"{MAX_MESH_BYTES} bytes")
    return f, size


def mesh_facts(path: str) -> MeshFacts:
    """What the mesh file at ``path`` holds (module docstring), or MeshFileError. PLY: its
    header, then its body walked (every face a triangle of existing vertices, every
    coordinate finite within float32: :func:`_ply_body`); OBJ: all its lines, each checked,
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
            if len(_READ) >= MAX_MESHES:
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
        bounds, uv_extent = _ply_body(f, header, size)
        facts = MeshFacts("ply", header.element("vertex").count, header.element("face").count,
                          header.uv is not None, bounds, uv_extent=uv_extent)
    else:
        facts = _obj_facts(f)
    f.seek(0)
    digest = hashlib.sha256()
    for block in iter(lambda: f.read(_CHUNK), b""):
        digest.update(block)
    return dataclasses.replace(facts, digest=digest.hexdigest())


def _obj_facts(f) -> MeshFacts:
    vertices = triangles = 0
    has_uv = True
    x0 = y0 = z0 = math.inf
    x1 = y1 = z1 = -math.inf
    uv_extent = 0.0
    for kind, value in obj_statements(f):
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
            has_uv = has_uv and all(t >= 0 for _, t in value)
        else:                                # vt: as Mitsuba stores it, v flipped (1 − v)
            u, v = value
            uv_extent = max(uv_extent, abs(u), abs(1.0 - v))
    return MeshFacts("obj", vertices, triangles, has_uv, ((x0, y0, z0), (x1, y1, z1)),
                     uv_extent=uv_extent if has_uv else None)


def mesh_bounds(path):
    """The ``bounds`` of :func:`mesh_facts` for the file at ``path``, or None where it
    cannot be read (the parser says why at the mesh), for the geometry that places shapes
    by their extent (geometry.sphere_bounds, a plane's disk, Mitsuba's float32 checks),
    which asks for them many times over one file (mesh_facts reads each version once)."""
    try:
        return mesh_facts(path).bounds
    except (MeshFileError, OSError, ValueError):
        return None


#: The largest |u|, |v| of a mesh's texture coordinates read without a warning: past 2¹⁰,
#: float32's step (Mitsuba's, where it holds and interpolates them) is 2⁻¹³ or more, a
#: texel of an image map 8192 pixels wide, so its image map lookups and the reference's
#: (float64) may differ (docs/rendering-model.md, "A mesh's texture coordinates").
MAX_PRECISE_UV = float(1 << 10)


def check_mesh_files(scene) -> list[str]:
    """Every mesh file of ``scene`` checked as the parser checks it, for a scene the parser
    never saw or whose files changed since (built in Python, edited, a file rewritten after
    ``scene.load``): :func:`mesh_facts` (kept per version of the file, so a file parsed
    and unchanged is not read again), the scene's triangles within MAX_MESH_TRIANGLES, and
    (u, v) in the file where the mesh's material reads an image map — else a SceneError at
    the mesh's ``file`` in the parser's sentence. Returns the warnings of texture
    coordinates past :data:`MAX_PRECISE_UV` read by an image map, one per mesh file.
    The translator calls it for every route into Mitsuba; the reference tracer reads the
    files with the same checks (tracer.read_meshes)."""
    from mimarble.scene.errors import SceneError
    from mimarble.scene.model import ImageChannel, walk
    from mimarble.scene.rules import image_map_uv_problem, mesh_triangles_problem
    imaged = {name for name, material in scene.materials.items()
              if any(isinstance(c, ImageChannel) for channel in material.channels().values()
                     for c in walk(channel))}
    total, warned, problems = 0, set(), []
    for mesh in scene.meshes:
        name = shortened(mesh.file, 256)
        try:
            facts = mesh_facts(mesh.location)
        except MeshFileError as e:
            raise SceneError.in_file(scene.source, mesh.pos, f"mesh file '{name}': {e}") from None
        total += facts.triangles
        problem = mesh_triangles_problem(total)
        if problem:
            raise SceneError.in_file(scene.source, mesh.pos, problem)
        if mesh.material in imaged:
            if not facts.has_uv:
                raise SceneError.in_file(scene.source, mesh.pos, image_map_uv_problem(
                    mesh.material, "this mesh's file"))
            if facts.uv_extent > MAX_PRECISE_UV and mesh.location not in warned:
                warned.add(mesh.location)
                problems.append(
                    f"{scene.source or '<scene>'}:{mesh.pos or '?'}: mesh file '{name}' has "
                    f"texture coordinates up to {facts.uv_extent:g}, past ±{MAX_PRECISE_UV:g}: "
                    f"Mitsuba holds them in float32, whose step there "
                    f"({_float32_step(facts.uv_extent):.2g}) reaches a texel of a large image "
                    f"map, so its image may differ from the reference's there "
                    f"(docs/rendering-model.md)")
    return problems


def _float32_step(value: float) -> float:
    """The spacing of float32 numbers at |value| (value within float32's range)."""
    return 2.0 ** (math.frexp(value)[1] - 24)


def _format_of(path) -> str:
    name = os.fspath(path).lower()
    if name.endswith(".ply"):
        return "ply"
    if name.endswith(".obj"):
        return "obj"
    raise MeshFileError("a mesh file is PLY (.ply) or Wavefront OBJ (.obj), by its name's "
                        "ending")


# ---------------------------------------------------------------------------
# PLY

def ply_header(f, size: int) -> PlyHeader:
    """The header of the PLY file open as ``f`` (binary, at its start) of ``size`` bytes,
    checked (module docstring); ``f`` is left just past it."""
    head = f.read(MAX_PLY_HEADER_BYTES)
    if not head.startswith((b"ply\n", b"ply\r\n")):
        raise MeshFileError('not a PLY file (it does not begin with the line "ply")')
    end = _header_end(head)
    f.seek(end)
    try:
        text = head[:end].decode("ascii")
    except UnicodeDecodeError:
        raise MeshFileError("the PLY header holds bytes that are not ASCII text") from None
    fmt = None
    elements: list[tuple[str, int, list[PlyProperty]]] = []
    for number, line in enumerate(text.split("\n")[1:], start=2):
        # Words as C++'s stream >> splits them (space, \t, \n, \v, \f, \r): str.split
        # would also split at \x1c-\x1f, which Mitsuba's header reader takes as letters.
        words = [word.decode("ascii") for word in line.encode("ascii").split()]
        if not words or words[0] == "comment":
            continue
        keyword = words[0]
        if keyword == "end_header":
            break
        if keyword == "format":
            fmt = _ply_format(words, fmt)
        elif keyword == "element":
            elements.append(_ply_element(words, elements))
        elif keyword == "property":
            if fmt is None or not elements:
                raise MeshFileError(f"PLY header line {number}: a property before the "
                                    f"{'format' if fmt is None else 'first element'} line")
            elements[-1][2].append(_ply_property(words, elements[-1]))
        else:
            raise MeshFileError(f"PLY header line {number}: unknown keyword "
                                f"'{shortened(keyword, 40)}' (Mitsuba 3.9's ply plugin reads "
                                f"format, comment, element, property and end_header only)")
    if fmt is None:
        raise MeshFileError("the PLY header has no format line")
    header = _ply_checked(fmt, tuple(PlyElement(n, c, tuple(p)) for n, c, p in elements), end)
    _ply_fits(header, size)
    return header


def _header_end(head: bytes) -> int:
    """The offset just past the ``end_header`` line."""
    at = 0
    while True:
        nl = head.find(b"\n", at)
        if nl < 0:
            raise MeshFileError(f"the PLY header does not end: no end_header line within its "
                                f"first {MAX_PLY_HEADER_BYTES} bytes")
        if head[at:nl].strip() == b"end_header":
            return nl + 1
        at = nl + 1


def _ply_format(words, seen) -> str:
    if seen is not None:
        raise MeshFileError("the PLY header has two format lines")
    if len(words) != 3 or words[1] not in _PLY_FORMATS:
        found = shortened(" ".join(words[1:]), 60)
        raise MeshFileError(f"unknown PLY format '{found}' (ascii, binary_little_endian or "
                            f"binary_big_endian, version 1.0)")
    if words[2] != "1.0":
        raise MeshFileError(f"PLY version {shortened(words[2], 20)}; Mitsuba reads version "
                            f"1.0")
    return words[1]


def _ply_element(words, elements):
    if len(words) != 3 or not words[2].isdigit():
        raise MeshFileError(f"a PLY element line is 'element NAME COUNT', found "
                            f"'{shortened(' '.join(words), 60)}'")
    name = words[1]
    if len(words[2].lstrip("0")) > 100:         # int() refuses 4300 digits and more
        raise MeshFileError(f"the PLY element '{shortened(name, 40)}' declares "
                            f"{shortened(words[2], 30)} records, more than a mesh file holds")
    if any(e[0] == name for e in elements):
        raise MeshFileError(f"the PLY header declares the element '{shortened(name, 40)}' "
                            f"twice")
    return name, int(words[2]), []


def _ply_type(word) -> str:
    if word not in PLY_TYPES:
        raise MeshFileError(f"unknown PLY property type '{shortened(word, 40)}'")
    return word


def _ply_property(words, element) -> PlyProperty:
    if len(words) == 5 and words[1] == "list":
        prop = PlyProperty(words[4], _ply_type(words[3]), _ply_type(words[2]))
        if PLY_TYPES[prop.count_type][0] == "f":
            raise MeshFileError(f"the PLY list '{shortened(prop.name, 40)}' has a "
                                f"floating-point length")
    elif len(words) == 3 and words[1] != "list":
        prop = PlyProperty(words[2], _ply_type(words[1]))
    else:
        raise MeshFileError(f"a PLY property line is 'property TYPE NAME' or 'property list "
                            f"TYPE TYPE NAME', found '{shortened(' '.join(words), 60)}'")
    if any(p.name == prop.name for p in element[2]):
        raise MeshFileError(f"the PLY element '{shortened(element[0], 40)}' declares the "
                            f"property '{shortened(prop.name, 40)}' twice")
    return prop


def _ply_checked(fmt, elements, end) -> PlyHeader:
    names = [e.name for e in elements]
    if "vertex" not in names:
        raise MeshFileError("the PLY file has no vertex element")
    if "face" not in names or elements[names.index("face")].count == 0:
        raise MeshFileError("the PLY file has no faces")
    vertex, face = elements[names.index("vertex")], elements[names.index("face")]
    if vertex.count > MAX_MESH_VERTICES:
        raise MeshFileError(f"the PLY header declares {vertex.count} vertices; a mesh file "
                            f"holds at most {MAX_MESH_VERTICES}")
    if face.count > MAX_MESH_TRIANGLES:
        raise MeshFileError(f"the PLY header declares {face.count} faces; a scene's meshes "
                            f"hold at most {MAX_MESH_TRIANGLES} triangles")
    for element in elements:                # every walk over records is bounded
        name = shortened(element.name, 40)
        if element.count and not element.properties:
            raise MeshFileError(f"the PLY element '{name}' declares {element.count} records "
                                f"of no properties")
        if element.count > MAX_MESH_VERTICES:
            raise MeshFileError(f"the PLY header declares {element.count} '{name}' records; "
                                f"an element of a mesh file holds at most {MAX_MESH_VERTICES}")
    uv = next((pair for pair in _PLY_UV_NAMES
               if vertex.property(pair[0]) and vertex.property(pair[1])), None)
    for name in ("x", "y", "z") + (uv or ()):
        prop = vertex.property(name)
        if prop is None:
            raise MeshFileError("the PLY vertex element has no x, y and z properties")
        if prop.count_type is not None or PLY_TYPES[prop.type][0] != "f":
            kind = "a list" if prop.count_type else prop.type
            raise MeshFileError(f"the PLY vertex property {name} is {kind}; coordinates are "
                                f"float or double (Mitsuba reads an integer as a fraction of "
                                f"its type's range)")
    face_list = next((n for n in _PLY_FACE_LISTS if face.property(n)), None)
    prop = face.property(face_list) if face_list else None
    if prop is None or prop.count_type is None:
        raise MeshFileError("the PLY face element has no list property vertex_indices "
                            "(or vertex_index)")
    for element in elements:
        for other in element.properties:
            if other.count_type and other is not prop:
                raise MeshFileError(
                    f"the PLY element '{shortened(element.name, 40)}' has the list property "
                    f"'{shortened(other.name, 40)}': Mitsuba 3.9's ply plugin reads one list, "
                    f"a face's vertex indices, and misreads any other")
    if uv is not None and uv != ("u", "v") and (vertex.property("u") or vertex.property("v")):
        lone = "u" if vertex.property("u") else "v"
        raise MeshFileError(
            f"the PLY vertex element has a property {lone} without its pair beside "
            f"{uv[0]} and {uv[1]}: Mitsuba 3.9's ply plugin renames {uv[0]}, {uv[1]} to u, v "
            f"and refuses two properties named {lone}")
    if PLY_TYPES[prop.type][0] == "f":
        raise MeshFileError(f"the PLY face list {face_list} holds floating-point numbers; "
                            f"vertex indices are integers")
    return PlyHeader(fmt, elements, end, uv, face_list)


def _ply_fits(header: PlyHeader, size: int) -> None:
    """The body can hold what the header declares: every record takes at least its scalars'
    bytes and its lists' lengths (binary), or two bytes a number (ascii: a digit and a
    separator); a face's list at least 3 indices."""
    ascii_ = header.format == "ascii"
    least = 0
    for element in header.elements:
        record = 0
        for prop in element.properties:
            fewest = 3 if element.name == "face" and prop.name == header.face_list else 0
            if ascii_:
                record += 2 * (1 + fewest) if prop.count_type else 2
            else:
                record += PLY_TYPES[prop.count_type][1] + fewest * PLY_TYPES[prop.type][1] \
                    if prop.count_type else PLY_TYPES[prop.type][1]
        least += element.count * record
    if least > size - header.size + (1 if ascii_ else 0):   # ascii: no last separator
        counts = ", ".join(f"{e.count} {e.name}" for e in header.elements[:4])
        raise MeshFileError(f"the PLY header declares more than the file holds ({counts} "
                            f"records need at least {least} bytes, the file has "
                            f"{size - header.size} after its header)")


def _ply_body(f, header: PlyHeader, size: int) -> tuple:
    """Walk the PLY body (``f`` just past the header) element by element and return the
    bounds of its vertex positions and the largest |u|, |v| of its texture coordinates
    (None: it has none); MeshFileError on the first thing Mitsuba 3.9.1's
    ``ply`` plugin would not read as the reference tracer does:

    * a face whose list is not 3 indices long (Mitsuba reads triangles only: "incompatible
      contents -- is this a triangle mesh?"; the reference tracer would read a fan);
    * a face index outside 0 … V − 1 (Mitsuba would read past its vertex buffer);
    * a coordinate x, y, z (or the (u, v) read) not finite or beyond ±FLT_MAX (Mitsuba
      stores float32, where it would be ±∞, and refuses such a mesh with a traceback);
    * a body that ends inside an element, or goes on past the last one (Mitsuba refuses
      both).

    Binary: fixed-size records are read :data:`_CHUNK` bytes at a time and their columns
    taken as stepped slices (a face's list, 3 indices, fixed-size as long as every length
    is 3, which is checked first); records with other lists are walked one by one. Ascii:
    the words are streamed and taken a chunk of records at a time."""
    walk = _AsciiWalk(f) if header.format == "ascii" else \
        _BinaryWalk(f, "little" if header.format == "binary_little_endian" else "big", size)
    vertices = header.element("vertex").count
    names = ("x", "y", "z") + (header.uv or ())
    lo, hi = [math.inf] * 3, [-math.inf] * 3
    uv_extent = 0.0
    for element in header.elements:
        if element.name == "vertex":
            for columns in walk.scalars(element, names):
                for i, name in enumerate(names):
                    least, most = _coordinate_range(
                        columns[name], "vertex coordinate" if i < 3 else "texture coordinate")
                    if i < 3:
                        lo[i], hi[i] = min(lo[i], least), max(hi[i], most)
                    else:
                        uv_extent = max(uv_extent, -least, most)
        elif element.name == "face":
            for indices in walk.triangles(element, header.face_list):
                least, most = min(indices), max(indices)
                if least < 0 or most >= vertices:
                    bad = least if least < 0 else most
                    raise MeshFileError(f"a face refers to vertex {bad}, which does not exist "
                                        f"(the file has {vertices}, numbered from 0)")
        else:
            walk.skip(element)
    walk.finish()
    return (tuple(lo), tuple(hi)), (uv_extent if header.uv else None)


def _coordinate_range(values, what: str) -> tuple[float, float]:
    """(min, max) of a column of coordinates, each finite and within ±FLT_MAX. Their sum
    is finite exactly when none is NaN or ±∞ (or, of finite ones, when none is huge: 3·10⁶
    numbers within ±FLT_MAX sum to at most 10⁴⁵), so one pass decides the common case."""
    if not math.isfinite(sum(values)) and not all(map(math.isfinite, values)):
        raise MeshFileError(f"a {what} is not finite")
    least, most = min(values), max(values)
    if max(-least, most) > FLT_MAX:
        raise MeshFileError(f"a {what} {_beyond_float32(most if most > -least else least)}")
    return least, most


def _beyond_float32(value: float) -> str:
    return (f"{value!r} is beyond float32's range (±{FLT_MAX!r}), the numbers Mitsuba "
            f"holds its meshes in")


def _polygon(n, element) -> MeshFileError:
    return MeshFileError(f"a face of {n} vertices: Mitsuba 3.9's ply plugin reads triangles "
                         f"only (split the {element.name}s into triangles)")


def _ends_inside(element) -> MeshFileError:
    return MeshFileError(f"the file ends inside its {element.name} element")


def _goes_on(more: str) -> MeshFileError:
    return MeshFileError(f"the file goes on past the elements its header declares{more}")


#: A PLY body is taken about this many bytes (binary) or words (ascii) at a time.
_CHUNK = 1 << 20

#: struct's (and memoryview.cast's) code of each PLY number (kind, bytes).
_CODES = {("i", 1): "b", ("u", 1): "B", ("i", 2): "h", ("u", 2): "H", ("i", 4): "i",
          ("u", 4): "I", ("i", 8): "q", ("u", 8): "Q", ("f", 2): "e", ("f", 4): "f",
          ("f", 8): "d"}


def _chunks(count: int, width: int):
    """The records in each chunk of ``count`` records of ``width`` bytes or words."""
    step = max(1, _CHUNK // max(width, 1))
    for first in range(0, count, step):
        yield min(step, count - first)


class _BinaryWalk:
    """A binary PLY body, element by element (:func:`_ply_body`)."""

    def __init__(self, f, order: str, size: int) -> None:
        self.f, self.order, self.size = f, order, size
        self.swap = order != sys.byteorder

    def _width(self, type_: str) -> int:
        return PLY_TYPES[type_][1]

    def _read(self, n: int, element) -> bytes:
        """``n`` bytes, refused before they are asked for when the file holds fewer."""
        if n > self.size - self.f.tell():
            raise _ends_inside(element)
        return self.f.read(n)

    def _column(self, block: bytes, records: int, record: int, offset: int, type_: str):
        """The numbers of type ``type_`` at ``offset`` of each of ``records`` records of
        ``record`` bytes: byte j of every number is the stepped slice block[offset + j::
        record] (its mirror image where the file's byte order is not this machine's),
        laid side by side and cast."""
        kind, width = PLY_TYPES[type_]
        out = bytearray(records * width)
        for j in range(width):
            at = offset + (width - 1 - j if self.swap else j)
            out[j::width] = block[at:records * record:record]
        code = _CODES[kind, width]
        if code == "e":                          # half: not a format memoryview casts to
            return [v for (v,) in struct.iter_unpack("=e", out)]
        return memoryview(out).cast(code)

    def skip(self, element) -> None:
        record = sum(self._width(p.type) for p in element.properties)
        if self.f.tell() + element.count * record > self.size:
            raise _ends_inside(element)
        self.f.seek(element.count * record, os.SEEK_CUR)

    def scalars(self, element, names):
        """Chunks of {name: the values of that scalar property}."""
        offsets, record = {}, 0
        for p in element.properties:
            offsets[p.name] = (record, p.type)
            record += self._width(p.type)
        for records in _chunks(element.count, record):
            block = self._read(records * record, element)
            yield {name: self._column(block, records, record, *offsets[name]) for name in names}

    def triangles(self, element, list_name: str):
        """Chunks of the face lists' indices, every list checked to hold 3. With the face
        list the only list, a record of R bytes (the list's length at ``before``) while
        every length is 3: a chunk's lengths are compared byte column by byte column with
        3's bytes, and the first record where one differs (every record before it being a
        triangle, it is where a triangle's length would be) is refused. (The face list
        is the file's only list: the header refuses any other.)"""
        prop = element.property(list_name)
        at = element.properties.index(prop)
        before = sum(self._width(p.type) for p in element.properties[:at])
        width, size = self._width(prop.count_type), self._width(prop.type)
        record = sum(self._width(p.type) for p in element.properties) + width + 2 * size
        three = (3).to_bytes(width, self.order)
        for records in _chunks(element.count, record):
            block = self.f.read(min(records * record, self.size - self.f.tell()))
            whole = len(block) // record
            bad = whole                          # the first record whose length is not 3
            for j in range(width):               # each byte of the length, every record
                column = block[before + j:whole * record:record]
                if column != three[j:j + 1] * whole:
                    bad = min(bad, next(k for k, b in enumerate(column) if b != three[j]))
            if bad < whole or len(block) >= bad * record + before + width:
                start = bad * record + before               # a length, complete or not 3
                n = int.from_bytes(block[start:start + width], self.order,
                                   signed=PLY_TYPES[prop.count_type][0] == "i")
                if n != 3:
                    raise _polygon(n, element)
            if whole < records:
                raise _ends_inside(element)
            indices = []
            for k in range(3):
                indices.extend(self._column(block, records, record, before + width + k * size,
                                            prop.type))
            yield indices

    def finish(self) -> None:
        more = self.size - self.f.tell()
        if more > 0:
            raise _goes_on(f" ({more} more byte{'s' if more > 1 else ''})")


class _AsciiWalk:
    """An ascii PLY body, element by element (:func:`_ply_body`): its words streamed line
    by line, every word checked as Mitsuba 3.9's ply plugin reads it — with C++'s stream
    ``>>`` of the property's type — so that a file it would refuse is refused here:

    * an integer property's word is a whole number written as one (``[+-]digits``: ``2e0``
      or ``2.0`` leave a tail that the next ``>>`` fails on) within its type's range
      (unsigned: 0 and up; C++ refuses a value that does not fit);
    * a floating-point property's word is a finite number within its type's range (half:
      below 65520, which rounds to infinity; float: within ±FLT_MAX);
    * a line holding ``_`` is refused (Python's float and int take 1_0, C++ does not)."""

    def __init__(self, f) -> None:
        self.words = self._words(f)

    @staticmethod
    def _words(f):
        for line in f:
            if b"_" in line:
                raise _not_a_number()
            yield from line.split()

    def _take(self, n: int, element) -> list:
        words = list(itertools.islice(self.words, n))
        if len(words) < n:
            raise _ends_inside(element)
        return words

    def _columns(self, element, records: int, width: int, words: list, offset=None,
                 names=()):
        """Every scalar property's column of a chunk of ``records`` records of ``width``
        words, checked by its type (class docstring): {name: values}; ``names``: the
        vertex coordinates read, x y z then u v, named so in a refusal."""
        out = {}
        for k, p in enumerate(element.properties):
            if not p.count_type:
                at = k if offset is None else offset[p.name]
                what = None if p.name not in names else \
                    "vertex coordinate" if names.index(p.name) < 3 else "texture coordinate"
                out[p.name] = _ascii_values(words[at:records * width:width], p.type, what)
        return out

    def skip(self, element) -> None:
        width = len(element.properties)
        for records in _chunks(element.count, width):
            self._columns(element, records, width, self._take(records * width, element))

    def scalars(self, element, names):
        width = len(element.properties)
        for records in _chunks(element.count, width):
            columns = self._columns(element, records, width,
                                    self._take(records * width, element), names=names)
            yield {name: columns[name] for name in names}

    def triangles(self, element, list_name: str):
        """As _BinaryWalk.triangles: while every length is 3, a record is the scalars,
        the length and 3 indices; the first record whose length is not 3 is refused."""
        prop = element.property(list_name)
        before = element.properties.index(prop)
        width = len(element.properties) + 3
        offset = {p.name: k + (3 if k > before else 0)
                  for k, p in enumerate(element.properties)}
        for records in _chunks(element.count, width):
            words = list(itertools.islice(self.words, records * width))
            whole = len(words) // width
            lengths = words[before:len(words):width]
            if lengths.count(b"3") < len(lengths):
                for n in _ascii_values(lengths, prop.count_type):
                    if n != 3:
                        raise _polygon(n, element)
            if whole < records:
                raise _ends_inside(element)
            self._columns(element, records, width, words, offset)
            indices = []
            for k in range(3):
                indices.extend(_ascii_values(words[before + 1 + k::width], prop.type))
            yield indices

    def finish(self) -> None:
        if next(self.words, None) is not None:
            raise _goes_on("")


#: An integer as C++'s stream >> reads one whole: a sign, then digits.
_INTEGER = re.compile(rb"[+-]?[0-9]+")
#: The range of each PLY integer type, (least, greatest).
_INTEGER_RANGES = {(kind, size): ((-(1 << (8 * size - 1)), (1 << (8 * size - 1)) - 1)
                                  if kind == "i" else (0, (1 << (8 * size)) - 1))
                   for kind, size in set(PLY_TYPES.values()) if kind != "f"}
#: A half (IEEE binary16) rounds to infinity from this magnitude (its largest, 65504, plus
#: half its last step).
_HALF_OVERFLOW = 65520.0


def _ascii_values(words, ply_type: str, what: str | None = None) -> list:
    """The numbers of an ascii body's ``words`` of one property, checked by its type
    (_AsciiWalk's docstring), or MeshFileError naming each as ``what`` (default: "TYPE
    value")."""
    kind, size = PLY_TYPES[ply_type]
    what = what or f"{ply_type} value"
    if kind == "f":
        values = _floats(words)
        if not math.isfinite(sum(values)) and not all(map(math.isfinite, values)):
            raise MeshFileError(f"a {what} is not finite")
        if values:
            least, most = min(values), max(values)
            big = most if most > -least else least
            if size == 4 and abs(big) > FLT_MAX:
                raise MeshFileError(f"a {what} {_beyond_float32(big)}")
            if size == 2 and abs(big) >= _HALF_OVERFLOW:
                raise MeshFileError(f"a {what} {big:g} is beyond a half's range (±65504; "
                                    f"from ±{_HALF_OVERFLOW:g} it rounds to infinity)")
        return values
    try:
        values = list(map(int, words))
    except ValueError:          # not [+-]digits, or more digits than int() takes (4300)
        word = next((w for w in words if not _INTEGER.fullmatch(w)), None)
        if word is None:
            raise MeshFileError(f"a {ply_type} value of thousands of digits, outside a "
                                f"{ply_type}'s range") from None
        raise MeshFileError(f"the {ply_type} value '{shortened(word.decode('latin-1'), 20)}' "
                            f"is not written as a whole number, as integers are (Mitsuba's "
                            f"reader stops at a '.' or an 'e')") from None
    least, most = _INTEGER_RANGES[kind, size]
    if values and (min(values) < least or max(values) > most):
        bad = min(values) if min(values) < least else max(values)
        raise MeshFileError(f"the {ply_type} value {bad} is outside a {ply_type}'s range "
                            f"({least} … {most})")
    return values


def _not_a_number() -> MeshFileError:
    return MeshFileError("the PLY body holds something that is not a number")


def _floats(words) -> list[float]:
    try:
        return list(map(float, words))
    except ValueError:
        raise _not_a_number() from None


# ---------------------------------------------------------------------------
# OBJ

def obj_statements(f, relative: bool = False):
    """The OBJ file open as ``f`` (binary), statement by statement, checked (module
    docstring): yields ``("v", (x, y, z))``, ``("vt", (u, v))`` as written, and ``("f",
    ((v, t), …))`` with 0-based indices resolved, t = −1 where a corner names no ``vt``.
    Negative (relative) indices are resolved against the elements defined so far when
    ``relative``, else refused (Mitsuba 3.9's OBJ reader takes none: ``strtoul`` makes −1
    an index past every vertex). Normals are checked and counted, not yielded.
    MeshFileError ``line N: …`` on the first malformed line or the first past a limit;
    ``the file has no faces`` at the end when it has none."""
    counts = {b"v": 0, b"vt": 0, b"vn": 0}
    triangles = 0
    number = 0
    lines = _obj_lines(f)
    first = next(lines, (b"", False))
    if first[0].startswith(_UTF8_BOM) and first[0][3:].split(b"#", 1)[0].split()[:1] in _READ_FIRST:
        raise MeshFileError("line 1: the file begins with a UTF-8 byte order mark, which "
                            "Mitsuba's OBJ reader takes as part of the line's keyword, so it "
                            "would drop the line: save the file without it")
    for number, (line, odd) in enumerate(itertools.chain((first,), lines), start=1):
        if b"#" in line:
            text = line.split(b"#", 1)[0]
            glued = not text[-1:].isspace()      # a face's last corner right before the #
        else:
            text, glued = line, False
        words = text.split()
        if not words:
            continue
        keyword = words[0]
        if odd and (keyword in counts or keyword == b"f"):
            _obj_separators(text, number)
        if keyword in counts:
            numbers = _obj_numbers(words, number, b"_" not in line)
            counts[keyword] += 1
            if keyword == b"vn":
                if len(numbers) < 3 or not any(numbers[:3]):
                    raise MeshFileError(f"line {number}: a normal (vn) needs three numbers, "
                                        f"not all 0")
                continue
            need = 3 if keyword == b"v" else 2
            if len(numbers) < need:
                what = "a vertex (v)" if keyword == b"v" else "a texture coordinate (vt)"
                raise MeshFileError(f"line {number}: {what} needs {need} numbers")
            big = max(numbers[:need], key=abs)
            if abs(big) > FLT_MAX:
                raise MeshFileError(f"line {number}: the number {_beyond_float32(big)}")
            if counts[keyword] > MAX_MESH_VERTICES:
                raise MeshFileError(f"line {number}: more than {MAX_MESH_VERTICES} "
                                    f"{keyword.decode()} lines, the most a mesh file holds")
            yield keyword.decode(), numbers[:need]
        elif keyword == b"f":
            if glued:
                raise MeshFileError(f"line {number}: a comment (#) right after a face's last "
                                    f"corner; Mitsuba's OBJ reader drops a corner not followed "
                                    f"by a space (write one before the #)")
            corners = _obj_face(words, number, counts, relative, b"_" not in line)
            if len(corners) < 3:
                raise MeshFileError(f"line {number}: a face needs 3 or more vertices")
            triangles += len(corners) - 2
            if triangles > MAX_MESH_TRIANGLES:
                raise MeshFileError(f"line {number}: the faces pass {MAX_MESH_TRIANGLES} "
                                    f"triangles, the most a scene's meshes hold")
            yield "f", corners
    if triangles == 0:
        raise MeshFileError("the OBJ file has no faces (f lines)")


_UTF8_BOM = b"\xef\xbb\xbf"
#: The first words of a first line that a byte order mark before them would make Mitsuba
#: drop (lines of other keywords are dropped by both readers anyway).
_READ_FIRST = ([b"v"], [b"vt"], [b"vn"], [b"f"])


def _obj_lines(f):
    """The lines of the OBJ file open as ``f`` (binary), without their newline, each with
    whether its part of the file holds a form feed, vertical tab or carriage return (then
    the line is checked for them: :func:`_obj_separators`): read a megabyte at a time, so
    that those bytes are looked for once a block rather than once a line. A line longer
    than :data:`MAX_OBJ_LINE_BYTES` is refused as soon as it is (never held whole)."""
    rest, number = b"", 0
    for block in iter(lambda: f.read(_CHUNK), b""):
        block = rest + block
        cut = block.rfind(b"\n") + 1
        lines = block[:cut].split(b"\n")
        lines.pop()                              # after the last newline: the next block's
        rest = block[cut:]
        for line in lines:
            number += 1
            if len(line) > MAX_OBJ_LINE_BYTES:
                raise _long_line(number)
        if len(rest) > MAX_OBJ_LINE_BYTES:
            raise _long_line(number + 1)
        odd = b"\r" in block or b"\x0b" in block or b"\x0c" in block
        for line in lines:
            yield line, odd
    if rest:
        yield rest, b"\r" in rest or b"\x0b" in rest or b"\x0c" in rest


def _long_line(number: int) -> MeshFileError:
    return MeshFileError(f"line {number} is longer than {MAX_OBJ_LINE_BYTES} bytes, the most "
                         f"Mitsuba's OBJ reader takes")


def _obj_separators(text: bytes, number: int) -> None:
    """Refuse a statement line (``text``: without its comment and newline) that Mitsuba
    3.9's OBJ reader splits otherwise than into its words: it separates them by spaces and
    tabs only, so a form feed, vertical tab, or carriage return other than the line's last
    character drops the line or fails it ("could not parse line")."""
    if b"\x0b" in text or b"\x0c" in text or b"\r" in text.rstrip(b"\r"):
        raise MeshFileError(f"line {number}: a form feed, vertical tab or carriage return "
                            f"within the line; Mitsuba's OBJ reader separates numbers by "
                            f"spaces and tabs only")


def _obj_numbers(words, number, plain: bool) -> tuple[float, ...]:
    """The numbers after the keyword; ``plain``: the line holds no ``_`` (Python's float
    takes 1_0, C's strtof, Mitsuba's, does not)."""
    try:
        if not plain:
            raise ValueError
        values = tuple(map(float, words[1:]))
    except ValueError:
        raise MeshFileError(f"line {number}: '{shortened(words[0].decode('latin-1'), 8)}' "
                            f"is followed by something that is not a number") from None
    if not all(map(math.isfinite, values)):
        raise MeshFileError(f"line {number}: a number that is not finite")
    return values


_OBJ_ELEMENTS = ((b"v", "vertex"), (b"vt", "texture coordinate"), (b"vn", "normal"))


def _obj_face(words, number: int, counts, relative: bool, plain: bool) -> tuple:
    """The corners (v, t) of ``f`` line ``number`` (``words`` with the keyword), 0-based.
    The common case, indices from 1 within the counts on a line without ``_`` (``plain``:
    Python's int takes 1_0, strtoul not), is read here; anything else goes to
    :func:`_obj_corner`, which resolves relative indices and says what is wrong."""
    nv, nt, nn = counts[b"v"], counts[b"vt"], counts[b"vn"]
    out = []
    for word in words[1:]:
        parts = word.split(b"/")
        if plain and len(parts) <= 3:
            try:
                v = int(parts[0])
                t = int(parts[1]) if len(parts) > 1 and parts[1] else 0
                n = int(parts[2]) if len(parts) > 2 and parts[2] else 0
                if 0 < v <= nv and (0 < t <= nt or (t == 0 and (len(parts) < 2 or not parts[1]))) \
                        and (0 < n <= nn or (n == 0 and (len(parts) < 3 or not parts[2]))):
                    out.append((v - 1, t - 1))
                    continue
            except ValueError:
                pass
        out.append(_obj_corner(word, number, counts, relative))
    return tuple(out)


def _obj_corner(word: bytes, number: int, counts, relative: bool) -> tuple[int, int]:
    """(v, t) of one face corner ``v``, ``v/t``, ``v//n`` or ``v/t/n``, 0-based (t = −1:
    none); n is checked only."""
    parts = word.split(b"/")
    if len(parts) > 3 or not parts[0]:
        raise MeshFileError(f"line {number}: a face corner is v, v/vt, v//vn or v/vt/vn, "
                            f"found '{shortened(word.decode('latin-1'), 40)}'")
    out = []
    for part, (keyword, what) in zip(parts, _OBJ_ELEMENTS):
        if not part:                     # v//n: no texture coordinate
            out.append(-1)
            continue
        digits = part[1:] if part[:1] == b"-" else part
        if not digits.isdigit():
            raise MeshFileError(f"line {number}: a face index is a whole number, found "
                                f"'{shortened(part.decode('latin-1'), 40)}'")
        index, defined = int(part), counts[keyword]
        if index < 0 and not relative:
            raise MeshFileError(f"line {number}: a negative (relative) index {index}; "
                                f"Mitsuba 3.9's OBJ reader takes indices counted from 1 only")
        resolved = index - 1 if index > 0 else defined + index
        if index == 0 or not 0 <= resolved < defined:
            raise MeshFileError(f"line {number}: {what} {index} does not exist (OBJ counts "
                                f"from 1, or back from -1; {defined} defined so far)")
        out.append(resolved)
    return out[0], (out[1] if len(out) > 1 else -1)
