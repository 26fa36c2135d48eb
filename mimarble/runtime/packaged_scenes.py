"""The paper's scenes, shipped with the package: found by name, listed, copied out.

The scene files (and the image maps they use) live once in git, in the checkout's
``scenes/``; ``mimarble/scenes`` is a symbolic link to it, which setuptools follows
when it builds a wheel (package data ``scenes/**``), so an installed mimarble holds
real copies in ``site-packages/mimarble/scenes/`` and a checkout reads ``scenes/``
itself (docs/design-decisions.md, "Shipping the paper's scenes").

**The rule for a SCENE argument** (``mimarble render``, ``reference``, ``compare``,
``sweep``, ``gallery``, ``bench``, ``doctor --warm``): a path that exists is that
file, always; otherwise a name without a folder part (``fig11a``, ``fig11a.scene``,
``veins-over-image``) is the packaged scene of that name; otherwise it stays the
path it was, and reading it says what is wrong. Names are the files' stems, unique
across the packaged folder (the §5 scenes sit in ``future-work/``).

Standard library only: the command line resolves names before Dr.Jit loads.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path

from .files import output_name_problem, write_atomically

#: Where the packaged scenes are (the checkout's ``scenes/`` through the link).
FOLDER = (Path(__file__).resolve().parent.parent / "scenes").resolve()
SUFFIX = ".scene"


def _key(path: Path):
    """Paper figures first (the top folder), then each subfolder's, by name."""
    relative = path.relative_to(FOLDER)
    return (len(relative.parts), relative.as_posix())


def paths() -> list[Path]:
    """Every packaged scene file: the paper's figures, then the §5 future-work scenes."""
    if not FOLDER.is_dir():
        return []
    return sorted((p for p in FOLDER.rglob("*" + SUFFIX) if p.is_file()), key=_key)


def figures() -> list[Path]:
    """The paper's figures only (the top folder): what ``./scenes/*.scene`` is in a checkout."""
    return [p for p in paths() if p.parent == FOLDER]


def names() -> dict[str, Path]:
    """Each packaged scene by name (its file's stem), in :func:`paths`'s order."""
    return {p.stem: p for p in paths()}


def _bare(argument: str) -> bool:
    """Whether ``argument`` has no folder part."""
    separators = {"/", os.sep} | ({os.altsep} if os.altsep else set())
    return bool(argument) and not any(s in argument for s in separators)


def find(name: str) -> Path | None:
    """The packaged scene called ``name`` (``fig11a`` or ``fig11a.scene``), else None."""
    name = str(name)
    if not _bare(name):
        return None
    stem = name[:-len(SUFFIX)] if name.endswith(SUFFIX) else name
    return names().get(stem)


def _missing(path: str) -> bool:
    """Whether nothing is at ``path``; a path the system cannot even look up (too long, a
    NUL byte, a loop of links) is not missing: reading it says what is wrong."""
    try:
        os.lstat(path)
    except FileNotFoundError:
        return True
    except (OSError, ValueError):
        return False
    return False


def is_unknown_name(argument) -> bool:
    """A name without a folder part that is neither a file here nor a packaged scene."""
    argument = os.fspath(argument)
    return _bare(argument) and _missing(argument) and find(argument) is None


def resolve(argument) -> str:
    """A SCENE argument as the path to read: an existing path always wins, then a
    packaged scene's name, else the argument itself (see the module's rule)."""
    argument = os.fspath(argument)
    if not _missing(argument):
        return argument
    found = find(argument)
    return str(found) if found is not None else argument


def summary(path: Path, most: int = 78) -> str:
    """The start of a scene file's header comment (its first two lines), shortened to
    ``most`` characters."""
    lines = []
    try:
        with open(path, encoding="utf-8") as f:
            for line in f:
                line = line.strip()
                if not line.startswith("//") or len(lines) == 2:
                    break
                lines.append(line[2:].strip())
    except (OSError, UnicodeDecodeError):
        return ""
    text = " ".join(lines)
    return text if len(text) <= most else text[:most - 1].rstrip() + "…"


def files() -> list[Path]:
    """Every file of the packaged folder a copy takes: scenes, their image maps, the README."""
    if not FOLDER.is_dir():
        return []
    return sorted((p for p in FOLDER.rglob("*")
                   if p.is_file() and "__pycache__" not in p.parts
                   and not any(part.startswith(".") for part in p.relative_to(FOLDER).parts)),
                  key=lambda p: p.relative_to(FOLDER).as_posix())


class CopyRefused(Exception):
    """A copy that would overwrite a file; the message is one sentence."""


def _link_problem(path: Path) -> CopyRefused | None:
    """A refusal if ``path``, a subfolder inside the folder copied into, is a symbolic
    link or not a folder (None: it is a real folder, or nothing is there)."""
    if path.is_symlink():
        return CopyRefused(f"{path}: is a symbolic link (to {os.readlink(path)}); scenes "
                           f"--copy never follows a link inside the folder it copies into, "
                           f"so name a new or empty folder")
    if os.path.lexists(path) and not path.is_dir():
        return CopyRefused(f"{path}: exists and is not a folder; scenes --copy writes only "
                           f"new files, so name a new or empty folder")
    return None


def copy_to(folder) -> list[Path]:
    """Copy every packaged file into ``folder`` (made if missing; its parent must exist),
    keeping the subfolders, so the scenes find their image maps. Refuses, before
    copying anything, to overwrite a file that is there, and to write through a symbolic
    link inside ``folder`` (a subfolder planted there as a link would lead the copy
    outside it): ``folder`` itself is what the user named, and may be one. Each
    subfolder is looked at again (``lstat``) right before a file is written into it.
    Returns the files written."""
    problem = output_name_problem(folder)
    if problem:
        raise CopyRefused(f"{os.fspath(folder)!r}: {problem}")
    folder = Path(folder)
    if folder.is_symlink() and not folder.exists():
        raise CopyRefused(f"{folder}: is a symbolic link to {os.readlink(folder)}, which does "
                          f"not exist; name a folder")
    plan = [(source, folder / source.relative_to(FOLDER)) for source in files()]
    subfolders = sorted({folder / parent for _, target in plan
                         for parent in target.relative_to(folder).parents[:-1]},
                        key=lambda p: len(p.parts))
    for path in subfolders:
        if (problem := _link_problem(path)) is not None:
            raise problem
    for _, target in plan:
        if os.path.lexists(target):
            raise CopyRefused(f"{target}: exists; scenes --copy writes only new files, so "
                              f"name a new or empty folder")
    made = [] if folder.exists() else [folder]
    written = []
    try:
        folder.mkdir(exist_ok=True)
        for source, target in plan:
            for parent in reversed(target.relative_to(folder).parents[:-1]):
                if (problem := _link_problem(folder / parent)) is not None:
                    raise problem            # planted while the copy ran
                if not (folder / parent).exists():
                    (folder / parent).mkdir()
                    made.append(folder / parent)
            # Whole or not at all: a failure (a full disk) leaves no truncated scene.
            write_atomically(target, lambda tmp, source=source: shutil.copyfile(source, tmp))
            written.append(target)
    except BaseException:
        for path in reversed(written):
            path.unlink(missing_ok=True)
        for path in reversed(made):
            with contextlib.suppress(OSError):
                path.rmdir()
        raise
    return written
