"""Comments, taken out before Lark reads the text: ``// …`` and nesting ``/* … */``.

Block comments nest, as POV-Ray's do: ``/* a /* b */ c */`` is one comment, so a block
of scene that holds a comment can be commented out whole. A regular expression (a Lark
terminal) cannot count, so :func:`blanked` replaces every comment by spaces before the
text is lexed, keeping its newlines: each token stays at the line and column where it
was written, and an error Lark finds is reported at its place in the file as written.

Inside a block comment only ``/*`` and ``*/`` count (a ``//`` or a ``"`` there is
text); a ``//`` comment runs to the end of its line, whatever it holds; a string
(``"…"`` on one line) holds no comment. A ``/*`` that is never closed is an error at
that ``/*``: the outermost one still open at the end of the file. A ``*/`` outside any
comment is left in the text, for the lexer to refuse at its place.
"""

from __future__ import annotations

import re

from .errors import SceneError

__all__ = ["blanked"]

#: What is read outside comments: a string (to its closing quote, or unterminated to the
#: end of its line, for Lark to refuse), a line comment, or the start of a block comment.
_OUTSIDE = re.compile(r'"[^"\n]*"?|//[^\n]*|/\*')
#: Inside a block comment: a nested opening or a closing.
_INSIDE = re.compile(r"/\*|\*/")
#: Every character but a newline (replaced by a space).
_NOT_NEWLINE = re.compile(r"[^\n]")


def _line_column(text: str, index: int) -> tuple[int, int]:
    line = text.count("\n", 0, index) + 1
    return line, index - (text.rfind("\n", 0, index) + 1) + 1


def blanked(text: str, filename: str = "<string>") -> str:
    """``text`` with every comment replaced by spaces (newlines kept), the same length;
    a SceneError at the ``/*`` of a block comment that is never closed."""
    if "/" not in text:
        return text
    parts: list[str] = []
    done = 0            # text[:done] is in parts
    at = 0
    while True:
        found = _OUTSIDE.search(text, at)
        if found is None:
            break
        start, kind = found.start(), found.group()[:2]
        if kind[0] == '"':                  # a string holds no comment
            at = found.end()
            continue
        end = found.end() if kind == "//" else _block_end(text, start, filename)
        comment = text[start:end]
        parts.append(text[done:start])
        parts.append(_NOT_NEWLINE.sub(" ", comment) if "\n" in comment else " " * len(comment))
        done = at = end
    if not parts:
        return text
    parts.append(text[done:])
    return "".join(parts)


def _block_end(text: str, start: int, filename: str) -> int:
    """Where the block comment opened at ``start`` ends (just past its ``*/``)."""
    depth, at, nested = 1, start + 2, None      # nested: where the first '/*' inside is
    while depth:
        found = _INSIDE.search(text, at)
        if found is None:
            line, column = _line_column(text, start)
            message = "unterminated block comment: '/*' has no matching '*/'"
            if nested is not None:
                nested = _line_column(text, nested)
                message += (f" (block comments nest: the '/*' at {nested[0]}:{nested[1]} "
                            f"inside it opens one of its own, which the next '*/' closes)")
            raise SceneError.at(text, filename, line, column, message)
        if found.group() == "/*":
            depth += 1
            if nested is None:
                nested = found.start()
        else:
            depth -= 1
        at = found.end()
    return at
