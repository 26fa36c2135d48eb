"""The studio's errors as it says them: :class:`StudioError` (what it cannot do now) and
:func:`error_dict` (a parse or render error as the page shows it)."""

from __future__ import annotations

from mimarble import scene as scene_language

__all__ = ["StudioError", "error_dict"]


class StudioError(Exception):
    """Something the studio cannot do now (save over a changed file, compare in path
    mode, …): one sentence, for the page to show."""


def error_dict(error: Exception) -> dict:
    """A parse or render error as the page shows it: ``message`` (the whole text: for a
    SceneError ``FILE:LINE:COL: message``, the line and its caret, the hint), ``where``,
    ``file``, ``line``, ``column``, ``hint``."""
    if isinstance(error, scene_language.SceneError):
        return {"message": str(error), "where": error.location, "file": error.filename,
                "line": error.line, "column": error.column, "hint": error.hint}
    return {"message": str(error), "where": None, "file": None, "line": None,
            "column": None, "hint": None}
