"""A PLY file's header: its grammar (``ply``, ``format``, ``comment``, ``element``,
``property``, ``end_header``), its elements' layout (:class:`PlyHeader`), checked within
the limits and against the file's size before anything past it is read.

The header's lines are split into words where C++'s ``>>`` splits them; the property types
are those Mitsuba 3.9's ``ply`` plugin knows (:data:`PLY_TYPES`); ``obj_info`` is refused,
as Mitsuba refuses it. The vertex's (u, v) are ``u v``, else ``texture_u texture_v``, else
``s t`` (Mitsuba's order of preference; a lone ``u`` or ``v`` beside another pair is
refused: Mitsuba renames the pair onto it); its normals are ``nx ny nz`` (all three, as
Mitsuba reads them; float or double); the face's list is ``vertex_index`` or
``vertex_indices``, the file's only list (Mitsuba reads every list as a length and 3
values). Read by the facts (facts.py, ply_body.py) and the arrays (arrays.py) alike.
Standard library only.
"""

from __future__ import annotations

from dataclasses import dataclass

from mimarble.runtime.reading import shortened
from .limits import MAX_MESH_TRIANGLES, MAX_MESH_VERTICES, MAX_PLY_HEADER_BYTES, MeshFileError

__all__ = ["PLY_TYPES", "PLY_NORMAL_NAMES", "PlyProperty", "PlyElement", "PlyHeader", "ply_header"]

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
#: A vertex's normal: Mitsuba 3.9's ply plugin reads it when all three are there.
PLY_NORMAL_NAMES = ("nx", "ny", "nz")
#: The face's list of vertex indices, in Mitsuba's order of preference.
_PLY_FACE_LISTS = ("vertex_index", "vertex_indices")


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
    face's list of vertex indices; ``normals``: the vertex has ``nx ny nz`` (vertex
    normals, :data:`PLY_NORMAL_NAMES`)."""

    format: str
    elements: tuple[PlyElement, ...]
    size: int
    uv: tuple[str, str] | None
    face_list: str
    normals: bool = False

    def element(self, name: str) -> PlyElement:
        return next(e for e in self.elements if e.name == name)


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
    normals = all(vertex.property(name) for name in PLY_NORMAL_NAMES)
    for name in ("x", "y", "z") + (uv or ()) + (PLY_NORMAL_NAMES if normals else ()):
        prop = vertex.property(name)
        if prop is None:
            raise MeshFileError("the PLY vertex element has no x, y and z properties")
        if prop.count_type is not None or PLY_TYPES[prop.type][0] != "f":
            kind = "a list" if prop.count_type else prop.type
            what = "normals" if name in PLY_NORMAL_NAMES else "coordinates"
            raise MeshFileError(f"the PLY vertex property {name} is {kind}; {what} are "
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
    return PlyHeader(fmt, elements, end, uv, face_list, normals)


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
