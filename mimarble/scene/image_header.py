"""Whether a file can be an image map, read from its header (and its last bytes) alone.

The scene language refuses an image map that is missing or is not an 8-bit PNG or a JPEG
while it parses, at the file's string, so the user hears of it before a render starts;
decoding the pixels comes later (the Mitsuba path, the reference tracer). What the
header says is checked here, the same for both renderers:

* the file is a regular file (a FIFO or a device is refused without being opened for a
  read that could block: runtime/reading.py);
* an 8-bit PNG (its IHDR chunk) or a JPEG (its frame header, SOFn, found by walking the
  markers), not empty, of at most :data:`~mimarble.scene.limits.MAX_IMAGE_MAP_PIXELS`
  pixels — so that a small file that decodes into gigabytes (a "decompression bomb") is
  refused before anything is decoded;
* complete: a PNG ends with its IEND chunk, a JPEG with its EOI marker (FF D9), either
  followed by nothing but zero bytes. A truncated JPEG otherwise decodes in Mitsuba with
  a warning and the rest of the map grey, where Pillow refuses it.

The header is read with the standard library only: the scene package imports no
imaging library.
"""

from __future__ import annotations

import os

from .limits import MAX_IMAGE_MAP_PIXELS
from mimarble.runtime.reading import open_failure, open_regular
from .rules import shortened

__all__ = ["image_file_problem", "image_file_sentence", "check_image_maps", "png_facts",
           "image_size", "MAX_IMAGE_MAP_PIXELS"]

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_END = b"IEND\xaeB`\x82"            # the IEND chunk's type and CRC (its length is 0)
_JPEG_SIGNATURE = b"\xff\xd8\xff"
_JPEG_END = b"\xff\xd9"                 # EOI
#: The start-of-frame markers (SOF0..SOF15 but DHT C4, JPG C8 and DAC CC).
_SOF = frozenset({0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF})
#: Markers without a length: TEM, RST0..7 (SOI and EOI are not met while walking).
_STANDALONE = frozenset({0x01, *range(0xD0, 0xD8)})
#: How much of the file's end is read to find its end marker behind zero padding.
_TAIL = 1 << 16


class _Problem(Exception):
    """Why the file cannot be an image map; ``undecodable``: it is an image, but one
    that cannot be decoded whole (truncated)."""

    def __init__(self, reason: str, undecodable: bool = False) -> None:
        super().__init__(reason)
        self.reason, self.undecodable = reason, undecodable


def image_file_problem(path: str) -> str | None:
    """Why ``path`` cannot be an image map (None: it can): it must exist, be a readable
    regular file, and be a complete 8-bit PNG or JPEG of at most
    :data:`MAX_IMAGE_MAP_PIXELS` pixels (read from its header and its end; decoding
    comes later)."""
    try:
        _check(path)
    except _Problem as p:
        return p.reason
    return None


def image_file_sentence(name: str, path: str) -> str | None:
    """The one sentence that refuses the image map ``name`` (as the scene writes it),
    found at ``path``, or None: ``image file 'NAME': REASON``, and for a file that is
    an image but would not decode whole, ``image file 'NAME' cannot be decoded: REASON``
    (the renderers' sentence for a file that fails to decode). A name of more than 256
    characters is shortened."""
    try:
        _check(path)
    except _Problem as p:
        name = shortened(name, 256)
        return f"image file '{name}'{' cannot be decoded' if p.undecodable else ''}: {p.reason}"
    return None


def image_size(path: str) -> tuple[int, int] | None:
    """(width, height) of the image map in ``path``, from its header, or None where
    :func:`image_file_problem` has a problem with it (an environment's least size is
    checked on it)."""
    try:
        return _check(path)
    except _Problem:
        return None


def check_image_maps(scene) -> None:
    """Every image map of ``scene`` passes the header check, else a SceneError at its
    ``file`` string in the parser's own sentence: for a scene built in Python, which the
    parser never saw, before anything decodes a map (both renderers, every Mitsuba path
    through ``to_mitsuba``)."""
    from .errors import SceneError
    for channel in scene.image_maps():
        sentence = image_file_sentence(channel.file, channel.location)
        if sentence:
            raise SceneError.in_file(scene.source, channel.pos, sentence)


def _check(path: str) -> tuple[int, int]:
    """(width, height) of an image map that passes every check, else a :class:`_Problem`."""
    where = shortened(path, 1024)           # longer is no path the system takes
    try:
        with open_regular(path) as f:
            head = f.read(33)       # the PNG signature and its IHDR chunk
            if head.startswith(_PNG_SIGNATURE):
                return _png(f, head)
            elif head.startswith(_JPEG_SIGNATURE):
                return _jpeg(f)
            else:
                raise _Problem("not a PNG or JPEG file; image maps are 8-bit PNG or JPEG")
    except OSError as e:
        raise _Problem(open_failure(e, where)) from None


def png_facts(f) -> tuple[int, int, bool] | None:
    """(width, height, complete) of the PNG open as ``f`` (binary, seekable; read from its
    header and its end), or None when it is no PNG. ``complete``: it ends with its IEND
    chunk (then zero bytes only)."""
    f.seek(0)
    head = f.read(33)
    if not head.startswith(_PNG_SIGNATURE) or len(head) < 24 or head[12:16] != b"IHDR":
        return None
    width, height = int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    return width, height, _ends(f, _PNG_END)


def _ends(f, end: bytes) -> bool:
    """The file ends with ``end``, then nothing but zero bytes (within its last 64 KiB)."""
    size = os.fstat(f.fileno()).st_size
    f.seek(max(0, size - _TAIL))
    return f.read(_TAIL).rstrip(b"\0").endswith(end)


def _size(kind: str, width: int, height: int) -> None:
    if width == 0 or height == 0:
        raise _Problem(f"an empty {kind} ({width}x{height})")
    if width * height > MAX_IMAGE_MAP_PIXELS:
        raise _Problem(f"a {kind} of {width}x{height} = {width * height} pixels; image maps "
                       f"hold at most {MAX_IMAGE_MAP_PIXELS} (8192x8192) pixels")


def _ends_with(f, end: bytes, kind: str, what: str) -> None:
    """The file ends with ``end``, then nothing but zero bytes (within its last 64 KiB)."""
    if not _ends(f, end):
        raise _Problem(f"a truncated {kind}: it does not end with {what}", undecodable=True)


def _png(f, head: bytes) -> tuple[int, int]:
    if len(head) < 33 or head[12:16] != b"IHDR":
        raise _Problem("a truncated PNG (no IHDR header)")
    width, height = int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    depth = head[24]
    _size("PNG", width, height)
    if depth != 8:
        raise _Problem(f"a {depth}-bit PNG; image maps are 8-bit PNG or JPEG")
    _ends_with(f, _PNG_END, "PNG", "its IEND chunk")
    return width, height


def _jpeg(f) -> tuple[int, int]:
    """Walk the markers from SOI to the frame header (SOFn): its precision and size."""
    f.seek(2)
    skipped = 0
    while True:
        byte = f.read(1)
        if not byte:
            raise _Problem("a truncated JPEG (no frame header, SOF)", undecodable=True)
        if byte != b"\xff":                         # stray bytes between segments, which
            skipped += 1                            # decoders skip (with a warning)
            if skipped > _TAIL:
                raise _Problem("a damaged JPEG: no marker where a frame header (SOF) "
                               "should be")
            continue
        marker = f.read(1)
        while marker == b"\xff":                    # fill bytes before a marker
            marker = f.read(1)
        if not marker:
            raise _Problem("a truncated JPEG (no frame header, SOF)", undecodable=True)
        code = marker[0]
        if code in _STANDALONE:
            continue
        if code in (0xD9, 0xDA):                    # EOI or SOS before any frame header
            raise _Problem("a damaged JPEG: no frame header (SOF) before its image data")
        length_bytes = f.read(2)
        if len(length_bytes) < 2:
            raise _Problem("a truncated JPEG (no frame header, SOF)", undecodable=True)
        length = int.from_bytes(length_bytes, "big")
        if length < 2:
            raise _Problem(f"a damaged JPEG: a marker segment of length {length}")
        if code in _SOF:
            frame = f.read(5)
            if len(frame) < 5:
                raise _Problem("a truncated JPEG (in its frame header, SOF)", undecodable=True)
            precision = frame[0]
            height, width = int.from_bytes(frame[1:3], "big"), int.from_bytes(frame[3:5], "big")
            _size("JPEG", width, height)
            if precision != 8:
                raise _Problem(f"a {precision}-bit JPEG; image maps are 8-bit PNG or JPEG")
            _ends_with(f, _JPEG_END, "JPEG", "its end marker (EOI, FF D9)")
            return width, height
        f.seek(length - 2, os.SEEK_CUR)
