"""Where mimarble keeps its files, and how it writes them: whole or not at all.

Every file mimarble writes goes through :func:`write_atomically` — under a temporary
name in the same folder, then renamed — images, the benchmark's and the stress
test's JSON (:func:`write_json`) and cached reference images, a sweep's index and
contact sheet — so an interruption or an error never leaves half a file where a
whole one was or would be.

Files kept between processes (the scene parser's tables, the benchmark's converged
reference images) live in :func:`cache_folder`, the user's own cache folder.

Standard library only: the scene package and the command line read it before
anything heavy is loaded.
"""

from __future__ import annotations

import json
import os
import re
import tempfile
from pathlib import Path

# The process's umask, read once: reading it means setting it, which must not happen
# while another thread (a sweep's image writer) creates files.
_UMASK = os.umask(0)
os.umask(_UMASK)


#: Temporary files are named ``.STEM.mimarble-PID-RANDOM.SUFFIX``: the writing process's
#: id says whether one left behind (the process was killed mid-write) is stale.
_TEMPORARY = re.compile(r"\..*\.mimarble-(\d+)-[^.]*\.?[^.]*$")
_cleaned: set = set()


def write_atomically(path, write) -> None:
    """``write(tmp)`` to a temporary file beside ``path`` (same suffix, so writers that
    choose a format by it choose the same), then rename it to ``path``. The new file gets
    the usual mode (0666 less the umask); on any failure the temporary file is removed,
    and the first write into a folder removes the temporary files that killed processes
    left there (a kill leaves no chance to remove them)."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    _remove_stale_temporaries(folder)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.mimarble-{os.getpid()}-",
                               suffix=path.suffix, dir=folder)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_UMASK)      # mkstemp makes 0600
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def _remove_stale_temporaries(folder: Path) -> None:
    """Remove the temporary files of processes that no longer run, once per folder."""
    key = os.path.abspath(folder)
    if key in _cleaned:
        return
    _cleaned.add(key)
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return
    for entry in entries:
        match = _TEMPORARY.match(entry.name)
        if match and entry.is_file(follow_symlinks=False) and not _running(int(match.group(1))):
            try:
                os.remove(entry.path)
            except OSError:
                pass


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True               # another user's, or not a pid: not ours to remove
    return True


def write_json(data, path) -> None:
    """``data`` as indented JSON, written whole; NumPy numbers are written as floats."""
    text = json.dumps(data, indent=1, default=float)
    write_atomically(path, lambda tmp: Path(tmp).write_text(text))


def cache_folder() -> Path:
    """mimarble's folder in the user's own cache: ``$XDG_CACHE_HOME/mimarble``, by default
    ``~/.cache/mimarble`` (the XDG base directory rule). Not created here: a caller
    creates it when it writes, and copes when it cannot.

    The user's own folder, not a shared temporary one, because what is cached is read
    back and trusted (a pickled parser, reference images): another user must not be
    able to plant it.
    """
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "mimarble"
