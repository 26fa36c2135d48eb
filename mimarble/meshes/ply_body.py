"""A PLY file's body walked in pure Python for the facts the parser needs: every face a
triangle of existing vertices, every coordinate finite within float32, the body ending
where its header says; the bounds of the positions and the extent of (u, v) on the way.

A binary body is read in stepped slices (memoryview casts of each column), an ascii one
word by word, each word read as Mitsuba reads it, with ``>>`` of its property's type:
integers written as whole numbers within their type's range, floating-point numbers
finite within their type's (a ``half`` below 65520). Standard library only.
"""

from __future__ import annotations

import itertools
import math
import os
import re
import struct
import sys

from mimarble.contract import FLT_MAX
from mimarble.runtime.reading import shortened
from . import limits
from .limits import MeshFileError, beyond_float32, long_normal, zero_normal
from .ply_header import PLY_NORMAL_NAMES, PLY_TYPES, PlyHeader

__all__ = ["ply_body"]


def ply_body(f, header: PlyHeader, size: int) -> tuple:
    """Walk the PLY body (``f`` just past the header) element by element and return the
    bounds of its vertex positions and the largest |u|, |v| of its texture coordinates
    (None: it has none); MeshFileError on the first thing Mitsuba 3.9.1's
    ``ply`` plugin would not read as the reference tracer does:

    * a face whose list is not 3 indices long (Mitsuba reads triangles only: "incompatible
      contents -- is this a triangle mesh?"; the reference tracer would read a fan);
    * a face index outside 0 … V − 1 (Mitsuba would read past its vertex buffer);
    * a coordinate x, y, z (or the (u, v) or normal nx, ny, nz read) not finite or beyond
      ±FLT_MAX (Mitsuba stores float32, where it would be ±∞, and refuses such a mesh
      with a traceback); a normal shorter than :data:`limits.MIN_NORMAL` in every
      component, or longer than :data:`limits.MAX_NORMAL` in one (Mitsuba normalises it
      in float32: zero becomes NaN, an overflowing one zero);
    * a body that ends inside an element, or goes on past the last one (Mitsuba refuses
      both).

    Binary: fixed-size records are read :data:`limits.READ_CHUNK` bytes at a time and their columns
    taken as stepped slices (a face's list, 3 indices, fixed-size as long as every length
    is 3, which is checked first); records with other lists are walked one by one. Ascii:
    the words are streamed and taken a chunk of records at a time."""
    walk = _AsciiWalk(f) if header.format == "ascii" else \
        _BinaryWalk(f, "little" if header.format == "binary_little_endian" else "big", size)
    vertices = header.element("vertex").count
    normals = PLY_NORMAL_NAMES if header.normals else ()
    names = ("x", "y", "z") + (header.uv or ()) + normals
    lo, hi = [math.inf] * 3, [-math.inf] * 3
    uv_extent = 0.0
    for element in header.elements:
        if element.name == "vertex":
            for columns in walk.scalars(element, names):
                for i, name in enumerate(names):
                    what = "vertex coordinate" if i < 3 else \
                        "vertex normal" if name in normals else "texture coordinate"
                    least, most = _coordinate_range(columns[name], what)
                    if i < 3:
                        lo[i], hi[i] = min(lo[i], least), max(hi[i], most)
                    elif name not in normals:
                        uv_extent = max(uv_extent, -least, most)
                if normals:
                    _normals_have_length(*(columns[name] for name in normals))
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


def _normals_have_length(nx, ny, nz) -> None:
    """Every normal (nx, ny, nz) of a chunk has a component of at least
    :data:`limits.MIN_NORMAL` in magnitude and none past :data:`limits.MAX_NORMAL`
    (Mitsuba normalises it in float32)."""
    least, most = limits.MIN_NORMAL, limits.MAX_NORMAL
    for x, y, z in zip(nx, ny, nz):
        if -least < x < least and -least < y < least and -least < z < least:
            raise MeshFileError(zero_normal((x, y, z)))
        if not (-most <= x <= most and -most <= y <= most and -most <= z <= most):
            raise MeshFileError(long_normal((x, y, z)))


def _coordinate_range(values, what: str) -> tuple[float, float]:
    """(min, max) of a column of coordinates, each finite and within ±FLT_MAX. Their sum
    is finite exactly when none is NaN or ±∞ (or, of finite ones, when none is huge: 3·10⁶
    numbers within ±FLT_MAX sum to at most 10⁴⁵), so one pass decides the common case."""
    if not math.isfinite(sum(values)) and not all(map(math.isfinite, values)):
        raise MeshFileError(f"a {what} is not finite")
    least, most = min(values), max(values)
    if max(-least, most) > FLT_MAX:
        raise MeshFileError(f"a {what} {beyond_float32(most if most > -least else least)}")
    return least, most


def _polygon(n, element) -> MeshFileError:
    return MeshFileError(f"a face of {n} vertices: Mitsuba 3.9's ply plugin reads triangles "
                         f"only (split the {element.name}s into triangles)")


def _ends_inside(element) -> MeshFileError:
    return MeshFileError(f"the file ends inside its {element.name} element")


def _goes_on(more: str) -> MeshFileError:
    return MeshFileError(f"the file goes on past the elements its header declares{more}")

#: struct's (and memoryview.cast's) code of each PLY number (kind, bytes).
_CODES = {("i", 1): "b", ("u", 1): "B", ("i", 2): "h", ("u", 2): "H", ("i", 4): "i",
          ("u", 4): "I", ("i", 8): "q", ("u", 8): "Q", ("f", 2): "e", ("f", 4): "f",
          ("f", 8): "d"}


def _chunks(count: int, width: int):
    """The records in each chunk of ``count`` records of ``width`` bytes or words."""
    step = max(1, limits.READ_CHUNK // max(width, 1))
    for first in range(0, count, step):
        yield min(step, count - first)


class _BinaryWalk:
    """A binary PLY body, element by element (:func:`ply_body`)."""

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
    """An ascii PLY body, element by element (:func:`ply_body`): its words streamed line
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
                    "vertex coordinate" if names.index(p.name) < 3 else \
                    "vertex normal" if p.name in PLY_NORMAL_NAMES else "texture coordinate"
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
                raise MeshFileError(f"a {what} {beyond_float32(big)}")
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
