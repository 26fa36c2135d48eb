"""Writing rendered images: linear RGB to 8-bit sRGB PNG or JPEG, or float OpenEXR, whole
or not at all.

The PNG's 8-bit values are exactly what Mitsuba's own conversion makes of the
whole image (its sRGB curve and blue-noise dither), computed a band of rows at
a time so that converting never needs a second full-size float image; a JPEG
compresses those same 8-bit values (Pillow, full-resolution colour). Every file
is written under a temporary name beside its destination and renamed into place
(mimarble/runtime/files.py), so an interruption never leaves half an image.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mimarble.runtime import environment, files
from mimarble.runtime.image_formats import (IMAGE_FORMATS, JPEG_FORMATS, JPEG_QUALITY,
    formats_sentence, quality_problem)

_, mi = environment.import_drjit_and_mitsuba()


def write_image(path, image: np.ndarray, quality: int | None = None,
                origin: tuple[int, int] = (0, 0)) -> None:
    """Write linear RGB ``image`` to ``path`` (.exr: float; .png, .jpg, .jpeg: 8-bit sRGB).

    PNG: what Mitsuba's ``Bitmap.convert(..., UInt8, srgb_gamma=True)`` makes of
    the image after NaN → 0 and clamping to [0, 1] (:func:`srgb8`), converted a
    band of rows at a time straight into the bitmap that is written, so the
    only full-size arrays are ``image`` and the 8-bit result. JPEG: the same
    8-bit pixels, compressed by Pillow at ``quality`` (1..100, default
    :data:`~mimarble.runtime.image_formats.JPEG_QUALITY`) without chroma subsampling
    (4:4:4: halving the colour resolution put red veins on grey up to 89 code
    values off at any quality, measured); ``quality`` is refused for the other formats.
    ``origin``: where ``image``'s top-left pixel lies in a larger image (a crop's ``x0, y0``):
    the 8-bit pixels are dithered as that image's are there, so a crop's PNG is the full
    PNG's window, code value for code value. The file is written under a temporary name
    in the same folder and renamed into place, so a failure never leaves half a file.
    A name no writer takes (``files.output_name_problem``: empty, NUL, not UTF-8) is a
    ValueError before anything is converted.
    """
    problem = files.output_name_problem(path)
    if problem:
        raise ValueError(f"{str(path)!r}: {problem}")
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in IMAGE_FORMATS:
        raise ValueError(f"{path}: unsupported image format {suffix or '(none)'!r}; "
                         f"use {formats_sentence(IMAGE_FORMATS)}")
    if suffix in JPEG_FORMATS:
        quality = JPEG_QUALITY if quality is None else quality
        problem = quality_problem(quality)
        if problem:
            raise ValueError(f"{path}: {problem}")
        write_jpeg(path, srgb8(image, origin=origin), quality)
        return
    if quality is not None:
        raise ValueError(f"{path}: quality applies to {formats_sentence(JPEG_FORMATS)} "
                         f"images, not {suffix}")
    if suffix == ".png":
        height, width = image.shape[:2]
        bitmap = mi.Bitmap(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, [width, height])
        srgb8(image, out=np.asarray(bitmap), origin=origin)   # into the bitmap's own pixels
    else:
        bitmap = mi.Bitmap(np.ascontiguousarray(image, dtype=np.float32))
    write_atomically(path, bitmap)


#: Mitsuba's 8-bit conversion dithers with a 256×256 threshold matrix indexed by the
#: pixel's position in the converted block: bands of a multiple of 256 rows line up with it.
DITHER_PERIOD = 256


def srgb8(image: np.ndarray, out: np.ndarray | None = None,
          rows_per_band: int = DITHER_PERIOD, origin: tuple[int, int] = (0, 0)) -> np.ndarray:
    """Linear RGB → 8-bit sRGB, exactly as Mitsuba converts the whole image.

    NaN becomes 0 and values are clamped to [0, 1] (as ``write_image`` always
    did), then Mitsuba's ``Bitmap.convert(RGB, UInt8, srgb_gamma=True)`` applies
    the sRGB curve (IEC 61966-2-1) with its blue-noise dither (offsets in
    [−½, ½) of a code value, a 256×256 pattern), a band of ``rows_per_band``
    rows (a multiple of :data:`DITHER_PERIOD`) at a time: the result equals
    converting the whole image at once (tests/test_tiled_render.py), with only
    band-sized temporaries. ``out``: a uint8 (H, W, 3) array to fill.

    ``origin`` ``(x, y)``: the image is a window of a larger one whose top-left pixel
    is at (x, y) there (a crop): each band is converted with ``x mod 256`` columns and,
    the first, ``y mod 256`` rows of padding before it, so that the dither pattern falls
    on every pixel as in the larger image's conversion (the pattern repeats every 256
    pixels in x and in y; tests/test_crop.py).
    """
    if rows_per_band % DITHER_PERIOD:
        raise ValueError(f"rows_per_band={rows_per_band} must be a multiple of {DITHER_PERIOD}")
    height, width = image.shape[:2]
    ox, oy = (int(v) % DITHER_PERIOD for v in origin)
    if out is None:
        out = np.empty(image.shape[:2] + (3,), dtype=np.uint8)
    for start in range(-oy, height, rows_per_band):     # bands on the larger image's grid
        y0, y1 = max(start, 0), min(start + rows_per_band, height)
        top = y0 - start                                # rows of padding: oy, then 0
        # fmax/fmin: NaN → 0, and a clamp to [0, 1] (±inf → 1, 0), in two passes over the band.
        if top or ox:
            band = np.zeros((top + y1 - y0, ox + width, 3), dtype=np.float32)
            np.fmax(image[y0:y1, :, :3], 0.0, out=band[top:, ox:], dtype=np.float32)
            np.fmin(band, 1.0, out=band)
        else:
            band = np.fmax(image[y0:y1, :, :3], 0.0, dtype=np.float32)
            np.fmin(band, 1.0, out=band)
        converted = mi.Bitmap(band).convert(
            mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True)
        out[y0:y1] = np.asarray(converted)[top:, ox:]
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


def write_jpeg(path, pixels: np.ndarray, quality: int = JPEG_QUALITY) -> None:
    """Write 8-bit sRGB ``pixels`` (H, W, 3) to a .jpg or .jpeg at ``quality`` (1..100),
    with full-resolution colour (4:4:4), whole or not at all."""
    from PIL import Image
    picture = Image.fromarray(np.ascontiguousarray(pixels, dtype=np.uint8))   # (H, W, 3): RGB
    files.write_atomically(Path(path), lambda tmp: picture.save(
        tmp, "JPEG", quality=int(quality), subsampling=0))


#: zlib level of the PNGs written: 1, the fastest (OpenCV's default too). Mitsuba's
#: default 5 took more than twice as long for a file only a little smaller (the dither
#: leaves little to compress; docs/benchmarks.md, "Figures moved out of the code").
PNG_COMPRESSION = 1


def write_atomically(path: Path, bitmap) -> None:
    """Write ``bitmap`` whole or not at all (:func:`mimarble.runtime.files.write_atomically`)."""
    if path.suffix.lower() == ".png":
        files.write_atomically(path, lambda tmp: bitmap.write(tmp, mi.Bitmap.FileFormat.PNG,
                                                              PNG_COMPRESSION))
    else:
        files.write_atomically(path, bitmap.write)
