"""Saving a scene's edits into its text: only the edited values' text changes.

:func:`rewrite` takes a scene file's text and edits by key path (keys.py) and returns the
text with each edited value's text replaced — a number, a word, a vector, a colour, a
ramp stop or the ramp's stops — and every other byte as it was: comments, layout, order,
CRLF newlines, tabs, unicode. The parser records where each value stands
(:class:`~mimarble.scene.nodes.Source`: offsets into the text; comments are blanked to
spaces of the same length before Lark reads it, so the offsets are the file's).

* A value the file does not state (a default) is written into its block: on a line of
  its own before the block's closing brace, indented as the block's last key, when the
  brace starts its line; else before the brace on its line. A block the file lacks
  (``camera``, ``image``) is a new statement at the end.
* A key that names several marbles (``marble.period``) rewrites each marble block; a
  marble written once in a named texture is one block, however often it is used.
* Every edit is checked: the text it makes, parsed again, must be the scene
  ``with_value`` makes — an edit the text cannot say alone (``stone.diffuse.period``
  where that marble is texture "veins"'s, which other materials use too) is refused,
  naming the key that can.

:func:`save_atomic` writes a file whole or not at all (a temporary file in its folder,
then ``os.replace``), and refuses when the file changed on disk since it was loaded.
"""

from __future__ import annotations

import os
import stat
import tempfile

from .comments import blanked
from .key_families import MarbleKeys, Place, evenly_spaced
from .key_values import KeyPathError, Value, number_text, read, vector_text
from .keys import key_of, with_value
from .limits import MAX_SCENE_BYTES
from .parser import parse

__all__ = ["rewrite", "save_atomic", "read_scene_text", "SaveRefused"]

_BOM = "\ufeff"
#: Edits one :func:`rewrite` writes at most: each is two parses of the text (8–12 ms for the
#: shipped scenes), so 1024 take seconds; a studio's save holds the keys edited since the
#: file was loaded, a few dozen.
MAX_EDITS = 1024


class SaveRefused(OSError):
    """A save that would overwrite what it was not given: the file changed on disk."""


def rewrite(text: str, edits, filename: str = "<string>", source: str | None = None) -> str:
    """``text`` with each edit written into it, every other byte kept.

    ========== ===========================================================================
    text       a scene file's text (:func:`read_scene_text`), a byte order mark kept
    edits      key path → value, as ``with_value`` takes them, applied in order (at most
               :data:`MAX_EDITS`)
    filename   the name messages give the text
    source     the file's path: its meshes and image maps are found beside it
    ========== ===========================================================================

    SceneError when ``text`` does not parse; KeyPathError for an unknown key, a value it
    cannot take, or an edit the text cannot say alone."""
    if not isinstance(text, str):
        raise TypeError(f"rewrite: the scene text must be str (read_scene_text reads a "
                        f"file's), found {type(text).__name__}")
    edits = dict(edits)
    if len(edits) > MAX_EDITS:
        raise KeyPathError(f"{len(edits)} edits at once; a save writes at most {MAX_EDITS}")
    for path, value in edits.items():
        text = _rewritten(text, path, value, filename, source)
    return text


def _rewritten(text: str, path: str, value, filename: str, source: str | None) -> str:
    """``text`` with one edit written into it, checked by parsing the result."""
    bom = _BOM if text.startswith(_BOM) else ""
    body = text[len(bom):]                       # the parser's offsets are past the mark
    scene = parse(body, filename, source=source)
    wanted = with_value(scene, path, value)      # the key and the value, checked
    key = key_of(scene, path)
    value = read(path, key.parameter, value, key.stop)
    text_of = _Text(body)
    for place in key.family.places(scene, key):
        text_of.place(place, key, value, key.family.written(key, value))
    new = text_of.result()
    if parse(new, filename, source=source) != wanted:
        raise KeyPathError(f"{path}: {_why_not(scene, key)}")
    return bom + new


def _why_not(scene, key) -> str:
    """Why an edit's text, parsed again, is not the edited scene: a material's (or a
    channel's) marble written in a named texture, which the file can only change for every
    use of the texture (and the scene's ``textures``) at once."""
    family = key.family
    if isinstance(family, MarbleKeys) and key.target[0] in ("material", "channel"):
        blocks = {m.source.block for m in family.selected(scene, key.target)}
        for group, prefix, selection in family.groups(scene):
            if selection[0] == "texture" and any(m.source.block in blocks for m in
                                                 family.selected(scene, selection)):
                name = key.parameter.name + ("" if key.stop is None else f".{key.stop}")
                return (f"its marble is written in {group}, so the file cannot change it for "
                        f"this material alone; edit {prefix}.{name} (every use of the texture)")
    return "the file cannot say this edit alone (its text, read again, is not the edited scene)"


class _Text:
    """The changes to a text, made at once: (start, end, new text) each, not overlapping."""

    def __init__(self, body: str) -> None:
        self.body = body
        self.blank = blanked(body)               # comments as spaces: braces found safely
        self.newline = "\r\n" if "\r\n" in body else "\n"
        self.changes: list[tuple[int, int, str]] = []

    def result(self) -> str:
        out, at = [], 0
        for start, end, new in sorted(self.changes, key=lambda c: (c[0], c[1])):
            if start < at:
                raise KeyPathError("two edits touch the same text")   # pragma: no cover
            out += [self.body[at:start], new]
            at = end
        return "".join(out) + self.body[at:]

    def place(self, place: Place, key, value: Value, written: str) -> None:
        """Write ``value`` at ``place``."""
        if place.source is None:                 # no such block: a statement of its own
            self.statement(f"{place.statement} {{ {place.name} {written} }}")
        elif place.name == "ramp":
            self.ramp(place, key, value)
        elif place.name in place.source.values:
            start, end = place.source.values[place.name]
            self.changes.append((start, end, written))
        else:
            self.insert(place.source, f"{place.name} {written}")

    def statement(self, line: str) -> None:
        """A new statement at the end of the text, on its own line."""
        end = len(self.body)
        lead = self.newline if self.body and not self.body.endswith("\n") else ""
        self.changes.append((end, end, lead + line + self.newline))

    def insert(self, source, line: str) -> None:
        """``line`` (a key and its value) into the block of ``source``."""
        start, end = source.block
        close = end - 1                           # the block's '}'
        line_start = self.blank.rfind("\n", 0, close) + 1
        if line_start > start and not self.blank[line_start:close].strip():
            # '}' starts its line: a line of its own, indented as the block's last key
            indent = self.indent(source, line_start)
            self.changes.append((line_start, line_start, indent + line + self.newline))
            return
        at = close
        while at > start and self.blank[at - 1] in " \t":
            at -= 1
        self.changes.append((at, at, " " + line + (" " if at == close else "")))

    def indent(self, source, close_line: int) -> str:
        """The indentation of the block's last key, or the closing brace's and one step."""
        if source.values:
            last = max(span[0] for span in source.values.values())
            line_start = self.blank.rfind("\n", 0, last) + 1
        else:
            line_start = close_line
        line = self.body[line_start:]
        indent = line[:len(line) - len(line.lstrip(" \t"))]
        if not source.values:
            indent += "\t" if indent.startswith("\t") else "    "
        return indent

    # -- ramps ----------------------------------------------------------------
    def ramp(self, place: Place, key, value: Value) -> None:
        """A ramp's stop, or its stops: each stop whose value changed rewritten (its
        colour, its position); positions written before every colour when the ramp gets
        them; the stops between the braces written anew when their count changes."""
        marble, source = place.node, place.source
        old = [(None if marble.ramp_positions is None else marble.ramp_positions[k], rgb)
               for k, rgb in enumerate(marble.ramp)]
        texts = [(self.body[p[0]:p[1]] if p else None, self.body[c[0]:c[1]])
                 for p, c in source.stops]
        if "ramp" not in source.values:           # unwritten: the default's, or a preset's
            texts = [(None if p is None else number_text(p), vector_text(rgb)) for p, rgb in old]
        if key.stop is None:
            new = list(zip(value.value[1] or [None] * len(value.value[0]), value.value[0]))
            new_texts = list(value.stops)
        else:
            n = key.stop
            position, rgb = value.value
            new, new_texts = list(old), list(texts)
            new[n] = (position if position is not None else old[n][0], rgb)
            new_texts[n] = (value.position_text or texts[n][0], value.text)
            if position is not None and old[n][0] is None:     # positions from now on
                spaced = evenly_spaced(len(old))
                new = [(spaced[k] if k != n else position, c) for k, (_, c) in enumerate(new)]
                new_texts = [(number_text(spaced[k]) if k != n else value.position_text, t)
                             for k, (_, t) in enumerate(new_texts)]
        if "ramp" not in source.values:
            items = " ".join(_item(t) for t in new_texts)
            self.insert(source, f"ramp {{ {items} }}")
            return
        if len(new) == len(old):                  # stop by stop: what changed
            for k, ((p, c), (p_text, c_text)) in enumerate(zip(new, new_texts)):
                p_span, c_span = source.stops[k]
                if c != old[k][1]:
                    self.changes.append((*c_span, c_text))
                if p is None and p_span is not None:        # positions taken away
                    self.changes.append((p_span[0], c_span[0], ""))
                elif p is not None and p_span is None:      # positions given
                    self.changes.append((c_span[0], c_span[0], p_text + " "))
                elif p is not None and p != old[k][0]:
                    self.changes.append((*p_span, p_text))
            return
        first, last = source.stops[0], source.stops[-1]
        start = (first[0] or first[1])[0]
        end = last[1][1]
        if len(source.stops) > 1:                 # as the stops were separated
            second = source.stops[1]
            gap = self.body[first[1][1]:(second[0] or second[1])[0]]
            separator = gap if not gap.strip() else " "
        else:
            separator = " "
        self.changes.append((start, end, separator.join(_item(t) for t in new_texts)))


def _item(stop: tuple) -> str:
    """A ramp stop as the ramp block writes it: ``[position] colour``."""
    position, colour = stop
    return f"{position} {colour}" if position is not None else colour


# ---------------------------------------------------------------------------
# Files

def read_scene_text(path) -> str:
    """A scene file's text exactly as it is (UTF-8; bytes that are not UTF-8 kept as
    surrogates; CRLF kept): what :func:`save_atomic` compares with the file on disk.
    OSError as ``open`` raises it; a file past the scene size limit is refused."""
    with open(path, "rb") as f:
        data = f.read(MAX_SCENE_BYTES + 1)
    if len(data) > MAX_SCENE_BYTES:
        raise SaveRefused(f"{os.fspath(path)}: larger than a scene file may be "
                          f"({MAX_SCENE_BYTES} bytes)")
    return data.decode("utf-8", "surrogateescape")


def save_atomic(path, text: str, loaded_text: str | None) -> None:
    """Write ``text`` to a scene file whole or not at all: a temporary file in the same
    folder, synced, then renamed over it (``os.replace``), with the file's permission bits.

    =========== ==========================================================================
    path        the file (a link is written through, to the file it names)
    text        the new text (:func:`rewrite`'s)
    loaded_text the file's text when it was loaded (:func:`read_scene_text`); None: no
                check ("Save as" a new name)
    =========== ==========================================================================

    :class:`SaveRefused`, nothing written, when the file on disk is no longer
    ``loaded_text``; OSError as the system says it (a folder not writable)."""
    path = os.path.realpath(os.fspath(path))
    if loaded_text is not None:
        try:
            current = read_scene_text(path)
        except FileNotFoundError:
            current = None
        if current != loaded_text:
            said = "was deleted" if current is None else "changed on disk"
            raise SaveRefused(f"{path}: the file {said} since it was loaded; reload it "
                              f"(nothing was written)")
    data = text.encode("utf-8", "surrogateescape")
    folder, name = os.path.split(path)
    fd, temporary = tempfile.mkstemp(dir=folder, prefix=f".{name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        try:
            os.chmod(temporary, stat.S_IMODE(os.stat(path).st_mode))
        except FileNotFoundError:
            pass
        os.replace(temporary, path)
    except BaseException:
        try:
            os.unlink(temporary)
        except FileNotFoundError:
            pass
        raise
