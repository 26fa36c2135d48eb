"""Image maps for the reference tracer: 8-bit PNG / JPEG, sRGB-decoded, bilinear, repeating.

What Mitsuba's ``bitmap`` texture does by default (``filter_type="bilinear"``,
``wrap_mode="repeat"``, ``raw=false``), in float64 and without Mitsuba:

* **Loading** (Pillow): the file is converted to RGB: grayscale v → (v, v, v), a
  palette → its RGB entries, alpha dropped (colours not premultiplied). Each byte
  b is decoded from sRGB with the exact IEC 61966-2-1 curve, c = b/255::

      c ≤ 0.04045:  c / 12.92          else:  ((c + 0.055) / 1.055) ** 2.4

  Loaded images are cached by (absolute path, mtime, size): a render reads each
  file once, and a file rewritten in place is read again.
* **Lookup** at (u, v) for a W×H image (Dr.Jit's ``Texture2f``, linear filter)::

      x = u·W − ½,  y = v·H − ½,  i = ⌊x⌋,  j = ⌊y⌋,  fx = x − i,  fy = y − j
      (1−fx)(1−fy)·t[j, i] + fx(1−fy)·t[j, i+1] + (1−fx)fy·t[j+1, i] + fx·fy·t[j+1, i+1]

  with column indices taken modulo W and row indices modulo H (repeat, for any
  u, v, negative ones included). Row 0 is the file's first (top) row, so v = 0
  is the top of the image.

Errors: a file that is missing, unreadable, not a regular file, or not a complete,
decodable 8-bit PNG or JPEG of at most ``mimarble.scene.LIMITS["max_image_map_pixels"]``
pixels raises :class:`ValueError` naming the file. The header is checked by the scene
language's rule before Pillow reads a pixel, so the reference refuses what the parser
and the Mitsuba path refuse, in the same words; the size is checked again on what
Pillow read from the file it opened.

Imports NumPy, Pillow, the standard library and the scene language's rule for an image
map's file (``mimarble.scene.image_header``: a regular file, a complete 8-bit PNG or JPEG
within the pixel limit; ``mimarble.runtime.reading.open_regular``).
"""

from __future__ import annotations

import functools
import os

import numpy as np
from PIL import Image

from mimarble.scene.image_header import MAX_IMAGE_MAP_PIXELS, image_file_problem
from mimarble.runtime.reading import open_regular

__all__ = [
    "SRGB8_TO_LINEAR",
    "srgb_to_linear",
    "load_image",
    "clear_cache",
    "bilinear",
]


def srgb_to_linear(c):
    """The exact IEC 61966-2-1 decoding curve on sRGB values c in [0, 1] -> float64 linear."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((np.maximum(c, 0.04045) + 0.055) / 1.055) ** 2.4)


#: The linear value of each 8-bit sRGB code 0…255 (float64, read-only).
SRGB8_TO_LINEAR = srgb_to_linear(np.arange(256, dtype=np.float64) / 255.0)
SRGB8_TO_LINEAR.flags.writeable = False

# Pillow modes of 8-bit files that convert to RGB without loss of meaning.
_MODES = frozenset({"L", "LA", "La", "P", "PA", "RGB", "RGBA", "RGBa", "RGBX", "YCbCr"})
_FORMATS = frozenset({"PNG", "JPEG", "MPO"})   # MPO: a JPEG with extra pictures (first one used)


def load_image(path) -> np.ndarray:
    """The image in ``path`` as linear RGB: a read-only float64 (H, W, 3), row 0 the top row.

    Cached by (absolute path, modification time, size). Raises ValueError naming
    the file when it is missing, unreadable or not a decodable 8-bit PNG or JPEG.
    """
    where = os.path.abspath(os.fspath(path))
    try:
        st = os.stat(where)
    except FileNotFoundError:
        raise ValueError(f"image file {where!r}: no such file") from None
    except OSError as e:
        raise ValueError(f"image file {where!r}: cannot read it: {e.strerror or e}") from None
    return _load(where, st.st_mtime_ns, st.st_size)


def clear_cache() -> None:
    """Forget every loaded image."""
    _load.cache_clear()


@functools.lru_cache(maxsize=64)
def _load(where: str, mtime_ns: int, size: int) -> np.ndarray:
    del mtime_ns, size                          # part of the cache key only
    try:
        problem = image_file_problem(where)     # the scene language's rule for the file
        if problem:
            raise ValueError(problem)
        with open_regular(where) as f:          # a FIFO swapped in is not waited on
            with Image.open(f) as im:
                width, height = im.size
                if width * height > MAX_IMAGE_MAP_PIXELS:   # the file changed since its check
                    raise ValueError(f"a {im.format} of {width}x{height} = {width * height} "
                                     f"pixels; image maps hold at most {MAX_IMAGE_MAP_PIXELS} "
                                     f"(8192x8192) pixels")
                if im.format not in _FORMATS:
                    raise ValueError(f"a {im.format or 'unknown'} image; "
                                     f"image maps are 8-bit PNG or JPEG")
                if im.mode not in _MODES:
                    raise ValueError(f"unsupported pixel mode {im.mode!r}; "
                                     f"image maps are 8-bit grey, palette or RGB(A)")
                im.load()
                rgb = np.asarray(im.convert("RGB"), dtype=np.uint8)
    except ValueError as e:
        raise ValueError(f"image file {where!r}: {e}") from None
    except Exception as e:                      # OSError, UnidentifiedImageError, zlib.error, …
        raise ValueError(f"image file {where!r}: cannot decode it as a PNG or JPEG "
                         f"({type(e).__name__}: {e})") from None
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.shape[0] == 0 or rgb.shape[1] == 0:
        raise ValueError(f"image file {where!r}: an empty image ({rgb.shape})")
    out = SRGB8_TO_LINEAR[rgb]                  # (H, W, 3) float64
    out.flags.writeable = False
    return out


def bilinear(texels, uv) -> np.ndarray:
    """Bilinear, repeating lookup of an (H, W, C) image at (k, 2) texture coordinates -> (k, C).

    x = u·W − ½, y = v·H − ½; the four texels around (x, y), indices modulo W and H,
    weighted by the fractional parts (see the module docstring). Row 0 is v's top.
    """
    t = np.asarray(texels, dtype=np.float64)
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    H, W = t.shape[0], t.shape[1]
    x = uv[:, 0] * W - 0.5
    y = uv[:, 1] * H - 0.5
    fi = np.floor(x)
    fj = np.floor(y)
    fx = (x - fi)[:, None]
    fy = (y - fj)[:, None]
    # Non-finite coordinates give NaN colours rather than an index error.
    bad = ~(np.isfinite(fi) & np.isfinite(fj))
    i0 = np.mod(np.where(bad, 0.0, fi), W).astype(np.int64)
    j0 = np.mod(np.where(bad, 0.0, fj), H).astype(np.int64)
    i1 = (i0 + 1) % W
    j1 = (j0 + 1) % H
    out = ((1.0 - fx) * (1.0 - fy) * t[j0, i0] + fx * (1.0 - fy) * t[j0, i1]
           + (1.0 - fx) * fy * t[j1, i0] + fx * fy * t[j1, i1])
    if bad.any():
        out[bad] = np.nan
    return out
