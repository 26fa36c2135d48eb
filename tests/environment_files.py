"""Small environment images written for the tests, from the formats' specifications (not
through mimarble's readers): OpenEXR scanline files (NONE or ZIP compression, HALF or
FLOAT samples) and Radiance HDR files (flat or run-length encoded).

OpenEXR: "The OpenEXR File Layout" (openexr.com): magic 76 2f 31 01, version 2, the
header's attributes (name, type, size, value) ending with a zero byte, the table of
chunk offsets (uint64), then chunks (int32 y, int32 size, data); a scanline's data is
each channel's samples in turn (channels sorted by name); ZIP: 16 scanlines a chunk,
the bytes split even/odd positions into two halves, then deltas (+128) byte to byte,
then zlib. Radiance: the header, a blank line, ``-Y H +X W``, RGBE pixels with
value = m·2^(e−136).
"""

from __future__ import annotations

import struct
import zlib

import numpy as np


def _attribute(name: str, kind: str, value: bytes) -> bytes:
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def write_exr(path, rgb: np.ndarray, half: bool = False, zip_compression: bool = False,
              extra_channels: tuple = ()) -> None:
    """``rgb`` (H, W, 3) written as an OpenEXR file of channels B, G, R (sorted), HALF or
    FLOAT, uncompressed or ZIP; ``extra_channels``: names of more channels (zeros)."""
    rgb = np.asarray(rgb)
    height, width, _ = rgb.shape
    kind, dtype = (1, "<f2") if half else (2, "<f4")
    names = sorted(("R", "G", "B") + tuple(extra_channels))
    planes = {"R": rgb[..., 0], "G": rgb[..., 1], "B": rgb[..., 2]}
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<iBBBBii", kind, 0, 0, 0, 0, 1, 1)
                      for n in names) + b"\0"
    window = struct.pack("<iiii", 0, 0, width - 1, height - 1)
    header = (b"\x76\x2f\x31\x01" + struct.pack("<I", 2)
              + _attribute("channels", "chlist", chlist)
              + _attribute("compression", "compression", bytes([3 if zip_compression else 0]))
              + _attribute("dataWindow", "box2i", window)
              + _attribute("displayWindow", "box2i", window)
              + _attribute("lineOrder", "lineOrder", b"\0")
              + _attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + _attribute("screenWindowCenter", "v2f", struct.pack("<ff", 0, 0))
              + _attribute("screenWindowWidth", "float", struct.pack("<f", 1.0))
              + b"\0")
    lines = 16 if zip_compression else 1
    chunks = []
    for y0 in range(0, height, lines):
        raw = b"".join(np.ascontiguousarray(planes.get(n, np.zeros((height, width)))[y]
                                            .astype(dtype)).tobytes()
                       for y in range(y0, min(y0 + lines, height)) for n in names)
        data = raw
        if zip_compression:
            b = np.frombuffer(raw, np.uint8)
            split = np.concatenate([b[0::2], b[1::2]])
            delta = split.astype(np.int16)
            delta[1:] = (split[1:].astype(np.int16) - split[:-1].astype(np.int16) + 128) % 256
            packed = zlib.compress(delta.astype(np.uint8).tobytes())
            data = packed if len(packed) < len(raw) else raw
        chunks.append(struct.pack("<ii", y0, len(data)) + data)
    offset = len(header) + 8 * len(chunks)
    table = b""
    for chunk in chunks:
        table += struct.pack("<Q", offset)
        offset += len(chunk)
    with open(path, "wb") as f:
        f.write(header + table + b"".join(chunks))


def rgbe(rgb: np.ndarray) -> np.ndarray:
    """(…, 3) floats → (…, 4) RGBE bytes (Ward's rule: m = ⌊c·2⁸/2^e⌋ for the largest
    component's exponent e, so that it is < 256)."""
    rgb = np.asarray(rgb, dtype=np.float64)
    top = rgb.max(axis=-1)
    mantissa, exponent = np.frexp(top)             # top = mantissa·2^exponent, mantissa ∈ [½, 1)
    scale = np.where(top > 1e-32, 256.0 / np.ldexp(1.0, exponent), 0.0)
    out = np.zeros(rgb.shape[:-1] + (4,), np.uint8)
    out[..., :3] = np.floor(rgb * scale[..., None]).astype(np.uint8)
    out[..., 3] = np.where(top > 1e-32, exponent + 128, 0)
    return out


def write_hdr(path, rgb: np.ndarray, encoded: bool = True) -> np.ndarray:
    """``rgb`` (H, W, 3) as a Radiance HDR file; returns the floats it holds exactly."""
    height, width, _ = np.shape(rgb)
    pixels = rgbe(rgb)
    body = bytearray()
    for y in range(height):
        if not encoded:
            body += pixels[y].tobytes()
            continue
        body += bytes([2, 2, width >> 8, width & 255])
        for c in range(4):
            channel = pixels[y, :, c].tobytes()
            x = 0
            while x < width:                        # a run where 3+ equal, else literals
                run = 1
                while x + run < width and run < 127 and channel[x + run] == channel[x]:
                    run += 1
                if run >= 3:
                    body += bytes([128 + run, channel[x]])
                    x += run
                else:
                    n = min(128, width - x)
                    body += bytes([n]) + channel[x:x + n]
                    x += n
    with open(path, "wb") as f:
        f.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (height, width))
        f.write(bytes(body))
    e = pixels[..., 3].astype(np.int64)
    return np.where(e[..., None] > 0,
                    pixels[..., :3] * np.ldexp(1.0, e - 136)[..., None], 0.0)
