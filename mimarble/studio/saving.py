"""Writing a studio session's edits back into its scene file: Save and Save as.

:class:`SceneSaving` holds :class:`~mimarble.studio.session.StudioSession`'s ``save`` and
``save_as`` (the session is one, mixed in: one concept a module, the session's editing and
rendering in session.py). A save rewrites only the edited values' text (``scene.rewrite``:
comments, layout, order and every other byte kept) and writes the file whole or not at all
(``scene.rewrite.save_atomic``). The text is rewritten and parsed outside the session's
lock, so an edit made meanwhile neither waits for the save nor is lost: it stays an unsaved
edit. Decisions: docs/design-decisions.md, "Marble studio engine (issue 41)".
"""

from __future__ import annotations

import os
from pathlib import Path

from mimarble import scene as scene_language
from mimarble.scene.edits import KeyPathError
from mimarble.scene.rewrite import SaveRefused, rewrite, save_atomic
from .errors import StudioError

__all__ = ["SceneSaving", "rewritten", "file_facts"]


class SceneSaving:
    """Save and Save as, mixed into the session, whose state they read and adopt:

    ============== ==================================================================
    path           the scene file (Save as makes it the new one)
    packaged       True for a packaged scene: Save refuses, Save as writes a copy
    _lock          the session's lock: its state is read and adopted under it
    _save_lock     one save at a time, held while the text is rewritten and parsed
    _text, _stat   the file's text as loaded or saved, and its :func:`file_facts`
    _base          that text parsed
    _edits         key → value, the edits not yet saved
    _disk_changed  the file changed on disk under unsaved edits: Save refuses
    _emit, state   the session's listeners, told the new state after a save
    ============== ==================================================================
    """

    def save(self) -> str:
        """Write the edits into the scene file, changing only their values' text
        (``scene.rewrite``: comments, layout, order, every other byte kept), whole or not
        at all; returns the text written. StudioError (one sentence, nothing written) for
        a packaged scene (Save as writes a copy), a file that changed on disk since it was
        loaded (:meth:`reload` first), or an edit the text cannot say. Edits made while it
        saves are kept as unsaved edits."""
        with self._save_lock:
            with self._lock:
                self._check_saveable()
                path, before, edits = self.path, self._text, dict(self._edits)
            text = rewritten(before, edits, path)
            base = scene_language.parse(text, filename=str(path), source=str(path))
            with self._lock:
                self._check_saveable()
                self._write("save", path, text, before, expected=before)
                self._saved(text, base, edits)
        self._emit("state", self.state())
        return text

    def _write(self, action: str, path, text: str, before: str, expected) -> None:
        """Write ``text`` to ``path`` atomically (``expected``: the text the file must
        still hold, None for any), under the lock, unless the file was reloaded since
        ``before`` was read; StudioError (nothing written) otherwise."""
        if self._text is not before:
            raise StudioError(f"{action}: the file was reloaded while it was being saved "
                              f"(nothing was written)")
        try:
            save_atomic(path, text, expected)
        except SaveRefused as e:
            self._disk_changed = True
            raise StudioError(f"{action}: {e}") from None
        except OSError as e:
            raise StudioError(f"{action}: {path}: {e.strerror or e}") from None

    def _check_saveable(self) -> None:
        if self.packaged:
            raise StudioError(f"save: {self.path.name} is a packaged scene, not yours "
                              f"to overwrite; use Save as to write a copy")
        if self._disk_changed:
            raise StudioError(f"save: {self.path} changed on disk since it was loaded; "
                              f"reload it (nothing was written)")

    def save_as(self, path) -> str:
        """Write the scene as edited now to ``path`` (the file's text with the edits
        written in, whole or not at all); the session then edits that file. Returns the
        text written; StudioError for a name or folder that cannot be written, or a
        folder where the scene's relative files (meshes, image maps) are not: nothing is
        written then, and the session keeps its file."""
        from mimarble.runtime.files import output_name_problem
        problem = output_name_problem(path)
        if problem:
            raise StudioError(f"save as: {str(path)!r:.80}: {problem}")
        with self._save_lock:
            with self._lock:
                before, edits = self._text, dict(self._edits)
            text = rewritten(before, edits, self.path)
            try:      # read as it would be there: its meshes and image maps beside it
                base = scene_language.parse(text, filename=str(path), source=str(path))
            except scene_language.SceneError as e:
                first = str(e).splitlines()[0]
                raise StudioError(f"save as: the scene would not read at {path} ({first}); "
                                  f"save it beside the files it names (nothing was "
                                  f"written)") from None
            with self._lock:
                self._write("save as", path, text, before, expected=None)
                self.path, self.packaged = Path(path), False
                self._saved(text, base, edits)
        self._emit("state", self.state())
        return text

    def _saved(self, text: str, base, saved: dict) -> None:
        """The file now holds ``text`` (parsed: ``base``), with the edits ``saved``: it
        is what the session was loaded from; edits made since stay unsaved."""
        self._text, self._stat, self._base = text, file_facts(self.path), base
        self._edits = {key: value for key, value in self._edits.items()
                       if key not in saved or saved[key] is not value}
        self._disk_changed = False


def rewritten(text: str, edits: dict, path: Path) -> str:
    """``text`` with ``edits`` written in (StudioError: an edit it cannot say)."""
    try:
        return rewrite(text, edits, filename=str(path), source=str(path))
    except (KeyPathError, scene_language.SceneError) as e:
        raise StudioError(f"save: {e}") from None


def file_facts(path: Path) -> tuple | None:
    """(size, modification time, change time, inode) of the file, None if it is gone."""
    try:
        found = os.stat(path)
    except OSError:
        return None
    return (found.st_size, found.st_mtime_ns, found.st_ctime_ns, found.st_ino)
