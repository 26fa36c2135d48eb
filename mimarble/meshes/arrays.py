"""The renderers' mesh files: PLY (ascii, binary) and OBJ read into float64 NumPy arrays.

``read_mesh(path)`` -> :class:`MeshData` (positions (V, 3) float64, triangles (T, 3)
int64, uv (V, 2) float64 or None, normals (V, 3) float64 or None), or :class:`~mimarble.meshes.limits.MeshFileError`
in one sentence. Imported by the renderers only (the parser reads facts.py, without
NumPy). What a file may hold and every limit are limits.py's; the PLY header is parsed and
checked by the code the facts use (:func:`~mimarble.meshes.ply_header.ply_header`: counts
within the limits and within the file's size before anything is allocated), the OBJ lines
are tokenised and checked by it too (:func:`~mimarble.meshes.obj_lines.obj_statements`,
which refuses the line past a limit); the body of a PLY file is read here with NumPy (``numpy.frombuffer`` with the header's
types and byte order; ascii a megabyte at a time, its words converted by NumPy).

Conventions, as Mitsuba 3.9.1 loads the same files (its src/shapes/obj.cpp, ply.cpp and
ply.h at tag v3.9.1, read for this module):

* **Polygons** become fans from their first corner, (v₀, vᵢ, vᵢ₊₁) for i = 1 … n − 2: Mitsuba's
  OBJ reader keeps ``tri[0]`` and shifts ``tri[1] = tri[2]; tri[2] = id`` for every corner
  past the third. Its PLY reader takes **triangles only**: the list length is a checked
  field of value 3 ("incompatible contents -- is this a triangle mesh?"), so a PLY polygon
  is read here as a fan, but the scene language refuses it
  (:func:`~mimarble.meshes.facts.mesh_facts`), as the tracer's :func:`read_meshes
  <mimarble.reference.tracer.read_meshes>` does, for Mitsuba's sake.
* **OBJ (u, v)**: Mitsuba's ``obj`` plugin has ``flip_tex_coords`` true by default and
  stores (u, 1 − v) for ``vt u v``; so does this reader. A vertex is a distinct
  (v, vt, vn) triple of a face corner, as Mitsuba keys its vertices (so the vertex normals
  a smooth mesh computes, per vertex, are split where Mitsuba's are). Mitsuba
  3.9.1 reads indices with ``strtoul`` and refuses **negative (relative) indices** as
  invalid vertices; they are read here (−1: the last element defined so far), as the OBJ
  format defines them, and refused by the scene language as PLY polygons are.
* **PLY (u, v)**: as written (``flip_tex_coords`` false by default for ``ply``), from the
  properties ``u v``, else ``texture_u texture_v``, else ``s t``.
* **Normals** (PLY ``nx ny nz``, OBJ ``vn`` named by every corner): as written, in the
  file's coordinates (not normalised: the renderer places and normalises them); None
  where the file has none, or an OBJ's corners do not all name one.

Every coordinate must be finite (Mitsuba refuses non-finite positions too); every index
must name a vertex of the file.
"""

from __future__ import annotations

import os
from array import array
from dataclasses import dataclass

import numpy as np

from .limits import (MAX_MESH_TRIANGLES, MAX_NORMAL, MIN_NORMAL, MeshFileError, long_normal,
                     open_mesh, zero_normal)
from .obj_lines import obj_statements
from .ply_header import PLY_NORMAL_NAMES, PLY_TYPES, PlyHeader, ply_header

__all__ = ["MeshData", "MeshFileError", "read_mesh", "fan_triangles"]


@dataclass(frozen=True)
class MeshData:
    """A mesh file's triangles: ``positions`` (V, 3) float64 in the file's coordinates,
    ``triangles`` (T, 3) int64 indices into them (polygons as fans), ``uv`` (V, 2) float64
    per vertex (Mitsuba's convention, module docstring) or None, ``normals`` (V, 3)
    float64 per vertex as the file writes them, or None."""

    positions: np.ndarray
    triangles: np.ndarray
    uv: np.ndarray | None
    normals: np.ndarray | None = None


def read_mesh(path, relative: bool = True) -> MeshData:
    """The mesh file at ``path`` (.ply or .obj, by its name) -> MeshData, or MeshFileError.
    ``relative``: an OBJ's negative indices are read (else refused, as the scene language
    refuses them for Mitsuba's sake: obj_lines.obj_statements)."""
    name = os.fspath(path).lower()
    f, size = open_mesh(path)
    with f:
        if name.endswith(".ply"):
            return _read_ply(f, size)
        if name.endswith(".obj"):
            return _read_obj(f, relative)
    raise MeshFileError("a mesh file is PLY (.ply) or Wavefront OBJ (.obj), by its name's "
                        "ending")


def fan_triangles(offsets: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """The fans of polygons whose corners are ``offsets[f] … offsets[f] + sizes[f] − 1``
    (sizes ≥ 3) of one corner array: (T, 3) int64 corner numbers, triangle i of polygon f
    = (o, o + i, o + i + 1), i = 1 … n − 2, polygons in order."""
    sizes = np.asarray(sizes, dtype=np.int64)
    per = sizes - 2
    total = int(per.sum())
    if total > MAX_MESH_TRIANGLES:
        raise MeshFileError(f"the faces make {total} triangles; a scene's meshes hold at most "
                            f"{MAX_MESH_TRIANGLES}")
    face = np.repeat(np.arange(len(sizes)), per)
    first = np.cumsum(per) - per                        # each polygon's first triangle
    i = np.arange(total, dtype=np.int64) - first[face] + 1
    o = np.asarray(offsets, dtype=np.int64)[face]
    return np.stack([o, o + i, o + i + 1], axis=1)


# ---------------------------------------------------------------------------
# OBJ

def _read_obj(f, relative: bool) -> MeshData:
    """One pass over the checked statements; corners are collected as (v, t, n) index
    triples and made vertices by np.unique (each distinct triple once, as Mitsuba keys
    its vertices)."""
    positions, texcoords, normals = array("d"), array("d"), array("d")   # 8 bytes a number
    corners, sizes = array("q"), array("q")               # (v, t, n) triples; corners per face
    for kind, value in obj_statements(f, relative):
        if kind == "v":
            positions.extend(value)
        elif kind == "vt":
            texcoords.extend(value)
        elif kind == "vn":
            normals.extend(value)
        else:
            sizes.append(len(value))
            for triple in value:
                corners.extend(triple)
    pos = np.frombuffer(positions, dtype=np.float64).reshape(-1, 3)
    triples = np.frombuffer(corners, dtype=np.int64).reshape(-1, 3)
    unique, vertex_of_corner = _distinct_rows(
        triples, (len(positions) // 3, len(texcoords) // 2 + 1, len(normals) // 3 + 1))
    sizes = np.frombuffer(sizes, dtype=np.int64)
    triangles = vertex_of_corner.reshape(-1)[fan_triangles(np.cumsum(sizes) - sizes, sizes)]
    uv = normal = None
    if triples.size and np.all(triples[:, 1] >= 0):
        tex = np.frombuffer(texcoords, dtype=np.float64).reshape(-1, 2)[unique[:, 1]]
        uv = np.stack([tex[:, 0], 1.0 - tex[:, 1]], axis=1)        # Mitsuba's flip
    if triples.size and np.all(triples[:, 2] >= 0):
        normal = np.frombuffer(normals, dtype=np.float64).reshape(-1, 3)[unique[:, 2]]
    return MeshData(pos[unique[:, 0]], triangles, uv, normal)


def _distinct_rows(triples: np.ndarray, ranges: tuple) -> tuple:
    """(the distinct rows of ``triples`` (N, 3) in lexicographic order, each row's number
    among them (N,)): np.unique's answer with axis 0, from one int64 key per row
    (v·R_t + t + 1)·R_n + n + 1 where ``ranges`` (R_v, R_t, R_n: the counts of v, and of
    vt and vn plus one for −1) keep it below 2⁶³ — twenty times faster than np.unique on
    rows at a million corners — else by a lexicographic sort."""
    r_v, r_t, r_n = ranges
    if r_v * r_t * r_n < 1 << 62:
        key = (triples[:, 0] * r_t + triples[:, 1] + 1) * r_n + triples[:, 2] + 1
        keys, inverse = np.unique(key, return_inverse=True)
        rest, n = np.divmod(keys, r_n)
        v, t = np.divmod(rest, r_t)
        return np.stack([v, t - 1, n - 1], axis=1), inverse.reshape(-1)
    order = np.lexsort((triples[:, 2], triples[:, 1], triples[:, 0]))
    ordered = triples[order]
    new = np.r_[True, np.any(ordered[1:] != ordered[:-1], axis=1)]
    inverse = np.empty(len(triples), dtype=np.int64)
    inverse[order] = np.cumsum(new) - 1
    return ordered[new], inverse


# ---------------------------------------------------------------------------
# PLY

def _read_ply(f, size: int) -> MeshData:
    header = ply_header(f, size)
    body = f.read()
    reader = _AsciiBody(body, _most_numbers(header)) if header.format == "ascii" else \
        _BinaryBody(body, "<" if header.format == "binary_little_endian" else ">")
    vertices = faces = None
    for element in header.elements:
        columns = reader.element(element)
        if element.name == "vertex":
            vertices = columns
        elif element.name == "face":
            faces = columns[header.face_list]
    reader.finish()
    return _ply_mesh(header, vertices, faces)


def _ply_mesh(header: PlyHeader, vertices: dict, faces) -> MeshData:
    def column(name):
        """A vertex property as its declared type holds it: an ascii body's decimals are
        rounded to a half or a float as a binary one stores them (and Mitsuba reads them)."""
        values = vertices[name]
        if header.format == "ascii":
            with np.errstate(over="ignore"):     # past the type's range: ∞, refused below
                values = values.astype(_dtype("=", header.element("vertex").property(name).type))
        return values.astype(np.float64)

    positions = np.stack([column(c) for c in "xyz"], axis=1)
    if not np.all(np.isfinite(positions)):
        raise MeshFileError("a vertex coordinate is not finite")
    uv = normals = None
    if header.uv is not None:
        uv = np.stack([column(c) for c in header.uv], axis=1)
        if not np.all(np.isfinite(uv)):
            raise MeshFileError("a texture coordinate is not finite")
    if header.normals:
        normals = np.stack([column(c) for c in PLY_NORMAL_NAMES], axis=1)
        if not np.all(np.isfinite(normals)):
            raise MeshFileError("a vertex normal is not finite")
        largest = np.max(np.abs(normals), axis=1)
        short = largest < MIN_NORMAL
        if short.any():
            raise MeshFileError(zero_normal(normals[np.argmax(short)]))
        long = largest > MAX_NORMAL
        if long.any():
            raise MeshFileError(long_normal(normals[np.argmax(long)]))
    indices, sizes = faces
    if indices.dtype.kind == "f":                # ascii: numbers, to be whole
        if not np.all(np.abs(indices) < 2.0 ** 62) or not np.all(indices == np.floor(indices)):
            raise MeshFileError("a face's vertex index is not a whole number")
    indices = indices.astype(np.int64)
    if np.any(sizes < 3):
        raise MeshFileError(f"a face of {int(sizes.min())} vertices; a face needs 3 or more")
    if indices.size and (indices.min() < 0 or indices.max() >= len(positions)):
        bad = int(indices.min()) if indices.min() < 0 else int(indices.max())
        raise MeshFileError(f"a face refers to vertex {bad}, which does not exist (the file "
                            f"has {len(positions)}, numbered from 0)")
    corners = fan_triangles(np.cumsum(sizes) - sizes, sizes)
    return MeshData(positions, indices[corners], uv, normals)


def _dtype(byte_order: str, ply_type: str) -> np.dtype:
    kind, size = PLY_TYPES[ply_type]
    return np.dtype(f"{byte_order}{kind}{size}")


class _Body:
    """A PLY body read element by element from ``at`` (counted in ``unit``): ``element(e)`` ->
    {property: values}, a list's values as (flat int64 values, lengths)."""

    unit = "byte"
    at = 0

    def size(self) -> int:
        raise NotImplementedError

    def finish(self) -> None:
        """Refuse what is left past the declared elements (Mitsuba refuses it too)."""
        more = self.size() - self.at
        if more:
            raise MeshFileError(f"the file goes on past the elements its header declares "
                                f"({more} more {self.unit}{'s' if more > 1 else ''})")


class _BinaryBody(_Body):
    """A binary PLY body (its values at their byte offsets)."""

    def __init__(self, body: bytes, byte_order: str) -> None:
        self.body, self.order, self.at = body, byte_order, 0

    def element(self, element) -> dict:
        lists = [p for p in element.properties if p.count_type]
        if element.count == 0:
            return {p.name: (np.zeros(0, np.int64), np.zeros(0, np.int64)) if p.count_type
                    else np.zeros(0) for p in element.properties}
        # The fast path: every record's lists as long as the first record's, so that the
        # element is one structured array.
        lengths = self._first_lengths(element)
        fields = []
        for p in element.properties:
            if p.count_type:
                fields.append((p.name + ".n", _dtype(self.order, p.count_type)))
                fields.append((p.name, _dtype(self.order, p.type), (lengths[p.name],)))
            else:
                fields.append((p.name, _dtype(self.order, p.type)))
        record = np.dtype(fields)
        if self.at + element.count * record.itemsize <= len(self.body):
            table = np.frombuffer(self.body, record, count=element.count, offset=self.at)
            if all(np.all(table[p.name + ".n"] == lengths[p.name]) for p in lists):
                self.at += element.count * record.itemsize
                out = {}
                for p in element.properties:
                    if p.count_type:
                        values = table[p.name].reshape(element.count, -1)
                        out[p.name] = (values.reshape(-1),
                                       np.full(element.count, lengths[p.name], np.int64))
                    else:
                        out[p.name] = table[p.name]
                return out
        return self._walk(element)

    def _first_lengths(self, element) -> dict:
        at, lengths = self.at, {}
        for p in element.properties:
            if p.count_type:
                n = self._read(p.count_type, at, element)
                lengths[p.name] = n
                at += _dtype(self.order, p.count_type).itemsize
                at += n * _dtype(self.order, p.type).itemsize
            else:
                at += _dtype(self.order, p.type).itemsize
        return lengths

    def _read(self, ply_type: str, at: int, element) -> int:
        dtype = _dtype(self.order, ply_type)
        if at + dtype.itemsize > len(self.body):
            raise MeshFileError(f"the file ends inside its {element.name} element")
        value = int(np.frombuffer(self.body, dtype, count=1, offset=at)[0])
        if value < 0:
            raise MeshFileError(f"a list of length {value} in the {element.name} element")
        return value

    def _walk(self, element) -> dict:
        """Record by record, where lists differ in length (polygons of several sizes)."""
        starts = {p.name: [] for p in element.properties}
        lengths = {p.name: [] for p in element.properties if p.count_type}
        sizes = [(p, _dtype(self.order, p.count_type).itemsize if p.count_type else 0,
                  _dtype(self.order, p.type).itemsize) for p in element.properties]
        at = self.at
        total = 0
        for _ in range(element.count):
            for p, count_size, size in sizes:
                if p.count_type:
                    n = self._read(p.count_type, at, element)
                    at += count_size
                    starts[p.name].append(at)
                    lengths[p.name].append(n)
                    at += n * size
                    total += max(n - 2, 0)
                else:
                    starts[p.name].append(at)
                    at += size
            if element.name == "face" and total > MAX_MESH_TRIANGLES:
                raise MeshFileError(f"the faces pass {MAX_MESH_TRIANGLES} triangles, the most "
                                    f"a scene's meshes hold")
        if at > len(self.body):
            raise MeshFileError(f"the file ends inside its {element.name} element")
        data = np.frombuffer(self.body, np.uint8)
        out = {}
        for p, _, size in sizes:
            dtype = _dtype(self.order, p.type)
            first = np.array(starts[p.name], dtype=np.int64)
            if p.count_type:
                n = np.array(lengths[p.name], dtype=np.int64)
                item = np.repeat(first, n) + size * (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n))
            else:
                item = first
            raw = data[item[:, None] + np.arange(size)].reshape(-1).tobytes()
            values = np.frombuffer(raw, dtype)
            out[p.name] = (values, n) if p.count_type else values
        self.at = at
        return out

    def size(self) -> int:
        return len(self.body)


#: An ascii body is converted to numbers this many bytes at a time (its words a list of
#: Python bytes objects meanwhile: up to ~40 bytes a word, 20 MB for a chunk of "0 ").
ASCII_CHUNK = 1 << 20


def _most_numbers(header: PlyHeader) -> int | None:
    """The most numbers an ascii body within the limits can hold: every property's value
    or list length, and the F face lists' indices, Σ n = Σ (n − 2) + 2F ≤
    MAX_MESH_TRIANGLES + 2F. None (no bound) where another list's length is free."""
    most = MAX_MESH_TRIANGLES + 2 * header.element("face").count
    for element in header.elements:
        for p in element.properties:
            if p.count_type and not (element.name == "face" and p.name == header.face_list):
                return None
        most += element.count * len(element.properties)
    return most


class _AsciiBody(_Body):
    """An ascii PLY body: its numbers, converted :data:`ASCII_CHUNK` bytes at a time and
    refused once more than a body within the limits holds (a small header over a large
    file allocates no more), then read element by element."""

    unit = "number"

    def __init__(self, body: bytes, most: int | None) -> None:
        chunks, total, at = [], 0, 0
        while at < len(body):
            end = len(body) if len(body) - at <= ASCII_CHUNK else \
                max(body.rfind(c, at, at + ASCII_CHUNK) for c in (b" ", b"\n", b"\t", b"\r")) + 1
            end = end if end > at else at + ASCII_CHUNK          # a word of 1 MiB: cut
            chunk = body[at:end]
            try:
                if b"_" in chunk:                # Python's float takes 1_0, C++'s >> not
                    raise ValueError
                chunks.append(np.array(chunk.split(), dtype=np.float64))
            except ValueError:
                raise MeshFileError("the PLY body holds something that is not a number") \
                    from None
            total += len(chunks[-1])
            if most is not None and total > most:
                raise MeshFileError(f"the file goes on past the elements its header declares "
                                    f"(more numbers than they hold within the limit of "
                                    f"{MAX_MESH_TRIANGLES} triangles)")
            at = end
        self.values = np.concatenate(chunks) if chunks else np.zeros(0)
        self.at = 0

    def element(self, element) -> dict:
        values, count = self.values, element.count
        if count == 0:           # no records (an element of no properties has none: a width of 0)
            return {p.name: (np.zeros(0, np.int64), np.zeros(0, np.int64)) if p.count_type
                    else np.zeros(0) for p in element.properties}
        lists = [p for p in element.properties if p.count_type]
        width = len(element.properties)             # numbers per record, with lists' lengths
        lengths = {}
        at = self.at
        for p in element.properties:                # the first record's list lengths
            if p.count_type:
                n = self._length(at, element) if count else 0
                lengths[p.name] = n
                at += 1 + n
                width += n
            else:
                at += 1
        end = self.at + count * width
        table = values[self.at:end].reshape(-1, width) if end <= len(values) else None
        column, columns = 0, {}
        for p in element.properties:
            columns[p.name] = column
            column += 1 + lengths.get(p.name, 0) if p.count_type else 1
        if table is not None and len(table) == count and all(
                np.all(table[:, columns[p.name]] == lengths[p.name]) for p in lists):
            self.at = end
            out = {}
            for p in element.properties:
                c = columns[p.name]
                if p.count_type:
                    out[p.name] = (table[:, c + 1:c + 1 + lengths[p.name]].reshape(-1),
                                   np.full(count, lengths[p.name], np.int64))
                else:
                    out[p.name] = table[:, c]
            return out
        return self._walk(element)

    def _length(self, at: int, element) -> int:
        if at >= len(self.values):
            raise MeshFileError(f"the file ends inside its {element.name} element")
        n = self.values[at]
        if not (n >= 0 and n == int(n)):
            raise MeshFileError(f"a list of length {n:g} in the {element.name} element")
        return int(n)

    def _walk(self, element) -> dict:
        out = {p.name: [] for p in element.properties}
        lengths = {p.name: [] for p in element.properties if p.count_type}
        at, total = self.at, 0
        for _ in range(element.count):
            for p in element.properties:
                if p.count_type:
                    n = self._length(at, element)
                    out[p.name].append(self.values[at + 1:at + 1 + n])
                    lengths[p.name].append(n)
                    at += 1 + n
                    total += max(n - 2, 0)
                else:
                    out[p.name].append(at)
                    at += 1
            if element.name == "face" and total > MAX_MESH_TRIANGLES:
                raise MeshFileError(f"the faces pass {MAX_MESH_TRIANGLES} triangles, the most "
                                    f"a scene's meshes hold")
        if at > len(self.values):
            raise MeshFileError(f"the file ends inside its {element.name} element")
        self.at = at
        result = {}
        for p in element.properties:
            if p.count_type:
                flat = np.concatenate(out[p.name]) if out[p.name] else np.zeros(0)
                result[p.name] = (flat, np.array(lengths[p.name], np.int64))
            else:
                result[p.name] = self.values[np.array(out[p.name], dtype=np.int64)]
        return result

    def size(self) -> int:
        return len(self.values)
