"""The scene's environment for the reference tracer: its own loader and lookup, in float64.

What Mitsuba 3.9's ``envmap`` emitter does (``src/emitters/envmap.cpp``, read at tag
v3.9.1), without Mitsuba:

* **Loading**: OpenEXR scanline files of HALF or FLOAT samples, uncompressed (NONE) or
  ZIP / ZIPS (zlib, after OpenEXR's byte split and delta predictor), R, G and B taken;
  Radiance HDR, flat or run-length encoded, each RGBE pixel m·2^(e−136) (e = 0: black),
  as Mitsuba's ``rgbe_to_float``; 8-bit PNG and JPEG as image maps load them (sRGB
  decoded: image_map.py). The header is checked by the scene language's rule first
  (mimarble/scene/environment_header.py), so the reference refuses what the parser
  refuses, in the same words. Other OpenEXR compressions (PIZ, PXR24, B44, DWA…) are
  Mitsuba's to read: the reference says so in one sentence.
* **Lookup** of a world direction d: the local direction ℓ = R⁻¹·d (R the rotation of
  ``rotate``), ``u = atan2(ℓ_x, −ℓ_z)/2π`` wrapped into [0, 1), ``v = acos(ℓ_y)/π``
  clamped to [0, 1]; for a W×H image, x = u·W − ½ (texel-centred columns, periodic:
  column −1 is column W−1), y = v·(H − 1) (rows at the poles' corners, clamped), then
  bilinear between columns ⌊x⌋, ⌊x⌋+1 (mod W) and rows ⌊y⌋, ⌊y⌋+1 (at most H−1); the
  result times ``intensity``. A ``color`` environment is colour × intensity everywhere.

Imports NumPy, the standard library, zlib and the scene package's header rule.
"""

from __future__ import annotations

import functools
import os
import zlib

import numpy as np

from mimarble.runtime.reading import open_regular, shortened
from mimarble.scene.environment_header import (EXR_COMPRESSIONS, EXR_TYPES, EnvironmentFileProblem,
                                              environment_file_problem, exr_layout, hdr_layout,
                                              walk_hdr)
from mimarble.scene.errors import SceneError
from mimarble.scene.model import Environment

__all__ = ["EnvironmentLookup", "Unreadable", "load_environment", "direction_uv", "lookup"]

#: The OpenEXR compressions the reference decodes.
_DECODED = ("NONE", "ZIPS", "ZIP")


class Unreadable(ValueError):
    """An environment file the reference cannot read; ``reason`` says why (the parser's
    words for a file it refuses)."""

    def __init__(self, where: str, reason: str) -> None:
        super().__init__(f"environment file {where!r}: {reason}")
        self.reason = reason


def load_environment(path) -> np.ndarray:
    """The environment image in ``path`` as linear RGB: a read-only float64 (H, W, 3), row
    0 the top (v = 0, straight up). Cached by (absolute path, modification time, size).
    Raises :class:`Unreadable` (a ValueError naming the file) when it cannot be read."""
    where = os.path.abspath(os.fspath(path))
    try:
        st = os.stat(where)
    except OSError:
        st = None
    return _load(where, None if st is None else (st.st_mtime_ns, st.st_size))


@functools.lru_cache(maxsize=4)
def _load(where: str, stamp) -> np.ndarray:
    problem = environment_file_problem(where)
    if problem:
        raise Unreadable(where, problem)
    try:
        with open_regular(where) as f:
            head = f.read(4)
            if head == b"\x76\x2f\x31\x01":
                image = _exr(f, where)
            elif head.startswith(b"#?"):
                image = _hdr(f)
            else:
                image = None
    except EnvironmentFileProblem as p:
        raise Unreadable(where, str(p)) from None
    if image is None:           # a PNG or JPEG: as an image map
        from .image_map import load_image
        image = np.array(load_image(where))
    image.flags.writeable = False
    return image


def _exr(f, where: str) -> np.ndarray:
    layout = exr_layout(f)
    name = EXR_COMPRESSIONS[layout.compression][0]
    if name not in _DECODED:
        raise Unreadable(where, f"the reference tracer reads OpenEXR files compressed with "
                                f"{', '.join(_DECODED)}, not {name} (path and whitted modes "
                                f"read it; save it with ZIP to compare)")
    width, height, lines = layout.width, layout.height, layout.lines_per_chunk
    sizes = [EXR_TYPES[kind][1] for _, kind in layout.channels]
    line_bytes = width * sum(sizes)
    file_size = os.fstat(f.fileno()).st_size
    f.seek(layout.table)
    offsets = np.frombuffer(f.read(8 * layout.chunks), "<u8")
    image = np.zeros((height, width, 3))
    for chunk, offset in enumerate(offsets.tolist()):
        if offset + 8 > file_size:
            raise Unreadable(where, f"a damaged OpenEXR file (chunk {chunk} lies past its end)")
        f.seek(offset)
        y, length = np.frombuffer(f.read(8), "<i4")
        if length < 0 or offset + 8 + int(length) > file_size:
            raise Unreadable(where, f"a damaged OpenEXR file (chunk {chunk} lies past its end)")
        count = min(lines, layout.y_min + height - int(y))
        first = int(y) - layout.y_min
        if not 0 <= first < height or count <= 0:
            raise Unreadable(where, f"a damaged OpenEXR file (chunk {chunk} is at row "
                                    f"{int(y)})")
        data = f.read(int(length))
        expected = count * line_bytes
        if len(data) != expected:
            data = _unzip(data, expected, where)
        rows = np.frombuffer(data, np.uint8).reshape(count, line_bytes)
        at = 0
        for (channel, kind), size in zip(layout.channels, sizes):
            dtype = {"HALF": "<f2", "FLOAT": "<f4", "UINT": "<u4"}[EXR_TYPES[kind][0]]
            values = rows[:, at:at + width * size].copy().view(dtype).astype(np.float64)
            if channel in ("R", "G", "B"):
                image[first:first + count, :, "RGB".index(channel)] = values
            at += width * size
    return image


def _unzip(data: bytes, expected: int, where: str) -> bytes:
    """OpenEXR's ZIP: zlib, then the delta predictor undone (a running sum, less 128 a
    byte, modulo 256), then the two halves interleaved back (even positions first)."""
    try:            # never more than the chunk's rows hold (a stream could inflate past them)
        raw = zlib.decompressobj().decompress(data, expected + 1)
    except zlib.error as e:
        raise Unreadable(where, f"a damaged OpenEXR file ({e})") from None
    if len(raw) != expected:
        raise Unreadable(where, f"a damaged OpenEXR file (a chunk holds {len(raw)} bytes, "
                                f"not {expected})")
    t = np.frombuffer(raw, np.uint8).astype(np.int64)
    t[1:] -= 128
    t = (np.cumsum(t) % 256).astype(np.uint8)
    out = np.empty_like(t)
    half = (len(t) + 1) // 2
    out[0::2], out[1::2] = t[:half], t[half:]
    return out.tobytes()


def _hdr(f) -> np.ndarray:
    layout = hdr_layout(f)
    width, height = layout.width, layout.height
    pixels = np.zeros((height, width, 4), np.uint8)

    def scanline(y, data):
        if y is None:                                   # flat: every pixel, interleaved
            pixels[...] = np.frombuffer(data, np.uint8).reshape(height, width, 4)
        else:                                           # encoded: four channels in turn
            pixels[y] = np.frombuffer(data, np.uint8).reshape(4, width).T

    walk_hdr(f, layout, scanline)
    e = pixels[..., 3].astype(np.int64)
    scale = np.where(e > 0, np.ldexp(1.0, e - 136), 0.0)
    return pixels[..., :3] * scale[..., None]


def direction_uv(local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) of unit local directions (N, 3): envmap's ``direction_to_uv``, u wrapped
    into [0, 1), v clamped to [0, 1]."""
    u = np.arctan2(local[:, 0], -local[:, 2]) / (2 * np.pi)
    v = np.arccos(np.clip(local[:, 1], -1.0, 1.0)) / np.pi
    return u - np.floor(u), np.clip(v, 0.0, 1.0)


def lookup(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The image at (u, v), bilinear as envmap's texture: texel-centred periodic columns,
    corner-aligned clamped rows."""
    height, width, _ = image.shape
    x, y = u * width - 0.5, v * (height - 1)
    i, j = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = (x - i)[:, None], (y - j)[:, None]
    i0, i1 = i % width, (i + 1) % width
    j0, j1 = np.clip(j, 0, height - 1), np.clip(j + 1, 0, height - 1)
    return ((1 - fy) * ((1 - fx) * image[j0, i0] + fx * image[j0, i1])
            + fy * ((1 - fx) * image[j1, i0] + fx * image[j1, i1]))


class EnvironmentLookup:
    """A scene's :class:`~mimarble.scene.model.Environment`, loaded: :meth:`radiance` of
    world directions. A file it cannot read is a SceneError at the file's string of the
    scene file ``source`` (None: a scene built in Python), in one sentence."""

    def __init__(self, environment: Environment, source: str | None = None) -> None:
        self.environment = environment
        self.image = None
        if environment.file is not None:
            try:
                self.image = load_environment(environment.location)
            except Unreadable as e:
                raise SceneError.in_file(source, environment.pos, f"environment file "
                                         f"'{shortened(environment.file, 256)}': {e.reason}") \
                    from None
        self.from_world = np.array(environment.rotation(), dtype=np.float64).T   # R⁻¹ = Rᵀ

    def radiance(self, d: np.ndarray) -> np.ndarray:
        """The radiance (N, 3) seen along unit world directions ``d`` (N, 3)."""
        env = self.environment
        if self.image is None:
            return np.broadcast_to(np.array(env.color) * env.intensity, (len(d), 3)).copy()
        local = d @ self.from_world.T
        local /= np.linalg.norm(local, axis=1, keepdims=True)
        return lookup(self.image, *direction_uv(local)) * env.intensity
