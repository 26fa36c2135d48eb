"""Whether a file can be an environment image, read from its header (and what says it is
whole) alone: OpenEXR and Radiance HDR here, 8-bit PNG and JPEG by the image maps' rule.

An ``environment { file "sky.exr" }`` is a latitude-longitude image that Mitsuba's
``envmap`` loads and the reference tracer decodes on its own. The parser refuses, at the
file's string, before any pixel is decoded:

* anything that is not a regular file (runtime/reading.py), or not one of the formats;
* an image of more than :data:`~mimarble.scene.limits.MAX_IMAGE_MAP_PIXELS` pixels (the
  image maps' limit: a small file that decodes into gigabytes is refused from its
  header), or narrower than 2 or shorter than 3 pixels, in every format (Mitsuba pads
  such a map, which the reference does not: a 4×2 PNG's backgrounds differed by 0.34;
  say ``color`` for a uniform sky);
* **OpenEXR**: a single-part scanline image (not tiled, deep or multi-part) whose header
  ends within :data:`EXR_HEADER_MOST` bytes, with channels R, G and B of HALF or FLOAT
  samples (other channels, such as A, are ignored), and complete: its table of chunk
  offsets and its last chunk lie within the file (a writer that stopped leaves a
  table of zeros, or a short file);
* **Radiance HDR** (RGBE): the ``#?`` signature, ``FORMAT=32-bit_rle_rgbe``, the
  resolution ``-Y H +X W``, and every scanline present: flat pixels (4 bytes each) or
  Mitsuba's run-length encoding, walked run by run (:func:`walk_hdr`), which the
  reference tracer's decoder uses too;
* PNG and JPEG: :func:`mimarble.scene.image_header.image_file_problem`'s rule.

Standard library only: the scene package imports no imaging library.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass

from mimarble.runtime.reading import open_failure, open_regular, shortened

from .image_header import image_file_problem, image_size
from .limits import MAX_IMAGE_MAP_PIXELS

__all__ = ["ENVIRONMENT_FORMATS", "EXR_HEADER_MOST", "EXR_COMPRESSIONS", "ExrLayout",
           "HdrLayout", "EnvironmentFileProblem", "environment_file_problem",
           "environment_file_sentence", "check_environment", "exr_layout", "hdr_layout",
           "walk_hdr"]

#: What an environment file may be, in words.
ENVIRONMENT_FORMATS = "OpenEXR, Radiance HDR, 8-bit PNG or JPEG"

_EXR_MAGIC = b"\x76\x2f\x31\x01"
#: An OpenEXR header longer than this is refused (real ones are a few hundred bytes).
EXR_HEADER_MOST = 1 << 20
#: OpenEXR's compressions by their code: (name, scanlines per chunk).
EXR_COMPRESSIONS = {0: ("NONE", 1), 1: ("RLE", 1), 2: ("ZIPS", 1), 3: ("ZIP", 16),
                    4: ("PIZ", 32), 5: ("PXR24", 16), 6: ("B44", 32), 7: ("B44A", 32),
                    8: ("DWAA", 32), 9: ("DWAB", 256)}
#: OpenEXR's sample types by their code: (name, bytes).
EXR_TYPES = {0: ("UINT", 4), 1: ("HALF", 2), 2: ("FLOAT", 4)}
_HDR_HEADER_MOST = 1 << 16
#: The smallest environment Mitsuba's envmap takes unpadded (``pad_to(2, 3)``).
_SMALLEST = (2, 3)


class EnvironmentFileProblem(Exception):
    """Why a file cannot be an environment image; ``str()`` is the reason."""


@dataclass(frozen=True)
class ExrLayout:
    """An OpenEXR file's layout as its header says: size, its data window's origin,
    compression code, channels ``(name, type code)`` in the file's (sorted) order, where
    the chunk-offset table starts and how many chunks it lists."""

    width: int
    height: int
    x_min: int
    y_min: int
    compression: int
    channels: tuple
    table: int
    chunks: int

    @property
    def lines_per_chunk(self) -> int:
        return EXR_COMPRESSIONS[self.compression][1]


@dataclass(frozen=True)
class HdrLayout:
    """A Radiance HDR file's layout: size and where its pixels start."""

    width: int
    height: int
    data: int

    @property
    def encoded(self) -> bool:
        """Whether scanlines may be run-length encoded (Mitsuba's rule: 8 ≤ W ≤ 32767)."""
        return 8 <= self.width <= 0x7FFF


def environment_file_problem(path: str) -> str | None:
    """Why ``path`` cannot be an environment image (None: it can). The answer is kept
    per version of the file (its size, modification and change times, inode, device):
    ``to_mitsuba`` checks the file again for every scene it translates — each sweep frame,
    each edit in the studio — and a Radiance HDR's check walks every scanline (docs/
    benchmarks.md, "Environment files": a large sky's walk against the check kept), which
    an unchanged file need not repeat."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):   # not there, or no path: the check says why, uncached
        return _environment_file_problem(path)
    return _kept_problem(os.fspath(path), (st.st_size, st.st_mtime_ns, st.st_ctime_ns,
                                           st.st_ino, st.st_dev))


@functools.lru_cache(maxsize=16)
def _kept_problem(path: str, version: tuple) -> str | None:
    """:func:`_environment_file_problem` of one version of the file at ``path``."""
    return _environment_file_problem(path)


def _environment_file_problem(path: str) -> str | None:
    """Why ``path`` cannot be an environment image (None: it can), read now."""
    where = shortened(path, 1024)
    try:
        with open_regular(path) as f:
            head = f.read(10)
            if head.startswith(_EXR_MAGIC):
                exr_layout(f)
                return None
            if head.startswith(b"#?"):
                walk_hdr(f, hdr_layout(f))
                return None
    except EnvironmentFileProblem as p:
        return str(p)
    except OSError as e:
        return open_failure(e, where)
    size = image_size(path)         # 8 bits: held to the least size as the others are
    if size is not None:
        try:
            _size("image", *size)
        except EnvironmentFileProblem as p:
            return str(p)
        return None
    problem = image_file_problem(path)
    if problem is None:             # changed between the two reads: read it again later
        return "the file changed while it was read"
    if problem.startswith("not a PNG or JPEG"):
        return f"not an environment image; environments are {ENVIRONMENT_FORMATS} files"
    return problem


def environment_file_sentence(name: str, path: str) -> str | None:
    """The one sentence that refuses the environment file ``name`` (as the scene writes
    it), found at ``path``, or None: ``environment file 'NAME': REASON``."""
    problem = environment_file_problem(path)
    if problem is None:
        return None
    return f"environment file '{shortened(name, 256)}': {problem}"


def check_environment(scene) -> None:
    """The scene's environment file passes the header check, else a SceneError at its
    ``file`` string in the parser's own sentence: for a scene built in Python, which the
    parser never saw, before Mitsuba or the reference decodes it."""
    environment = scene.environment
    if environment is None or environment.file is None:
        return
    from .errors import SceneError
    sentence = environment_file_sentence(environment.file, environment.location)
    if sentence:
        raise SceneError.in_file(scene.source, environment.pos, sentence)


def _size(kind: str, width: int, height: int) -> None:
    if width * height > MAX_IMAGE_MAP_PIXELS:
        raise EnvironmentFileProblem(
            f"an {kind} of {width}x{height} = {width * height} pixels; environments hold at "
            f"most {MAX_IMAGE_MAP_PIXELS} (8192x8192) pixels")
    if width < _SMALLEST[0] or height < _SMALLEST[1]:
        raise EnvironmentFileProblem(
            f"an {kind} of {width}x{height} pixels; an environment image is at least "
            f"{_SMALLEST[0]}x{_SMALLEST[1]} (write color < r g b > for a uniform sky)")


# -- OpenEXR ------------------------------------------------------------------------
def _cstring(head: bytes, at: int, most: int) -> tuple[str, int]:
    end = head.find(b"\0", at, at + most + 1)
    if end < 0 and at + most + 1 > len(head):
        raise EnvironmentFileProblem("a truncated OpenEXR file (in its header)")
    if end < 0:
        raise EnvironmentFileProblem("a damaged OpenEXR file: a header name is not "
                                     "terminated")
    return head[at:end].decode("latin-1"), end + 1


def _int(data: bytes, at: int, size: int = 4, signed: bool = True) -> int:
    return int.from_bytes(data[at:at + size], "little", signed=signed)


def exr_layout(f) -> ExrLayout:
    """The layout of the OpenEXR file open as ``f`` (binary, seekable), checked: a
    single-part scanline image with R, G and B channels of HALF or FLOAT samples within
    the size limits, complete. Raises :class:`EnvironmentFileProblem`."""
    size = os.fstat(f.fileno()).st_size
    f.seek(0)
    head = f.read(min(size, EXR_HEADER_MOST + 8))
    flags = _int(head, 4, 4, False)
    if flags & 0xFF != 2:
        raise EnvironmentFileProblem(f"an OpenEXR file of version {flags & 0xFF}; "
                                     f"version 2 is read")
    for bit, what in ((0x200, "tiled"), (0x800, "deep"), (0x1000, "multi-part")):
        if flags & bit:
            raise EnvironmentFileProblem(f"a {what} OpenEXR file; environments are "
                                         f"single-part scanline images")
    most = 255 if flags & 0x400 else 31
    at, attributes = 8, {}
    while True:
        if at >= len(head):
            raise EnvironmentFileProblem(
                "a truncated OpenEXR file (its header does not end)" if len(head) == size else
                f"a damaged OpenEXR file: its header does not end within "
                f"{EXR_HEADER_MOST} bytes")
        if head[at] == 0:
            at += 1
            break
        name, at = _cstring(head, at, most)
        kind, at = _cstring(head, at, most)
        length = _int(head, at)
        at += 4
        if length < 0 or at + length > len(head):
            raise EnvironmentFileProblem("a truncated OpenEXR file (in its header)")
        attributes[name] = (kind, head[at:at + length])
        at += length
    for needed in ("channels", "compression", "dataWindow"):
        if needed not in attributes:
            raise EnvironmentFileProblem(f"a damaged OpenEXR file: its header has no "
                                         f"'{needed}'")
    compression = attributes["compression"][1][:1]
    compression = compression[0] if compression else -1
    if compression not in EXR_COMPRESSIONS:
        raise EnvironmentFileProblem(f"an OpenEXR file of unknown compression {compression}")
    window = attributes["dataWindow"][1]
    if len(window) != 16:
        raise EnvironmentFileProblem("a damaged OpenEXR file: its dataWindow is not 4 "
                                     "integers")
    x_min, y_min, x_max, y_max = (_int(window, 4 * k) for k in range(4))
    width, height = x_max - x_min + 1, y_max - y_min + 1
    if width <= 0 or height <= 0:
        raise EnvironmentFileProblem(f"an empty OpenEXR image ({max(width, 0)}x"
                                     f"{max(height, 0)})")
    _size("OpenEXR image", width, height)
    channels = _exr_channels(attributes["channels"][1], most)
    lines = EXR_COMPRESSIONS[compression][1]
    chunks = -(-height // lines)
    layout = ExrLayout(width, height, x_min, y_min, compression, channels, at, chunks)
    _exr_complete(f, layout, size)
    return layout


def _exr_channels(data: bytes, most: int) -> tuple:
    """The channel list ``(name, type)``, with R, G and B present, each of HALF or FLOAT
    samples, none subsampled."""
    channels, at = [], 0
    while at < len(data) and data[at] != 0:
        name, at = _cstring(data, at, most)
        if at + 16 > len(data):
            raise EnvironmentFileProblem("a damaged OpenEXR file: its channel list is cut")
        kind, x_sampling, y_sampling = _int(data, at), _int(data, at + 8), _int(data, at + 12)
        at += 16
        if kind not in EXR_TYPES:
            raise EnvironmentFileProblem(f"a damaged OpenEXR file: channel '{shortened(name)}' "
                                         f"has the unknown sample type {kind}")
        channels.append((name, kind, x_sampling, y_sampling))
    names = [c[0] for c in channels]
    missing = [c for c in "RGB" if c not in names]
    if missing:
        raise EnvironmentFileProblem(
            f"an OpenEXR file without channel{'s' if len(missing) > 1 else ''} "
            f"{', '.join(missing)} (it has {', '.join(map(shortened, names)) or 'none'}); "
            f"environments are RGB")
    for name, kind, xs, ys in channels:
        if name in ("R", "G", "B") and kind == 0:
            raise EnvironmentFileProblem(f"an OpenEXR file whose channel {name} holds UINT "
                                         f"samples; environments are HALF or FLOAT")
        if (xs, ys) != (1, 1):
            raise EnvironmentFileProblem(f"an OpenEXR file with the subsampled channel "
                                         f"'{shortened(name)}'; environments are not "
                                         f"subsampled")
    return tuple((name, kind) for name, kind, _, _ in channels)


def _exr_complete(f, layout: ExrLayout, size: int) -> None:
    """The offset table is within the file, and its first and last chunks are whole."""
    end = layout.table + 8 * layout.chunks
    if end > size:
        raise EnvironmentFileProblem("a truncated OpenEXR file (its table of chunks is cut)")
    for k in (0, layout.chunks - 1):
        f.seek(layout.table + 8 * k)
        offset = _int(f.read(8), 0, 8, False)
        if offset < end or offset + 8 > size:
            raise EnvironmentFileProblem("a truncated OpenEXR file (its table of chunks "
                                         "points past its end, or is empty)")
        f.seek(offset)
        chunk = f.read(8)
        length = _int(chunk, 4)
        if length < 0 or offset + 8 + length > size:
            raise EnvironmentFileProblem("a truncated OpenEXR file (a chunk of pixels is cut)")


# -- Radiance HDR -------------------------------------------------------------------
def hdr_layout(f) -> HdrLayout:
    """The layout of the Radiance HDR file open as ``f``: Mitsuba's reading of its header
    (``#?`` first; lines up to the resolution ``-Y H +X W``; ``FORMAT=32-bit_rle_rgbe``
    among them). Raises :class:`EnvironmentFileProblem`."""
    f.seek(0)
    head = f.read(_HDR_HEADER_MOST)
    lines = head.split(b"\n")
    if len(lines) < 2:
        raise EnvironmentFileProblem("a truncated Radiance HDR file (in its header)")
    at, rgbe = len(lines[0]) + 1, False
    for line in lines[1:-1]:
        at += len(line) + 1
        if line.startswith(b"FORMAT=32-bit_rle_xyze"):
            raise EnvironmentFileProblem("a Radiance HDR file of XYZ colours; environments "
                                         "are RGB (FORMAT=32-bit_rle_rgbe)")
        rgbe |= line.startswith(b"FORMAT=32-bit_rle_rgbe")
        tokens = line.split()
        if len(tokens) == 4 and tokens[0] == b"-Y" and tokens[2] == b"+X":
            if not rgbe:
                raise EnvironmentFileProblem("a Radiance HDR file without "
                                             "FORMAT=32-bit_rle_rgbe before its resolution")
            try:
                height, width = int(tokens[1]), int(tokens[3])
            except ValueError:
                break
            if width <= 0 or height <= 0:
                raise EnvironmentFileProblem(f"an empty Radiance HDR image ({width}x{height})")
            _size("HDR image", width, height)
            return HdrLayout(width, height, at)
    raise EnvironmentFileProblem(f"a Radiance HDR file without a resolution line '-Y H +X "
                                 f"W' in its first {_HDR_HEADER_MOST} bytes")


def walk_hdr(f, layout: HdrLayout, scanline=None) -> None:
    """Every scanline of the HDR file ``f`` (``layout``: its header's) read as Mitsuba
    reads them, block by block: flat pixels (4 bytes each, for the whole file when the
    first scanline is not encoded), or a scanline ``2 2 W>>8 W&255`` of four channels of
    runs (a count c > 128: c − 128 copies of the next byte; else c bytes as they are).
    ``scanline(y, data)``, when given, receives each scanline's bytes: ``4·W`` of them,
    the R, G, B and E channels one after the other (encoded) or ``RGBE`` pixels
    interleaved (flat, with ``y`` None: the whole image at once). Raises
    :class:`EnvironmentFileProblem` for a file that is truncated or damaged."""
    size = os.fstat(f.fileno()).st_size
    width, height = layout.width, layout.height
    f.seek(layout.data)
    first = f.read(4)
    flat = not layout.encoded or len(first) == 4 and (first[0] != 2 or first[1] != 2
                                                       or first[2] & 0x80)
    if flat:
        if layout.data + 4 * width * height > size:
            raise EnvironmentFileProblem("a truncated Radiance HDR file (its pixels are cut)")
        if scanline is not None:
            f.seek(layout.data)
            scanline(None, f.read(4 * width * height))
        return
    f.seek(layout.data)
    reader = _Blocks(f)
    for y in range(height):
        start = reader.take(4)
        if start[0] != 2 or start[1] != 2 or (start[2] << 8 | start[3]) != width:
            raise EnvironmentFileProblem(f"a damaged Radiance HDR file: scanline {y} is not "
                                         f"run-length encoded for width {width}")
        out = bytearray() if scanline is not None else None
        for _ in range(4):
            left = width
            while left > 0:
                count, value = reader.take(2)
                run = count - 128 if count > 128 else count
                if run == 0 or run > left:
                    raise EnvironmentFileProblem(f"a damaged Radiance HDR file: a run of "
                                                 f"{run} in scanline {y}")
                left -= run
                if count > 128:
                    if out is not None:
                        out += bytes((value,)) * run
                else:
                    rest = reader.take(run - 1) if run > 1 else b""
                    if out is not None:
                        out.append(value)
                        out += rest
        if scanline is not None:
            scanline(y, bytes(out))


class _Blocks:
    """Bytes taken from a file in order, read a block at a time."""

    def __init__(self, f, block: int = 1 << 20) -> None:
        self.f, self.block, self.data, self.at = f, block, b"", 0

    def take(self, n: int) -> bytes:
        if self.at + n > len(self.data):
            self.data = self.data[self.at:] + self.f.read(max(self.block, n))
            self.at = 0
            if n > len(self.data):
                raise EnvironmentFileProblem("a truncated Radiance HDR file (its pixels are "
                                             "cut)")
        out = self.data[self.at:self.at + n]
        self.at += n
        return out
