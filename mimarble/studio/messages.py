"""The studio page's messages to its server, declared once: each type, its fields and their
JSON types, and the checks a message passes before the server acts on it.

The page sends JSON objects over the websocket (``{"type": "edit", "key": …, "value": …}``);
the server answers every one it cannot use with one sentence (:class:`MessageError`) and
goes on: a malformed, unknown, oversized or ill-typed message never reaches the session.
The server's own messages to the page (``hello``, ``frame``, ``state``, ``controls``,
``values``, ``edited``, ``invalid``, ``done``, ``problem``, ``compare``) are written in
mimarble/studio/server.py; the frame's binary layout is :func:`frame_message`'s.

Standard library only.
"""

from __future__ import annotations

import json
import math
import struct
import sys

#: The largest message the page may send, in bytes (a ramp of 64 colours is ~2 KB): a
#: bigger one is answered and dropped. The websocket itself closes at :data:`MAX_WIRE_BYTES`.
MAX_MESSAGE_BYTES = 64 * 1024
#: The transport's own limit (uvicorn's ``ws_max_size``): larger frames close the socket.
MAX_WIRE_BYTES = 1024 * 1024
#: The longest key path and file name a message may carry, in characters.
MAX_TEXT = 4096

_NUMBER = (int, float)
#: Each message type: its fields, each with the JSON types it may have (None: any JSON
#: value, checked by the session: an edit's value is the parameter table's to judge).
FIELDS = {
    "edit": {"key": (str,), "value": None, "seq": _NUMBER},
    "orbit": {"dx": _NUMBER, "dy": _NUMBER},
    "zoom": {"factor": _NUMBER},
    "save": {},
    "save_as": {"path": (str,)},
    "snapshot": {"path": (str,)},
    "export": {"path": (str,), "python": (bool,)},
    "compare": {},
    "preset": {"prefix": (str,), "name": (str,)},
    "reload": {},
    "ping": {"seq": _NUMBER},
}
#: The fields a message may leave out.
OPTIONAL = {("edit", "seq"), ("export", "python"), ("ping", "seq")}


class MessageError(ValueError):
    """A message the server cannot use; its text is the sentence the page shows."""


def parse(text) -> dict:
    """The message ``text`` (str or bytes) as a checked dict, or :class:`MessageError`.

    Checks: size (:data:`MAX_MESSAGE_BYTES`), JSON, an object, a known ``type``, every
    field present with its JSON type, no unknown field, finite numbers, strings within
    :data:`MAX_TEXT` characters.
    """
    size = len(text.encode("utf-8", "surrogatepass") if isinstance(text, str) else text)
    if size > MAX_MESSAGE_BYTES:
        raise MessageError(f"a message of {size} bytes is over the studio's limit of "
                           f"{MAX_MESSAGE_BYTES} bytes; it was dropped")
    try:
        message = json.loads(text, parse_constant=_no_constant)
    except (ValueError, RecursionError) as e:
        raise MessageError(f"a message must be a JSON object; this one is not JSON ({e})") from None
    if not isinstance(message, dict):
        raise MessageError("a message must be a JSON object with a \"type\"")
    kind = message.get("type")
    if kind not in FIELDS:
        known = ", ".join(sorted(FIELDS))
        raise MessageError(f"unknown message type {str(kind)[:40]!r}; the studio knows: {known}")
    fields = FIELDS[kind]
    for name in message:
        if name != "type" and name not in fields:
            raise MessageError(f"a {kind!r} message has no field {str(name)[:40]!r}; "
                               f"it has: {', '.join(fields) or 'none'}")
    for name, types in fields.items():
        if name not in message:
            if (kind, name) in OPTIONAL:
                continue
            raise MessageError(f"a {kind!r} message needs the field {name!r}")
        value = message[name]
        if types is not None and (not isinstance(value, types)
                                  or (bool not in types and isinstance(value, bool))):
            wanted = " or ".join(_JSON_NAMES[t] for t in types)
            raise MessageError(f"a {kind!r} message's {name!r} must be {wanted}")
        _check_sizes(value, f"{kind}.{name}")
    return message


_JSON_NAMES = {str: "a string", int: "a number", float: "a number", bool: "true or false"}


def _no_constant(name):
    """JSON's non-standard NaN and Infinity are refused as they are read."""
    raise ValueError(f"{name} is not a number JSON allows")


#: The largest finite float: a JSON integer past it is no number the studio can use.
_LARGEST_FLOAT = sys.float_info.max


def _check_sizes(value, where: str, depth: int = 0) -> None:
    """Strings within :data:`MAX_TEXT`, numbers finite, nesting shallow."""
    if depth > 4:
        raise MessageError(f"{where} is nested too deeply")
    if isinstance(value, str) and len(value) > MAX_TEXT:
        raise MessageError(f"{where} is {len(value)} characters long; at most {MAX_TEXT}")
    if isinstance(value, float) and not math.isfinite(value):
        raise MessageError(f"{where} must be a finite number")
    if isinstance(value, int) and abs(value) > _LARGEST_FLOAT:
        # JSON's 1 followed by 400 zeros is a Python int: float() of it overflows later.
        raise MessageError(f"{where} must be a finite number (it is past a float's range)")
    if isinstance(value, list):
        for item in value:
            _check_sizes(item, where, depth + 1)
    if isinstance(value, dict):
        for item in value.values():
            _check_sizes(item, where, depth + 1)


def frame_message(header: dict, image: bytes) -> bytes:
    """A frame as one binary websocket message: the header's JSON length (4 bytes,
    big-endian), the header as UTF-8 JSON, then the image's bytes (PNG or JPEG; its type
    is the header's ``mime``). The page (static/studio.js, ``onFrame``) reads it back."""
    head = json.dumps(header, separators=(",", ":")).encode()
    return struct.pack(">I", len(head)) + head + image
