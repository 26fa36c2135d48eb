"""Opening the files a user names for reading: regular files only, never blocking; the names
in sentences, shortened.

A FIFO opened for reading waits for a writer, forever if none comes; a device such as
``/dev/zero`` never ends. Scene files and image maps are therefore looked at with
``os.stat`` first and refused unless they are regular files, and then opened
non-blocking and looked at again through the descriptor, so that nothing swapped in
between is read either. Scene files, image maps, mesh files and sweeps' frames are
opened so. Standard library only.
"""

from __future__ import annotations

import errno
import os
import stat

__all__ = ["NotRegularFile", "not_regular", "open_regular", "open_failure", "shortened"]

_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"),
          (stat.S_ISLNK, "a symbolic link, which is not followed"))


class NotRegularFile(OSError):
    """A path that is there but is no regular file (nor a directory); ``str()`` says what
    it is, e.g. ``it is a FIFO (named pipe), not a regular file``."""

    def __str__(self) -> str:
        return self.strerror


def not_regular(mode: int) -> str | None:
    """What a file of ``mode`` is, when it is neither a regular file nor a directory."""
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    kind = next((name for test, name in _KINDS if test(mode)), "a special file")
    return f"it is {kind}, not a regular file"


def _check(mode: int, path) -> None:
    if stat.S_ISDIR(mode):
        raise IsADirectoryError(errno.EISDIR, "Is a directory", os.fspath(path))
    problem = not_regular(mode)
    if problem:
        raise NotRegularFile(errno.EINVAL, problem, os.fspath(path))


def open_regular(path, follow_links: bool = True):
    """``path`` opened for binary reading, when it is a regular file. Raises
    FileNotFoundError, PermissionError, IsADirectoryError, :class:`NotRegularFile`
    (anything else that is not a regular file: refused without being opened) or
    another OSError. ``follow_links=False``: a symbolic link is refused too (in a folder
    of data, such as a sweep's, a link could lead out of it)."""
    _check((os.stat if follow_links else os.lstat)(path).st_mode, path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    if not follow_links:
        flags |= getattr(os, "O_NOFOLLOW", 0)   # a link swapped in since: ELOOP
    fd = os.open(path, flags)            # non-blocking: a FIFO swapped in does not wait
    try:
        _check(os.fstat(fd).st_mode, path)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def open_failure(error: OSError, where: str) -> str:
    """Why a file (shown as ``where``) could not be opened, in a few words: the sentences
    the image maps' and meshes' checks end with."""
    if isinstance(error, FileNotFoundError):
        return f"no such file (looked for {where})"
    if isinstance(error, IsADirectoryError):
        return f"it is a directory ({where})"
    if isinstance(error, PermissionError):
        return f"permission denied ({where})"
    if isinstance(error, NotRegularFile):
        return f"{error} ({where})"
    return f"cannot read it: {error.strerror or error} ({where})"


def shortened(text: str, most: int = 60) -> str:
    """``text``, cut to at most ``most`` characters with ``...`` where it was cut: a
    word or a name quoted in a message (a 4 MB word is not echoed)."""
    text = str(text)
    return text if len(text) <= most else text[:most - 3] + "..."
