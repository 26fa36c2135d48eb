"""What a mesh file may hold, each limit stated once; the error of a file that cannot be
used (:class:`MeshFileError`), and a file opened within the size limit (:func:`open_mesh`).

Limits, each checked before anything in proportion to it is read or allocated:

* the file is a regular file (mimarble/runtime/reading.py) of at most
  :data:`MAX_MESH_BYTES`, from its size, before it is read;
* **PLY**: the header ends (``end_header``) within :data:`MAX_PLY_HEADER_BYTES`; its face
  count is at most :data:`MAX_MESH_TRIANGLES`, its vertex count and
  every other element's at most :data:`MAX_MESH_VERTICES`, an element of no properties has
  no records (its records would take no bytes: 10¹⁵ of them fit any file), and the file is
  large enough for what the header declares (the fewest bytes each record can take), so a
  100-byte file claiming 10¹² faces is refused from its header (ply_header.py). Its faces
  are then triangles (ply_body.py), so the face count is the triangle count; the reference
  tracer's reader (arrays.py), which also takes polygons (a fan of n − 2 triangles for n
  corners), counts them and refuses past the limit;
* **OBJ**: the lines are streamed; the triangles (Σ (n − 2) over the faces) are refused the
  line they pass the limit, the ``v``, ``vt`` and ``vn`` lines past :data:`MAX_MESH_VERTICES`
  (obj_lines.py);
* **vertex normals** (PLY ``nx ny nz``, OBJ ``vn``): each finite, within float32, and
  its largest component at least :data:`MIN_NORMAL` and at most :data:`MAX_NORMAL` in
  magnitude (Mitsuba normalises every normal it reads, in float32: a zero one becomes
  NaN, one whose |n|² overflows becomes zero).

The scene language's limits (mimarble/scene/limits.py) take the two that are a scene's
(:data:`MAX_MESH_TRIANGLES`, :data:`MAX_MESH_BYTES`) from here. Standard library only.
"""

from __future__ import annotations

import os

from mimarble.contract import FLT_MAX
from mimarble.runtime.reading import open_failure, open_regular, shortened

__all__ = ["MAX_MESH_TRIANGLES", "MAX_MESH_BYTES", "MAX_MESH_VERTICES", "MAX_PLY_HEADER_BYTES",
           "MAX_OBJ_LINE_BYTES", "MAX_PRECISE_UV", "MIN_NORMAL", "MAX_NORMAL", "READ_CHUNK", "MeshFileError", "open_mesh",
           "beyond_float32", "zero_normal", "long_normal"]

#: Triangles over all the meshes of a scene (2²⁰, about a million): the reference tracer
#: holds them in float64 with a bounding-volume hierarchy (~0.3 GB at the limit), and a
#: mesh file's header is checked against it before anything is read past it.
MAX_MESH_TRIANGLES = 1 << 20

#: A mesh file's size, bytes (256 MiB): a million triangles fit in a tenth of it, in any
#: of the PLY or OBJ encodings read here.
MAX_MESH_BYTES = 1 << 28

#: A PLY header's size, bytes: a header lists a few elements and properties, so 64 KiB is
#: far past any real one, and a file without ``end_header`` is not read on and on.
MAX_PLY_HEADER_BYTES = 1 << 16

#: Vertices of a mesh file (PLY vertex records, OBJ ``v`` and ``vt`` lines): three per
#: triangle of :data:`MAX_MESH_TRIANGLES`, the most a mesh within that
#: limit can use.
MAX_MESH_VERTICES = 3 * MAX_MESH_TRIANGLES

#: An OBJ line's length, bytes, without its newline: Mitsuba's OBJ reader copies each line
#: into a buffer of 1025 bytes and refuses a line of 1024 or more.
MAX_OBJ_LINE_BYTES = 1023

#: The largest |u|, |v| of a mesh's texture coordinates read without a warning: past 2¹⁰,
#: float32's step (Mitsuba's, where it holds and interpolates them) is 2⁻¹³ or more, a
#: texel of an image map 8192 pixels wide, so its image map lookups and the reference's
#: (float64) may differ (docs/rendering-model.md, "A mesh's texture coordinates").
MAX_PRECISE_UV = float(1 << 10)

#: The least largest component |n_k| of a vertex normal in a file (2⁻⁴⁰, about 9·10⁻¹³):
#: Mitsuba 3.9 normalises each normal it reads in float32 (src/shapes/ply.cpp, obj.cpp),
#: n·rsqrt(|n|²), and |n|² must stay a normal float32 number (≥ 2⁻¹²⁶) for that to be a
#: unit vector; a zero normal becomes NaN there. Shorter normals are refused.
MIN_NORMAL = 2.0 ** -40
#: The greatest largest component |n_k| of a vertex normal in a file (2⁶⁰, about 1.2·10¹⁸):
#: past 2⁶⁴ or so |n|² overflows float32 to ∞ in that normalisation, rsqrt(∞) = 0, and
#: Mitsuba's normal becomes (0, 0, 0) (checked with Mitsuba 3.9.1: (10³⁰, 0, 0) loads as
#: zero) while the reference's float64 one is a unit vector. Longer normals are refused.
MAX_NORMAL = 2.0 ** 60

#: A PLY body is taken about this many bytes (binary) or words (ascii) at a time, an OBJ
#: file's lines and a file's digest this many bytes at a time.
READ_CHUNK = 1 << 20


class MeshFileError(ValueError):
    """A mesh file that cannot be used, in one sentence (no file name, no position)."""


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


def zero_normal(normal) -> str:
    """The sentence for a vertex normal too short to have a direction (MIN_NORMAL)."""
    shown = " ".join(f"{c:g}" for c in normal)
    return (f"a vertex normal ({shown}) has no direction: Mitsuba normalises normals in "
            f"float32, so each needs a component of at least {MIN_NORMAL:g} (2^-40) in "
            f"magnitude")


def long_normal(normal) -> str:
    """The sentence for a vertex normal too long to normalise in float32 (MAX_NORMAL)."""
    shown = " ".join(f"{c:g}" for c in normal)
    return (f"a vertex normal ({shown}) is too long: Mitsuba normalises normals in float32, "
            f"where its squared length overflows, so no component may pass {MAX_NORMAL:g} "
            f"(2^60) in magnitude")


def beyond_float32(value: float) -> str:
    """The sentence's end for a coordinate past float32's range."""
    return (f"{value!r} is beyond float32's range (±{FLT_MAX!r}), the numbers Mitsuba "
            f"holds its meshes in")
