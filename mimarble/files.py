"""Files written whole or not at all: under a temporary name in the same folder, then renamed.

Every file mimarble writes goes through :func:`write_atomically` — images, the
benchmark's JSON and cached reference images, a sweep's index and contact sheet —
so an interruption or an error never leaves half a file where a whole one was or
would be.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

# The process's umask, read once: reading it means setting it, which must not happen
# while another thread (a sweep's image writer) creates files.
_UMASK = os.umask(0)
os.umask(_UMASK)


def write_atomically(path, write) -> None:
    """``write(tmp)`` to a temporary file beside ``path`` (same suffix, so writers that
    choose a format by it choose the same), then rename it to ``path``. The new file gets
    the usual mode (0666 less the umask); on any failure the temporary file is removed."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix,
                               dir=path.parent if str(path.parent) else ".")
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_UMASK)      # mkstemp makes 0600
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
