"""The image files mimarble writes.

Its own module, importing nothing: the command line checks an output name
before Dr.Jit and Mitsuba load (mimarble/__init__.py).
"""

from __future__ import annotations

#: 8-bit sRGB PNG, linear float OpenEXR, or 8-bit sRGB JPEG (the PNG's pixels, compressed).
IMAGE_FORMATS = (".png", ".exr", ".jpg", ".jpeg")

#: The suffixes written as JPEG, and their quality (Pillow's and libjpeg's 1..100) unless
#: told otherwise: at 95, with full-resolution colour (4:4:4), fig01d, fig10d, fig11a and
#: fig11b at 500² decode within 26 code values of the PNG's pixels, 2.1 RMS (measured;
#: docs/design-decisions.md, "Images").
JPEG_FORMATS = (".jpg", ".jpeg")
JPEG_QUALITY = 95
JPEG_QUALITIES = (1, 100)


def formats_sentence(suffixes) -> str:
    """``.png, .exr, .jpg or .jpeg``: the suffixes, for an error message."""
    suffixes = list(suffixes)
    return suffixes[0] if len(suffixes) == 1 else f"{', '.join(suffixes[:-1])} or {suffixes[-1]}"


def quality_problem(quality) -> str | None:
    """What is wrong with a JPEG ``quality`` (an integer in 1..100), or None."""
    lo, hi = JPEG_QUALITIES
    if isinstance(quality, bool) or not isinstance(quality, int):
        return f"quality must be an integer in {lo}..{hi}, found {quality!r:.40}"
    if not lo <= quality <= hi:
        return f"quality must be in {lo}..{hi}, found {quality}"
    return None
