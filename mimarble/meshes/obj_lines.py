"""An OBJ file's lines, statement by statement, checked as Mitsuba 3.9's ``obj`` plugin
reads them: ``v``, ``vt``, ``vn`` and ``f`` (fans from the first corner), indices from 1,
the triangles and vertices within the limits the line they pass them.

``v x y z`` (further numbers ignored), ``vt u v`` (each finite, within ±FLT_MAX), ``vn x y
z`` (finite, within ±FLT_MAX, its largest component between MIN_NORMAL and MAX_NORMAL in
magnitude: Mitsuba normalises it in float32), ``f`` with 3 or more corners ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn``, each referring
to an element defined before the face. Negative (relative) indices, which the OBJ format
allows, are refused for the facts (Mitsuba 3.9.1 reads indices with ``strtoul``: −1
becomes 2³² − 1, "an invalid vertex") and read for the arrays (``relative``). Everything
after ``#`` is a comment; other statements (``o``, ``g``, ``s``, ``usemtl``, ``mtllib``,
``l``, …) are ignored. A line is at most :data:`~mimarble.meshes.limits.MAX_OBJ_LINE_BYTES`
bytes (Mitsuba's OBJ reader refuses longer ones). Mitsuba separates a statement's words by
spaces and tabs only and ends a face's corner at a space, tab or carriage return, so a
statement line holding a form feed, a vertical tab or a carriage return before its end, a
face's last corner followed at once by ``#``, and a UTF-8 byte order mark before the first
line's ``v``, ``vt``, ``vn`` or ``f`` (Mitsuba would drop that line) are refused.
Standard library only.
"""

from __future__ import annotations

import itertools
import math

from mimarble.contract import FLT_MAX
from mimarble.runtime.reading import shortened
from . import limits
from .limits import (MAX_MESH_TRIANGLES, MAX_MESH_VERTICES, MAX_NORMAL, MAX_OBJ_LINE_BYTES,
                     MIN_NORMAL, MeshFileError, beyond_float32, long_normal, zero_normal)

__all__ = ["obj_statements"]


def obj_statements(f, relative: bool = False, notes: dict | None = None):
    """The OBJ file open as ``f`` (binary), statement by statement, checked (module
    docstring): yields ``("v", (x, y, z))``, ``("vt", (u, v))``, ``("vn", (x, y, z))`` as
    written, and ``("f", ((v, t, n), …))`` with 0-based indices resolved, t (n) = −1
    where a corner names no ``vt`` (``vn``). ``notes``, a dict when given, gets
    ``"face_without_normal"``: the line of the first face one of whose corners names no
    ``vn`` (facts.py: where such a file's normals would be incomplete).
    Negative (relative) indices are resolved against the elements defined so far when
    ``relative``, else refused (Mitsuba 3.9's OBJ reader takes none: ``strtoul`` makes −1
    an index past every vertex).
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
                if len(numbers) < 3:
                    raise MeshFileError(f"line {number}: a normal (vn) needs three numbers")
                largest = max(map(abs, numbers[:3]))
                if largest < MIN_NORMAL:
                    raise MeshFileError(f"line {number}: {zero_normal(numbers[:3])}")
                if largest > MAX_NORMAL:
                    raise MeshFileError(f"line {number}: {long_normal(numbers[:3])}")
            need = 2 if keyword == b"vt" else 3
            if len(numbers) < need:
                what = "a vertex (v)" if keyword == b"v" else "a texture coordinate (vt)"
                raise MeshFileError(f"line {number}: {what} needs {need} numbers")
            big = max(numbers[:need], key=abs)
            if abs(big) > FLT_MAX:
                raise MeshFileError(f"line {number}: the number {beyond_float32(big)}")
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
            if notes is not None and "face_without_normal" not in notes \
                    and any(n < 0 for _, _, n in corners):
                notes["face_without_normal"] = number
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
    for block in iter(lambda: f.read(limits.READ_CHUNK), b""):
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
    """The corners (v, t, n) of ``f`` line ``number`` (``words`` with the keyword), 0-based.
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
                    out.append((v - 1, t - 1, n - 1))
                    continue
            except ValueError:
                pass
        out.append(_obj_corner(word, number, counts, relative))
    return tuple(out)


def _obj_corner(word: bytes, number: int, counts, relative: bool) -> tuple[int, int, int]:
    """(v, t, n) of one face corner ``v``, ``v/t``, ``v//n`` or ``v/t/n``, 0-based (t, n =
    −1: none)."""
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
    return out[0], (out[1] if len(out) > 1 else -1), (out[2] if len(out) > 2 else -1)
