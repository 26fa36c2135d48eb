"""Writing rendered images: linear RGB to 8-bit sRGB PNG or float OpenEXR, whole or not at all.

The PNG's 8-bit values are exactly what Mitsuba's own conversion makes of the
whole image (its sRGB curve and blue-noise dither), computed a band of rows at
a time so that converting never needs a second full-size float image. Every file
is written under a temporary name beside its destination and renamed into place
(mimarble/files.py), so an interruption never leaves half an image.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import environment, files
from ..image_formats import IMAGE_FORMATS

_, mi = environment.import_drjit_and_mitsuba()


def write_image(path, image: np.ndarray) -> None:
    """Write linear RGB ``image`` to ``path`` (.exr: float; .png: 8-bit sRGB).

    PNG: what Mitsuba's ``Bitmap.convert(..., UInt8, srgb_gamma=True)`` makes of
    the image after NaN → 0 and clamping to [0, 1] (:func:`srgb8`), converted a
    band of rows at a time straight into the bitmap that is written, so the
    only full-size arrays are ``image`` and the 8-bit result. The file is
    written under a temporary name in the same folder and renamed into place,
    so a failure never leaves half a file.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in IMAGE_FORMATS:
        raise ValueError(f"{path}: unsupported image format {suffix or '(none)'!r}; "
                         f"use {' or '.join(IMAGE_FORMATS)}")
    if suffix == ".png":
        height, width = image.shape[:2]
        bitmap = mi.Bitmap(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, [width, height])
        srgb8(image, out=np.asarray(bitmap))     # a view of the bitmap's own pixels
    else:
        bitmap = mi.Bitmap(np.ascontiguousarray(image, dtype=np.float32))
    write_atomically(path, bitmap)


#: Mitsuba's 8-bit conversion dithers with a 256×256 threshold matrix indexed by the
#: pixel's position in the converted block: bands of a multiple of 256 rows line up with it.
DITHER_PERIOD = 256


def srgb8(image: np.ndarray, out: np.ndarray | None = None,
          rows_per_band: int = DITHER_PERIOD) -> np.ndarray:
    """Linear RGB → 8-bit sRGB, exactly as Mitsuba converts the whole image.

    NaN becomes 0 and values are clamped to [0, 1] (as ``write_image`` always
    did), then Mitsuba's ``Bitmap.convert(RGB, UInt8, srgb_gamma=True)`` applies
    the sRGB curve (IEC 61966-2-1) with its blue-noise dither (offsets in
    [−½, ½) of a code value, a 256×256 pattern), a band of ``rows_per_band``
    rows (a multiple of :data:`DITHER_PERIOD`) at a time: the result equals
    converting the whole image at once (tests/test_tiled_render.py), with only
    band-sized temporaries. ``out``: a uint8 (H, W, 3) array to fill.
    """
    if rows_per_band % DITHER_PERIOD:
        raise ValueError(f"rows_per_band={rows_per_band} must be a multiple of {DITHER_PERIOD}")
    height = image.shape[0]
    if out is None:
        out = np.empty(image.shape[:2] + (3,), dtype=np.uint8)
    for y0 in range(0, height, rows_per_band):
        # fmax/fmin: NaN → 0, and a clamp to [0, 1] (±inf → 1, 0), in two passes over the band.
        band = np.fmax(image[y0:y0 + rows_per_band, :, :3], 0.0, dtype=np.float32)
        np.fmin(band, 1.0, out=band)
        out[y0:y0 + rows_per_band] = mi.Bitmap(band).convert(
            mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True)
    return out


def write_rgb8(path, pixels: np.ndarray) -> None:
    """Write 8-bit RGB ``pixels`` (H, W, 3) to a .png as they are (no transfer curve)."""
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"{path}: 8-bit images are written as .png")
    height, width = pixels.shape[:2]
    bitmap = mi.Bitmap(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, [width, height])
    np.asarray(bitmap)[...] = pixels                   # into the bitmap's pixels: no copy
    write_atomically(path, bitmap)


#: zlib level of the PNGs written: 1, the fastest (OpenCV's default too). Mitsuba's
#: default 5 made writing fig11a's 500² PNG 48 ms against 19 ms for a file 17 % larger
#: (193 → 226 kB; the dither leaves little to compress), on the AMD EPYC.
PNG_COMPRESSION = 1


def write_atomically(path: Path, bitmap) -> None:
    """Write ``bitmap`` whole or not at all (:func:`mimarble.files.write_atomically`)."""
    if path.suffix.lower() == ".png":
        files.write_atomically(path, lambda tmp: bitmap.write(tmp, mi.Bitmap.FileFormat.PNG,
                                                              PNG_COMPRESSION))
    else:
        files.write_atomically(path, bitmap.write)
