"""Scene text -> :class:`~mimarble.scene.model.Scene`, with positioned errors: ``parse``
and ``load``, the entry points.

Two stages:

1. Lark parses the text with the grammar (``scene.lark`` and the marble's rules
   written from its parameter table: grammar.py; LALR(1), basic lexer, positions
   propagated), fed token by token so that a statement past its count limit is refused
   at once (lark_front.py). Lark's exceptions become :class:`SceneError` with a human
   message (syntax_errors.py); no Lark exception escapes.

2. :class:`~mimarble.scene.builder.SceneBuilder` walks the tree into the frozen model,
   one reader per kind of statement (build_view, build_materials, build_shapes; values:
   build_values), checking what the grammar does not (builder.py).

Limits (limits.py, docs/scene-language.md "Limits") are enforced at the edge: a scene
file larger than :data:`~mimarble.scene.limits.MAX_SCENE_BYTES` is refused from its
size (at most that many bytes and one more are read), a FIFO or a device without being
opened for a read that could block (runtime/reading.py).
"""

from __future__ import annotations

import hashlib
import os
from typing import TYPE_CHECKING

from .errors import SceneError
from .lark_front import oversized, scene_tree
from .limits import LIMITS, MAX_SCENE_BYTES
from mimarble.runtime.reading import NotRegularFile, open_regular
from .syntax_errors import decoded

if TYPE_CHECKING:
    from .model import Scene

__all__ = ["parse", "load", "LIMITS"]

# LIMITS: limits.py, each stated once with why (and in docs/scene-language.md, Limits);
# the marble's are its parameter table's.

#: The refusal of a scene larger than the limit.
_TOO_LARGE = (f"the scene is larger than 4 MiB ({MAX_SCENE_BYTES} bytes), the most a scene "
              f"file holds (docs/scene-language.md, Limits)")


#: Scenes parsed from files, by file name (and where it is) and a digest of the bytes
#: read, with their image maps' file facts: the model is immutable, so a file read again
#: with the same bytes and maps is not parsed again (a warm ``mimarble.render(path)``
#: reads the file, ~20 µs, where parsing took ~2 ms).
_PARSED: dict = {}
_PARSED_KEPT = 16


def load(path: str | os.PathLike) -> Scene:
    """Read and parse a scene file. Every failure is a :class:`SceneError`; a file that
    is not a regular file (a FIFO, a device) is refused without being opened for a
    read that could block, and one larger than ``LIMITS["max_scene_bytes"]`` without
    being read past that. The file is read every time; the same bytes under the same
    name give the scene parsed before."""
    filename = os.fspath(path)
    if isinstance(filename, bytes):
        filename = os.fsdecode(filename)
    if filename == "" or "\0" in filename:    # "" is the current folder to the system
        raise SceneError("cannot read scene file: " + (
            "the name is empty" if not filename else
            "the name holds a NUL character, which no file name can"), filename=repr(filename))
    try:
        with open_regular(path) as f:
            if os.fstat(f.fileno()).st_size > MAX_SCENE_BYTES:
                raise SceneError(_TOO_LARGE, filename=filename)
            data = f.read(MAX_SCENE_BYTES + 1)     # no more, should it have grown since
    except NotRegularFile as e:
        raise SceneError(f"cannot read scene file: {e}", filename=filename) from None
    except FileNotFoundError:
        raise SceneError(f"cannot read scene file: no such file (looked for "
                         f"{os.path.abspath(filename)})", filename=filename) from None
    except IsADirectoryError:
        raise SceneError("cannot read scene file: it is a directory", filename=filename) from None
    except PermissionError:
        raise SceneError("cannot read scene file: permission denied", filename=filename) from None
    except OSError as e:
        raise SceneError(f"cannot read scene file: {e.strerror or e}", filename=filename) from None
    key = (os.path.abspath(filename), filename, hashlib.blake2b(data, digest_size=16).digest())
    kept = _PARSED.get(key)
    # The parser also checks the image maps' and mesh files' headers: a file changed
    # since is read again.
    if kept is None or kept[1] != _file_facts(kept[0]):
        scene = parse(data, filename=filename, source=filename)   # errors are not kept
        if len(_PARSED) >= _PARSED_KEPT:
            _PARSED.pop(next(iter(_PARSED)))
        kept = _PARSED[key] = (scene, _file_facts(scene))
    return kept[0]


def _file_facts(scene) -> tuple:
    """(size, modification and change times, inode) of each image map's and mesh's file
    (None: unreadable)."""
    facts = []
    for located in scene.image_maps() + scene.meshes:
        try:
            found = os.stat(located.location)
            facts.append((found.st_size, found.st_mtime_ns, found.st_ctime_ns, found.st_ino))
        except OSError:
            facts.append(None)
    return tuple(facts)


def parse(text: str | bytes, filename: str = "<string>", *, source: str | None = None) -> Scene:
    """Parse scene text. ``filename`` is used in messages only.

    ``Scene.source`` is ``source`` if given, else ``filename`` unless that is
    the default ``"<string>"``. Text of more than ``LIMITS["max_scene_bytes"]``
    bytes (as UTF-8) is refused, as a file of that size is.
    """
    if not isinstance(text, (str, bytes, bytearray)):
        raise TypeError(f"parse: the scene text must be str or bytes, found "
                        f"{type(text).__name__}")
    if oversized(text):
        raise SceneError(_TOO_LARGE, filename=filename)
    if isinstance(text, (bytes, bytearray)):
        text = decoded(bytes(text), filename)
    if text.startswith("\ufeff"):  # a UTF-8 byte order mark is not part of the scene
        text = text[1:]
    if source is None and filename != "<string>":
        source = filename
    tree = scene_tree(text, filename)
    # The builder (and the model it builds) loads only for text that parsed: a syntax
    # error is answered without them (issue 39's start-up of a malformed scene).
    from .builder import SceneBuilder
    return SceneBuilder(text, filename, source).scene(tree, source)


# --------------------------------------------------------------------------
#  Tree -> model, with validation
# --------------------------------------------------------------------------
