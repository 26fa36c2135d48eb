"""The studio's frames: a render's pixels as image bytes, with what the page shows beside them.

A :class:`Frame` is what the render thread hands out (mimarble/studio/worker.py): the
image encoded for a browser, its size, the samples so far against the target, and the
histograms of t (mimarble/studio/histogram.py). :func:`encode` makes the bytes: the
8-bit sRGB pixels Mitsuba's conversion makes (``image_output.srgb8``: the curve and its
dither, as ``mimarble render`` writes them), compressed as PNG (zlib level 1, as
``mimarble render``) or JPEG — docs/benchmarks.md, "Studio", has the two measured.
"""

from __future__ import annotations

import dataclasses
import io
import time

import numpy as np

from mimarble.mitsuba.rendering.image_output import PNG_COMPRESSION, srgb8
from mimarble.runtime.image_formats import JPEG_QUALITY

#: How frames are encoded unless told otherwise: ``auto`` — JPEG (quality 95, 4:4:4)
#: while a frame is not final, PNG (exact: the pixels ``mimarble render`` writes) once
#: it is; or ``png``, ``jpeg`` always: JPEG encodes several times faster into a smaller
#: frame (docs/benchmarks.md, "Studio engine", encoding alone).
FRAME_FORMAT = "auto"
MIME = {"png": "image/png", "jpeg": "image/jpeg"}


@dataclasses.dataclass(frozen=True, eq=False)
class Frame:
    """One image the studio shows.

    ========== ==========================================================================
    version    the edit version it shows (``StudioSession.state()["version"]``)
    image      the encoded bytes (``mime``: ``image/png`` or ``image/jpeg``)
    width      pixels across
    height     pixels down
    spp        samples per pixel so far
    target_spp the samples refinement stops at (the scene's ``samples``)
    mode       ``whitted`` or ``path``
    render_ms  the render thread's time for this frame's samples (ms)
    encode_ms  the time spent encoding ``image`` (ms)
    histograms one dict per marble in view (mimarble/studio/histogram.py); None on a
               version's first frame when they were not computed yet (a
               ``histograms`` event follows it)
    pixels     linear float32 (height, width, 3): the image before encoding
    stride     1, or k > 1 for a reduced frame of a drag: the whole image's pixels of
               every k-th row and column (worker.py, "Reduced frames"), never final
    ========== ==========================================================================
    """

    version: int
    image: bytes
    mime: str
    width: int
    height: int
    spp: int
    target_spp: int
    mode: str
    render_ms: float
    encode_ms: float
    histograms: tuple | None = ()
    pixels: np.ndarray | None = dataclasses.field(default=None, repr=False)
    stride: int = 1

    @property
    def final(self) -> bool:
        """Whether refinement has reached the target (a reduced frame never has)."""
        return self.spp >= self.target_spp and self.stride == 1

    def meta(self) -> dict:
        """Everything but the bytes and the pixels, JSON-able."""
        return {"version": self.version, "mime": self.mime, "width": self.width,
                "height": self.height, "spp": self.spp, "target_spp": self.target_spp,
                "final": self.final, "mode": self.mode, "stride": self.stride,
                "render_ms": round(self.render_ms, 3), "encode_ms": round(self.encode_ms, 3),
                "histograms": None if self.histograms is None else list(self.histograms)}


def encode(pixels: np.ndarray, fmt: str = FRAME_FORMAT) -> tuple[bytes, str, float]:
    """(bytes, mime type, milliseconds taken) of linear RGB ``pixels`` (H, W, 3) as an
    8-bit sRGB ``png`` or ``jpeg`` (quality ``JPEG_QUALITY``, 4:4:4, as ``mimarble render``
    writes one)."""
    from PIL import Image
    start = time.perf_counter()
    picture = Image.fromarray(srgb8(pixels))
    buffer = io.BytesIO()
    if fmt == "png":
        picture.save(buffer, "PNG", compress_level=PNG_COMPRESSION)
    elif fmt == "jpeg":
        picture.save(buffer, "JPEG", quality=JPEG_QUALITY, subsampling=0)
    else:
        raise ValueError(f"frame format {fmt!r:.20} is not png or jpeg")
    return buffer.getvalue(), MIME[fmt], (time.perf_counter() - start) * 1e3


def png_of_rgb8(pixels: np.ndarray) -> bytes:
    """PNG bytes of 8-bit RGB ``pixels`` (H, W, 3) as they are (no transfer curve): an
    error map, say."""
    from PIL import Image
    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(pixels, dtype=np.uint8)).save(
        buffer, "PNG", compress_level=PNG_COMPRESSION)
    return buffer.getvalue()
