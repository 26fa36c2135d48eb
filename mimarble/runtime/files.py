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


def output_name_problem(name) -> str | None:
    """What is wrong with ``name`` as the name of a file or folder to write, in words that
    follow it (``NAME: …``), or None. The one rule of every writer (the command line's
    ``-o``, ``--diff``, ``--copy``, ``--json``…; ``write_image``, ``export``, ``sweep``):

    * empty — a path of no characters means the current folder to the system, so a
      writer would write there, or fall back to a default name the user did not give;
    * a NUL character — no system takes one;
    * not UTF-8 — a name whose bytes are not UTF-8 reaches Python as lone surrogates
      (U+DC80..U+DCFF, PEP 383); Mitsuba's image writers and the exported files' text take
      UTF-8 only, so such a name is refused, in every writer alike, rather than written by
      some (Pillow's JPEG) and not others (Mitsuba's PNG and EXR).
    """
    text = os.fspath(name)
    if isinstance(text, bytes):
        text = os.fsdecode(text)
    if text == "":
        return "an empty name; name the file or folder to write"
    if "\0" in text:
        return "the name holds a NUL character, which no file name can"
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as e:
        bad = text[e.start]
        byte = (f"the byte \\x{ord(bad) - 0xDC00:02x}" if 0xDC80 <= ord(bad) <= 0xDCFF
                else f"U+{ord(bad):04X}")
        return (f"the name is not UTF-8 ({byte} at character {e.start + 1}); mimarble writes "
                f"files under UTF-8 names only: give another")
    return None


def write_atomically(path, write) -> None:
    """``write(tmp)`` to a temporary file beside ``path`` (same suffix, so writers that
    choose a format by it choose the same), then rename it to ``path``. The new file gets
    the usual mode (0666 less the umask); on any failure the temporary file is removed,
    and the first write into a folder removes the temporary files that killed processes
    left there (a kill leaves no chance to remove them). A name refused by
    :func:`output_name_problem` is a ValueError, before anything is made."""
    problem = output_name_problem(path)
    if problem:
        raise ValueError(f"{os.fspath(path)!r}: {problem}")
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
