"""SceneError: every user error in a scene file, as ``FILE:LINE:COL: message``."""

from __future__ import annotations

import unicodedata

from .limits import MAX_SCENE_BYTES
from mimarble.runtime.reading import open_regular

__all__ = ["SceneError", "TAB_SIZE", "SHOWN_WIDTH", "printable"]

#: Tab stops used to display a source line (columns still count a tab as one).
TAB_SIZE = 8
#: The most characters of a source line shown: a longer line is shown as a window of
#: this many around the column, "..." where it was cut (an error on a 4 MB line does not
#: echo 4 MB).
SHOWN_WIDTH = 120
_CUT = "..."

#: Format characters (Unicode category Cf) shown as they are: the zero-width joiner and
#: non-joiner, which Persian and Indic words and emoji sequences need. The other format
#: characters act instead of showing — the bidirectional overrides and isolates reorder
#: the text after them on the screen — and are escaped.
_SHOWN_FORMAT_CHARACTERS = frozenset("\u200c\u200d")
#: Categories whose characters act on a terminal rather than show: controls (C0, DEL,
#: C1: ESC begins the terminal's escape sequences, BEL rings, CSI U+009B is ESC [),
#: lone surrogates (Python's stand-ins for the bytes of a name that is not UTF-8) and
#: the line and paragraph separators.
_ACTING_CATEGORIES = frozenset(("Cc", "Cs", "Zl", "Zp"))
_ESCAPES = {"\t": "\\t", "\n": "\\n", "\r": "\\r"}


def printable(text, keep: str = "") -> str:
    """``text`` — a user's string, a file name — as it may be echoed in a message on a
    terminal: every character that would act rather than show (``_ACTING_CATEGORIES``,
    format characters but the joiners) written as a Python string literal writes it
    (``\\x1b``, ``\\x07``, ``\\x9b``, ``\\u202e``, ``\\n``); a byte of a file name that
    is not UTF-8 (which Python decodes to a lone surrogate U+DC80..U+DCFF) as ``\\xNN``,
    that byte. Letters of every script, accents and emoji are shown as they are.
    ``keep``: characters left as they are (a quoted source line's tabs, which the caret
    line expands alike). Every message that echoes a user's string shows it through
    this: SceneError's parts, and the command line's messages and warnings."""
    text = str(text)
    if text.isprintable():     # no control, separator or format character: nothing acts
        return text
    return "".join(_shown_character(c) if c not in keep else c for c in text)


def _shown_character(c: str) -> str:
    category = unicodedata.category(c)
    if category not in _ACTING_CATEGORIES and not (
            category == "Cf" and c not in _SHOWN_FORMAT_CHARACTERS):
        return c
    code = ord(c)
    if c in _ESCAPES:
        return _ESCAPES[c]
    if 0xDC80 <= code <= 0xDCFF:                 # surrogateescape: the byte itself
        return f"\\x{code - 0xDC00:02x}"
    return f"\\x{code:02x}" if code < 0x100 else \
        f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


class SceneError(Exception):
    """A syntax or validation error in a scene file.

    Attributes: ``filename``, ``line`` and ``column`` (1-based; column counts
    characters, a tab is one), ``message``, ``source_line`` (the text of the
    offending line, without its newline). ``str(err)`` is::

        FILE:LINE:COL: message
        the offending source line
                ^

    with tabs expanded to 8-column stops and the caret under the column, then, for a habit
    of POV-Ray's that the language writes otherwise, one more line ``hint: …`` naming
    this language's way (``hint``; syntax_errors.POVRAY_HINTS). A line longer
    than :data:`SHOWN_WIDTH` characters is shown as a window of that many around the
    column, with ``...`` where it was cut.
    Errors without a position (a file that cannot be read) have ``line`` and
    ``column`` None and print as ``FILE: message`` alone.
    The command-line interface prints ``str(err)`` and exits with status 2.
    """

    exit_status = 2

    def __init__(
        self,
        message: str,
        *,
        filename: str = "<string>",
        line: int | None = None,
        column: int | None = None,
        source_line: str | None = None,
        hint: str | None = None,
    ) -> None:
        self.message = message
        self.hint = hint
        self.filename = filename
        self.line = line
        self.column = column
        self.source_line = source_line
        super().__init__(message)

    @classmethod
    def at(cls, text: str, filename: str, line: int, column: int, message: str,
           hint: str | None = None) -> "SceneError":
        """An error at (line, column) of ``text``, quoting that line."""
        lines = text.split("\n")
        src = lines[line - 1] if 1 <= line <= len(lines) else ""
        return cls(message, filename=filename, line=line, column=column,
                   source_line=src.rstrip("\r"), hint=hint)

    @classmethod
    def in_file(cls, source: str | None, pos, message: str) -> "SceneError":
        """An error found after parsing, at ``pos`` (line, column; None: unknown) of the
        scene file ``source`` (None: built in Python), quoting its line when it can."""
        line, column = (pos.line, pos.column) if pos is not None else (None, None)
        src = None
        if source and line is not None:
            try:          # a regular file of at most the scene size limit, read whole
                with open_regular(source) as f:
                    data = f.read(MAX_SCENE_BYTES + 1)
                if len(data) <= MAX_SCENE_BYTES:
                    lines = data.decode("utf-8").lstrip("\ufeff").split("\n")
                    src = lines[line - 1].rstrip("\r") if line <= len(lines) else None
            except (OSError, UnicodeDecodeError):
                src = None
        return cls(message, filename=source or "<scene>", line=line, column=column, source_line=src)

    @classmethod
    def undecodable_image(cls, scene, channel, reason: str) -> "SceneError":
        """An image map of ``scene`` whose file the parser accepted (its header) but a
        renderer could not decode, at the map's ``file`` string."""
        return cls.in_file(scene.source, channel.pos,
                           f"image file '{channel.file}' cannot be decoded: {reason}")

    def __reduce__(self):
        return (_rebuild, (self.message, self.filename, self.line, self.column, self.source_line,
                           self.hint))

    @property
    def location(self) -> str:
        """``FILE:LINE:COL`` (or less, when the position is unknown)."""
        parts = [self.filename]
        if self.line is not None:
            parts.append(str(self.line))
            if self.column is not None:
                parts.append(str(self.column))
        return ":".join(parts)

    def __str__(self) -> str:
        shown = self._shown()
        return shown if self.hint is None else f"{shown}\nhint: {printable(self.hint)}"

    def _shown(self) -> str:
        # The user's strings (the file's name, a word quoted in the message, the source
        # line) through printable(): a scene's escape codes are shown, never sent.
        head = f"{printable(self.location)}: {printable(self.message)}"
        if self.line is None or self.source_line is None:
            return head
        line = self.source_line
        at = max(self.column - 1, 0) if self.column is not None else 0
        # The window shown: the whole line, or SHOWN_WIDTH characters around the column.
        start, end = 0, len(line)
        if len(line) > SHOWN_WIDTH:
            start = min(max(at - SHOWN_WIDTH // 2, 0), len(line) - SHOWN_WIDTH)
            end = start + SHOWN_WIDTH
        before = _CUT if start > 0 else ""
        shown = printable(before + line[start:end] + (_CUT if end < len(line) else ""),
                          keep="\t").expandtabs(TAB_SIZE)
        if self.column is None:
            return f"{head}\n{shown}"
        # The caret under the column of the line as shown (escapes widen what precedes it).
        prefix = printable(before + line[start:at], keep="\t")
        # Pad past the end of the line if the column is beyond it (end of file).
        prefix += " " * max(at - len(line), 0)
        width = len(prefix.expandtabs(TAB_SIZE))
        return f"{head}\n{shown}\n{' ' * width}^"


def _rebuild(message, filename, line, column, source_line, hint=None):
    return SceneError(message, filename=filename, line=line, column=column, source_line=source_line,
                      hint=hint)
