"""``mimarble bake``: one shape's channel, evaluated by the float64 reference, into an image
through the shape's (u, v), or (``--volume``) into a grid over its bounding box.

**Image** (N × N texels, linear RGB, written 8-bit sRGB PNG or float EXR by
:func:`mimarble.mitsuba.rendering.image_output.write_image`). Texel (i, j) — column i, row j, row 0
the top — holds the channel at the surface point whose (u, v) is its centre,
((i + ½)/N, (j + ½)/N): where Mitsuba's ``bitmap`` texture (Dr.Jit's ``Texture2f``: x =
u·N − ½) reads that texel alone, so a bilinear lookup of the image reproduces the channel
up to interpolation between texel centres. v = 0 is the top row, as in the ``bitmap``.

* **Sphere** of centre c and radius r: Mitsuba's ``sphere`` (u, v) inverted
  (mimarble/reference/channels.py, ``sphere_uv``): φ = 2πu, θ = πv,
  p = c + r·(sin θ cos φ, sin θ sin φ, cos θ). Every texel is on the sphere. Use the image
  with ``wrap_mode`` ``clamp`` where you can: ``repeat`` (the scene language's image maps)
  wraps v too, so the half texel nearest each pole blends in the other pole's row.
* **Mesh** with texture coordinates (the file's, as Mitsuba reads them:
  mimarble/meshes/arrays.py): each texel centre is looked up in the triangles'
  (u, v), and the triangle containing it gives the point by its barycentric coordinates
  (b₀, b₁, b₂): p = b₀·p₀ + b₁·p₁ + b₂·p₂ of its world vertices (the object-space point
  likewise, of the file's vertices). (u, v) outside [0, 1] wrap as ``repeat`` does
  (texel i mod N; up to ±:data:`MAX_UV`, past which a mesh is refused); a triangle whose
  (u, v) span more than one repeat of the image (a tiled floor) is refused: no image
  holds it once. Where triangles overlap in (u, v)
  (mirrored halves sharing a chart), one of them gives the texel. Texels no triangle
  covers are filled from their covered neighbours, :data:`DILATION` texels deep (the
  mean of the covered ones of the eight around, wrapping as ``repeat`` does, repeatedly),
  so that a bilinear lookup at a seam never blends in an uncovered texel; beyond that
  they are black.
* **Planes and boxes** have no (u, v) here, and are refused; a box can be baked with
  ``--volume``.

**Volume** (N × N × N voxels): Mitsuba's volume grid file, read by ``gridvolume``
(src/render/volumegrid.cpp): ``VOL``, version 3, encoding 1 (float32), the x, y, z
resolutions, 3 channels, the bounding box as 6 float32 (x, y, z min, then max), then the
voxels, little-endian, ``data[((z·N + y)·N + x)·3 + channel]``. With ``use_grid_bbox``
``gridvolume`` maps a world point to (p − min)/(max − min) and reads it as ``Texture3f``
does, voxel centres at (i + ½)/N: so voxel (x, y, z) holds the channel at
min + ((x, y, z) + ½)·(max − min)/N, of the bounding box as written (float32, rounded
outwards). The box is the shape's in world space: a sphere's c ± r, a box's corners', a
mesh's vertices'; one flat along an axis (a planar mesh) is given a thickness of
:data:`FLAT_FRACTION` of its largest extent there. A plane is unbounded (refused), and a
channel with an image map has no value off the surface (refused).

The channel is the material's ``--channel``, by default its diffuse, else the first it
has (ambient, diffuse, specular); evaluated with ``object_points`` (the object-space
points, for ``space object`` marbles) when it has such a marble. Sizes are checked before
anything is allocated (:data:`MAX_IMAGE_SIZE`, :data:`MAX_VOLUME_SIZE`); the work is done
:data:`CHUNK` points at a time, and a volume is written a slice at a time, so memory stays
at the image (12 bytes a texel, twice that while an EXR is written) or at one slice of
the volume.

Standard library at import (the command line checks its arguments with the constants
here before NumPy loads); NumPy and the reference inside the functions.
"""

from __future__ import annotations

import math
import struct
from pathlib import Path

#: The most texels along a side of a baked image: 8192² texels are 0.8 GB of float32
#: colour, and about 7 minutes of fig11a's 12-octave marble in float64 on two cores
#: (1024² took 6.9 s, measured); image maps are limited to 8192² pixels too.
MAX_IMAGE_SIZE = 8192
#: ``--size`` of an image when none is given.
DEFAULT_IMAGE_SIZE = 1024
#: The most voxels along a side of a baked volume: 512³ voxels are 1.6 GB of file, and
#: about 10 minutes of fig11a's marble on two cores (128³ took 9.6 s, measured).
MAX_VOLUME_SIZE = 512
#: ``--size`` of a volume when none is given.
DEFAULT_VOLUME_SIZE = 64

#: What ``-o`` may end in.
IMAGE_SUFFIXES = (".png", ".exr")
VOLUME_SUFFIXES = (".vol",)

#: A material's channels, in the order a default is looked for after ``diffuse``.
CHANNELS = ("ambient", "diffuse", "specular", "albedo", "reflectance", "density")

#: How many texels deep the covered texels of a mesh's image are extended (bilinear
#: lookup reads the texel beside the nearest: one is enough, two leave a margin).
DILATION = 2

#: The thickness given to a bounding box that is flat along an axis, as a fraction of
#: its largest extent (1 where it is a single point).
FLAT_FRACTION = 1e-3

#: Points evaluated at once: the float64 marble holds a few dozen arrays of this many.
CHUNK = 1 << 16

#: The largest |u| or |v| a mesh's image is baked through: there float64's step is 2⁻²⁰,
#: 128 times finer than a texel of MAX_IMAGE_SIZE, so each triangle's (u, v) shifted by
#: whole repeats keeps its place in the image; past it, refused (and texel numbers stay
#: far inside int64).
MAX_UV = 2.0 ** 32


class BakeError(ValueError):
    """What cannot be baked, in one sentence (the command line exits with status 2)."""


# ---------------------------------------------------------------------------
# What is baked: checked before anything is allocated

def size_problem(size: int, volume: bool = False) -> str | None:
    """What is wrong with ``--size`` (texels or voxels along a side), or None."""
    most = MAX_VOLUME_SIZE if volume else MAX_IMAGE_SIZE
    if isinstance(size, bool) or not isinstance(size, int) or not 1 <= size <= most:
        return f"--size {size}: must be in 1..{most} for {'a volume' if volume else 'an image'}"
    return None


def chosen(scene, shape_id: str, channel: str | None = None, volume: bool = False):
    """(shape, channel name, channel) to bake, or BakeError saying why not."""
    from mimarble.scene.model import ImageChannel, walk
    try:
        shape = scene.shape(shape_id)
    except KeyError as e:
        raise BakeError(e.args[0]) from None
    from mimarble.scene.shapes import kind_of
    kind = kind_of(shape)
    if not kind.bounded:
        raise BakeError(f"{shape_id} is a {kind.keyword}: it has no (u, v) to bake an image "
                        f"through and no bounds to bake a volume in")
    if kind.keyword not in _TEXELS and not volume:
        raise BakeError(f"{shape_id} is a {kind.keyword}: it has no (u, v) to bake an image "
                        f"through; bake a volume with --volume")
    material = scene.material_of(shape)
    present = dict(material.channels())
    inside = material.subsurface.channels() if material.subsurface is not None else {}
    if volume:                                            # a volume's own: albedo, density
        present.update(inside)
    elif channel in inside:
        raise BakeError(f"{channel} is {shape_id}'s subsurface's, a volume's: bake it with "
                        f"--volume")
    if not present:
        raise BakeError(f'{shape_id}\'s material "{material.name}" has no channels to bake')
    if channel is None:
        channel = "diffuse" if "diffuse" in present else next(iter(present))
    elif channel not in present:
        raise BakeError(f'{shape_id}\'s material "{material.name}" has no {channel} channel '
                        f"(it has {', '.join(present)})")
    value = present[channel]
    if volume and any(isinstance(c, ImageChannel) for c in walk(value)):
        raise BakeError(f"{shape_id}'s {channel} channel holds an image map, which has no "
                        f"value off the surface: a volume cannot hold it")
    return shape, channel, value


def _needs_object_points(channel) -> bool:
    """Whether the channel holds a ``space object`` marble (``model.in_object_space``)."""
    from mimarble.scene.model import in_object_space
    return in_object_space(channel)


def _evaluate(channel, points, uv=None, object_points=None):
    """The channel at (k, 3) world points (their (u, v), their object-space points: needed
    for ``space object`` marbles only) by the float64 reference."""
    from mimarble.reference.channels import channel_color
    return channel_color(channel, points, uv, object_points=object_points)


# ---------------------------------------------------------------------------
# Images

def _texel_centres(indices, size):
    return (indices + 0.5) / size


def _sphere_texels(shape, size, channel, out, progress):
    """Every texel of a sphere: (u, v) → φ = 2πu, θ = πv → the point (module docstring)."""
    import numpy as np
    object_space = _needs_object_points(channel)
    centre, radius = np.asarray(shape.center, dtype=np.float64), float(shape.radius)
    rows = max(1, CHUNK // size)
    u = _texel_centres(np.arange(size, dtype=np.float64), size)
    phi = 2.0 * math.pi * u
    for j0 in range(0, size, rows):
        j1 = min(size, j0 + rows)
        v = _texel_centres(np.arange(j0, j1, dtype=np.float64), size)
        theta = math.pi * v
        sin_t, cos_t = np.sin(theta)[:, None], np.cos(theta)[:, None]
        local = np.stack(np.broadcast_arrays(sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t),
                         axis=-1).reshape(-1, 3)
        uv = np.stack(np.broadcast_arrays(u[None, :], v[:, None]), axis=-1).reshape(-1, 2)
        colour = _evaluate(channel, centre + radius * local, uv,
                           local if object_space else None)
        out[j0:j1] = colour.reshape(j1 - j0, size, 3)
        progress(j1 * size, size * size)


def _mesh_data(shape):
    """The mesh's file read (mimarble/meshes/arrays.py), its world vertices."""
    import numpy as np

    from mimarble.meshes.arrays import MeshFileError, read_mesh
    from mimarble.scene.geometry import object_to_world
    try:
        data = read_mesh(shape.location)
    except MeshFileError as e:              # changed since the scene was read
        raise BakeError(f"{shape.location}: {e}") from None
    m = np.array(object_to_world(shape), dtype=np.float64)
    positions = np.asarray(data.positions, dtype=np.float64)
    return data, positions @ m[:3, :3].T + m[:3, 3]


def _mesh_texels(shape_id, shape, size, channel, out, progress):
    """Every texel a triangle's (u, v) covers (module docstring), then the dilation."""
    import numpy as np
    data, world = _mesh_data(shape)
    if data.uv is None:
        raise BakeError(f"{shape_id} ({shape.file}) has no texture coordinates to bake an "
                        f"image through; bake a volume with --volume")
    triangles = np.asarray(data.triangles, dtype=np.int64)
    uv = np.asarray(data.uv, dtype=np.float64)[triangles]                 # (T, 3, 2)
    big = np.nonzero((np.abs(uv) > MAX_UV).any(axis=(1, 2)))[0]
    if big.size:
        t = int(big[0])
        raise BakeError(f"{shape_id} ({shape.file}): triangle {t}'s texture coordinates reach "
                        f"{np.abs(uv[t]).max():g}, past the ±{MAX_UV:g} through which an image "
                        f"is baked")
    lo, hi = uv.min(axis=1), uv.max(axis=1)
    # Whole repeats of the image are one texel apart modulo N: each triangle is shifted by
    # the floor of its least (u, v), to [0, 1) there, so that its texel numbers stay small.
    shift = np.floor(lo)
    uv, lo, hi = uv - shift[:, None, :], lo - shift, hi - shift
    # Texel centres (i + ½)/N inside [lo, hi]: i from ⌈lo·N − ½⌉ to ⌊hi·N − ½⌋.
    first = np.ceil(lo * size - 0.5).astype(np.int64)
    last = np.floor(hi * size - 0.5).astype(np.int64)
    wide = np.nonzero((last - first + 1 > size).any(axis=1))[0]
    if wide.size:
        t = int(wide[0])
        u0, v0 = lo[t] + shift[t]
        u1, v1 = hi[t] + shift[t]
        raise BakeError(f"{shape_id} ({shape.file}): triangle {t}'s texture coordinates span "
                        f"more than one repeat of the image (u {u0:g}..{u1:g}, "
                        f"v {v0:g}..{v1:g}): no baked image holds it once")
    owner, first, last = _pieces(first, last)
    counts = (last - first + 1).prod(axis=1)
    object_space = _needs_object_points(channel)
    positions = np.asarray(data.positions, dtype=np.float64)
    covered = np.zeros((size, size), dtype=bool)
    done, total = 0, int(counts.sum())
    for batch in _batches(counts):
        p, i, j = _candidates(batch, first, last, counts)
        t = owner[p]
        weights = _barycentric(uv[t], _texel_centres(np.stack([i, j], axis=-1), size))
        inside = (weights >= -1e-9).all(axis=1)
        t, i, j, weights = t[inside], i[inside] % size, j[inside] % size, weights[inside]
        corners = triangles[t]
        points = np.einsum("kc,kcd->kd", weights, world[corners])
        texel_uv = _texel_centres(np.stack([i, j], axis=-1), size)
        object_points = np.einsum("kc,kcd->kd", weights, positions[corners]) \
            if object_space else None
        colour = _evaluate(channel, points, texel_uv, object_points)
        out[j, i] = colour                        # overlapping triangles: one of them
        covered[j, i] = True
        done += int(counts[batch].sum())
        progress(done, total)
    _dilate(out, covered, DILATION)


def _pieces(first, last):
    """Each triangle's box of texels ``first``..``last`` (inclusive (i, j), (T, 2) each) cut
    into bands of rows of at most CHUNK texels (a triangle over the whole image is many
    bands): (triangle of each piece, its first, its last); empty boxes dropped."""
    import numpy as np
    width, height = (np.clip(last - first + 1, 0, None)[:, k] for k in (0, 1))
    band = np.maximum(1, CHUNK // np.maximum(width, 1))           # rows a piece
    pieces = np.where((width > 0) & (height > 0), -(-height // band), 0)
    owner = np.repeat(np.arange(len(first)), pieces)
    k = np.arange(int(pieces.sum())) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    j0 = first[owner, 1] + k * band[owner]
    j1 = np.minimum(j0 + band[owner] - 1, last[owner, 1])
    return (owner, np.stack([first[owner, 0], j0], axis=-1),
            np.stack([last[owner, 0], j1], axis=-1))


def _batches(counts):
    """Consecutive runs of pieces whose texels number at most CHUNK (one piece at least)."""
    import numpy as np
    ends = np.cumsum(counts)
    start = 0
    while start < len(counts):
        base = ends[start - 1] if start else 0
        stop = int(np.searchsorted(ends, base + CHUNK, side="right"))
        stop = max(stop, start + 1)
        yield np.arange(start, stop)
        start = stop


def _candidates(batch, first, last, counts):
    """(piece, i, j) of every texel in the boxes of the pieces ``batch``."""
    import numpy as np
    n = counts[batch]
    width = last[batch, 0] - first[batch, 0] + 1
    p = np.repeat(batch, n)
    offset = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    w = np.repeat(width, n)
    i = np.repeat(first[batch, 0], n) + offset % w
    j = np.repeat(first[batch, 1], n) + offset // w
    return p, i, j


def _barycentric(corners, q):
    """(b₀, b₁, b₂) of points q (k, 2) in triangles ``corners`` (k, 3, 2); a triangle of
    no area in (u, v) gives −1 (outside)."""
    import numpy as np
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    e1, e2, d = b - a, c - a, q - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    flat = det == 0
    det = np.where(flat, 1.0, det)
    s = (d[:, 0] * e2[:, 1] - d[:, 1] * e2[:, 0]) / det
    t = (e1[:, 0] * d[:, 1] - e1[:, 1] * d[:, 0]) / det
    weights = np.stack([1.0 - s - t, s, t], axis=-1)
    weights[flat] = -1.0
    return weights


def _dilate(image, covered, depth: int) -> None:
    """Give each uncovered texel with covered ones among its eight neighbours (wrapping,
    as ``repeat`` does) their mean; ``depth`` times. The rest stays black. Only the
    texels filled are gathered: memory in proportion to the seams, not to the image."""
    import numpy as np
    image[~covered] = 0.0
    rows, columns = covered.shape
    around = [(dj, di) for dj in (-1, 0, 1) for di in (-1, 0, 1) if dj or di]
    for _ in range(depth):
        near = np.zeros_like(covered)
        for dj, di in around:                   # rolled[j, i] = covered[j − dj, i − di]
            near |= np.roll(covered, (dj, di), axis=(0, 1))
        j, i = np.nonzero(near & ~covered)
        if j.size == 0:
            return
        total = np.zeros((j.size, 3), dtype=np.float64)
        count = np.zeros(j.size, dtype=np.int64)
        for dj, di in around:
            jj, ii = (j - dj) % rows, (i - di) % columns
            c = covered[jj, ii]
            total += image[jj, ii] * c[:, None]
            count += c
        image[j, i] = total / count[:, None]
        covered[j, i] = True


def bake_image(scene, shape_id: str, size: int = DEFAULT_IMAGE_SIZE, channel: str | None = None,
               progress=None):
    """The (size, size, 3) float32 linear image of ``shape_id``'s channel (module
    docstring); BakeError for what cannot be baked."""
    problem = size_problem(size)
    if problem:
        raise BakeError(problem)
    shape, _, value = chosen(scene, shape_id, channel)
    import numpy as np

    from mimarble.runtime.progress import report
    update = report(progress, f"bake {shape_id}", unit="texel")
    out = np.zeros((size, size, 3), dtype=np.float32)
    from mimarble.scene.shapes import kind_of
    _TEXELS[kind_of(shape).keyword](shape_id, shape, size, value, out, update)
    update(size * size, size * size)
    return out


#: The kinds an image is baked through, by keyword: each shape's texels (module docstring).
_TEXELS = {"sphere": lambda shape_id, shape, *rest: _sphere_texels(shape, *rest),
           "mesh": _mesh_texels}


# ---------------------------------------------------------------------------
# Volumes

def world_bounds(shape):
    """(min, max) of the shape's world bounding box, each three floats: a sphere's exactly,
    a mesh's around its world vertices, any other kind's around its world corners."""
    import numpy as np

    from mimarble.scene.model import Mesh, Sphere
    if isinstance(shape, Sphere):
        return (tuple(c - shape.radius for c in shape.center),
                tuple(c + shape.radius for c in shape.center))
    corners = np.asarray(_mesh_data(shape)[1] if isinstance(shape, Mesh) else shape.corners())
    return tuple(map(float, corners.min(axis=0))), tuple(map(float, corners.max(axis=0)))


def grid_bounds(shape):
    """The bounding box as the volume file holds it: float32, rounded outwards, a flat
    axis thickened (module docstring); two float64 arrays."""
    import numpy as np
    lo, hi = (np.array(b, dtype=np.float64) for b in world_bounds(shape))
    extent = hi - lo
    pad = FLAT_FRACTION * extent.max() if extent.max() > 0 else 1.0
    flat = extent <= 0
    lo[flat] -= pad / 2
    hi[flat] += pad / 2
    lo32, hi32 = lo.astype(np.float32), hi.astype(np.float32)
    lo32 = np.where(lo32 > lo, np.nextafter(lo32, np.float32(-np.inf)), lo32)
    hi32 = np.where(hi32 < hi, np.nextafter(hi32, np.float32(np.inf)), hi32)
    return lo32.astype(np.float64), hi32.astype(np.float64)


def voxel_centres(lo, hi, size: int, z: int):
    """The (size·size, 3) world points of slice z, x fastest (the file's order)."""
    import numpy as np
    cells = _texel_centres(np.arange(size, dtype=np.float64), size)
    step = (hi - lo)
    x = lo[0] + cells * step[0]
    y = lo[1] + cells * step[1]
    zz = lo[2] + cells[z] * step[2]
    xs, ys = np.meshgrid(x, y)                    # (y, x): x fastest when flattened
    return np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, zz)], axis=-1)


def _to_object(shape, points):
    """object_to_world(shape)⁻¹ · points (a sphere's exactly: (p − c)/r)."""
    import numpy as np

    from mimarble.scene.geometry import object_to_world
    from mimarble.scene.model import Sphere
    if isinstance(shape, Sphere):
        return (points - np.asarray(shape.center)) / shape.radius
    m = np.array(object_to_world(shape), dtype=np.float64)
    return np.linalg.solve(m[:3, :3], (points - m[:3, 3]).T).T


#: The volume file's header: 'VOL', version 3, encoding 1 (float32), x, y, z resolution,
#: channels, then the bounding box (src/render/volumegrid.cpp, ``VolumeGrid::read``).
VOLUME_HEADER = struct.Struct("<3sBiiiii6f")


def bake_volume(scene, shape_id: str, path, size: int = DEFAULT_VOLUME_SIZE,
                channel: str | None = None, progress=None):
    """Write ``shape_id``'s channel on a size³ grid (module docstring) to ``path``, whole
    or not at all; returns the bounding box written ((min, max), float64 arrays)."""
    problem = size_problem(size, volume=True)
    if problem:
        raise BakeError(problem)
    shape, _, value = chosen(scene, shape_id, channel, volume=True)
    import numpy as np

    from mimarble.runtime.files import write_atomically
    from mimarble.runtime.progress import report
    lo, hi = grid_bounds(shape)
    object_space = _needs_object_points(value)
    update = report(progress, f"bake {shape_id}", unit="voxel")

    def write(tmp):
        with open(tmp, "wb") as f:
            f.write(VOLUME_HEADER.pack(b"VOL", 3, 1, size, size, size, 3, *lo, *hi))
            for z in range(size):
                points = voxel_centres(lo, hi, size, z)
                colour = np.empty((len(points), 3), dtype="<f4")
                for k in range(0, len(points), CHUNK):
                    p = points[k:k + CHUNK]
                    colour[k:k + CHUNK] = _evaluate(value, p, None,
                                                    _to_object(shape, p) if object_space else None)
                f.write(colour.tobytes())
                update((z + 1) * size * size, size ** 3)
    write_atomically(Path(path), write)
    return lo, hi


def gridvolume_dict(path) -> dict:
    """The Mitsuba ``volume`` texture that reads a baked volume on a surface: a
    ``gridvolume`` placed by the file's bounding box (docs/mitsuba-scene.md)."""
    return {"type": "volume", "volume": {"type": "gridvolume", "filename": str(path),
                                         "use_grid_bbox": True, "raw": True,
                                         "filter_type": "trilinear", "wrap_mode": "clamp"}}
