"""Whether a file can be an image map, read from its header alone.

The scene language refuses an image map that is missing or is not an 8-bit PNG or a JPEG
while it parses, at the file's string, so the user hears of it before a render starts;
decoding the pixels comes later (the Mitsuba path, the reference tracer). The header is
read with the standard library only: the scene package imports no imaging library.
"""

from __future__ import annotations

__all__ = ["image_file_problem"]

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_JPEG_SIGNATURE = b"\xff\xd8\xff"


def image_file_problem(path: str) -> str | None:
    """Why ``path`` cannot be an image map (None: it can): it must exist, be readable,
    and be an 8-bit PNG or a JPEG (read from its header; decoding comes later)."""
    try:
        with open(path, "rb") as f:
            head = f.read(33)       # the PNG signature and its IHDR chunk
    except FileNotFoundError:
        return f"no such file (looked for {path})"
    except IsADirectoryError:
        return f"it is a directory ({path})"
    except PermissionError:
        return f"permission denied ({path})"
    except OSError as e:
        return f"cannot read it: {e.strerror or e} ({path})"
    if head.startswith(_PNG_SIGNATURE):
        if len(head) < 33 or head[12:16] != b"IHDR":
            return "a truncated PNG (no IHDR header)"
        width, height = int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
        depth = head[24]
        if width == 0 or height == 0:
            return f"an empty PNG ({width}x{height})"
        if depth != 8:
            return f"a {depth}-bit PNG; image maps are 8-bit PNG or JPEG"
        return None
    if head.startswith(_JPEG_SIGNATURE):
        return None
    return "not a PNG or JPEG file; image maps are 8-bit PNG or JPEG"
