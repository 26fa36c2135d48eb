"""A sweep's folder: its index (``sweep.json``, read back and checked for a resumed
sweep), the images it says are done, what a run did, and the lock that keeps a second
sweep out while one writes there.

A sweep folder is data, not instructions: only each frame's status, error, time and
metrics are read back from the index, each checked; a damaged index or entry is said in
one warning and rendered again. Links, pipes and devices in the folder are never
followed or read.
"""

from __future__ import annotations

import contextlib
import json
import os
import warnings
from pathlib import Path

from mimarble.runtime import files
from mimarble.scene.image_header import png_facts
from mimarble.runtime.reading import NotRegularFile, open_regular
from mimarble.sweeps.frames import file_name
from mimarble.sweeps.settings import SweepError


INDEX = "sweep.json"
#: The index is rewritten at most this often while frames come in (and at the end).
INDEX_INTERVAL_S = 0.5


#: An index file larger than this is not one a sweep wrote (MAX_FRAMES entries of
#: MAX_SETTINGS values each stay under 10 MB): it is taken as damaged, not read.
MAX_INDEX_BYTES = 32 * 2**20


#: What makes two sweeps the same sweep (a resumed one must match on each), with the
#: JSON type each has in an index that is not damaged.
_SAME = {"scene_digest": str, "settings": list, "spp": (int, type(None)), "compare": bool,
         "variant": str}
_STATUSES = ("todo", "done", "failed")


def open_index(out_dir: Path, source, scene, settings, spp, compare, all_frames,
                variant) -> dict:
    """The index in ``out_dir``: made, or read back for a resumed sweep of the same kind
    (the same scene — by content, sizes included —, settings, spp, comparison and
    variant; another is refused). Only each frame's status, error, time and metrics are
    read back, each checked; the rest is this sweep's own. A damaged index is said in a
    warning and started afresh; a damaged frame entry, that frame alone."""
    import hashlib
    described = {"scene": str(source) if isinstance(source, (str, os.PathLike))
                 else getattr(source, "source", None) or "<scene>",
                 "scene_digest": hashlib.sha256(repr(scene).encode()).hexdigest()[:16],
                 "settings": [{"key": s.key, "values": list(s.values)} for s in settings],
                 "spp": spp, "compare": compare, "variant": variant}
    settings_list = list(settings)
    index = dict(described, frames=[
        {"index": f["index"], "values": f["values"], "file": file_name(f, settings_list),
         "status": "todo", "error": None, "render_s": None} for f in all_frames])
    path = out_dir / INDEX
    stored, problem = _read_index(path)
    if stored is _NO_INDEX:
        stored = None
    elif problem is None:
        problem = _header_problem(stored)
        if problem is None and {k: stored[k] for k in _SAME} != {k: described[k] for k in _SAME}:
            raise SweepError(f"{out_dir} holds another sweep ({path}: another scene, size, "
                             f"setting, spp or variant); write this one elsewhere")
        if problem is None and not isinstance(stored.get("frames"), list):
            problem = "it has no list of frames"
        elif problem is None and len(stored["frames"]) != len(all_frames):
            problem = f"it lists {len(stored['frames'])} frames, not {len(all_frames)}"
    if problem is not None:
        warnings.warn(f"{path}: the sweep index is damaged ({problem}); starting it afresh: "
                      f"every frame is rendered again", stacklevel=3)
    elif stored is not None:
        damaged = []
        for entry, kept in zip(index["frames"], stored["frames"]):
            entry_problem = _entry_problem(kept, entry, compare)
            if entry_problem is not None:
                damaged.append((entry["index"], entry_problem))
                continue
            entry.update({k: kept[k] for k in ("status", "error", "render_s")})
            entry.update({k: kept[k] for k in ("rmse", "psnr") if k in kept})
            if entry["status"] == "todo":
                entry["error"] = None
        if damaged:
            n, (first, why) = len(damaged), damaged[0]
            warnings.warn(f"{path}: {counted(n, 'frame entry', 'frame entries')} of the sweep "
                          f"index {'is' if n == 1 else 'are'} damaged (frame {first}: {why}); "
                          f"rendering {pronoun_for(n)} again", stacklevel=3)
    write_index(out_dir, index)
    return index


_NO_INDEX = object()


def _read_index(path: Path):
    """(the JSON in ``path``, None), (_NO_INDEX, None) if there is none, or (None, why it
    is not an index). Read only as a regular file in the folder, of at most
    MAX_INDEX_BYTES."""
    try:
        with open_regular(path, follow_links=False) as f:
            data = f.read(MAX_INDEX_BYTES + 1)
    except FileNotFoundError:
        return _NO_INDEX, None
    except IsADirectoryError:
        raise SweepError(f"{path}: is a folder, where the sweep's index goes; move it "
                         f"away") from None
    except OSError as e:
        return None, _unreadable(e)
    if len(data) > MAX_INDEX_BYTES:
        return None, f"larger than {MAX_INDEX_BYTES // 2**20} MiB, more than any sweep's index"
    try:
        return json.loads(data), None
    except UnicodeDecodeError:
        return None, "it is not text"
    except json.JSONDecodeError as e:
        return None, f"not JSON: {e.msg} at line {e.lineno} column {e.colno}"
    except (ValueError, RecursionError):   # nested deeper than json reads
        return None, "not JSON that can be read (nested too deep)"


def _header_problem(stored) -> str | None:
    """Why ``stored`` does not begin as an index does (None: it does)."""
    if not isinstance(stored, dict):
        return f"it holds a JSON {_json_type(stored)}, not an object"
    for key, kind in _SAME.items():
        if key not in stored:
            return f"it has no {key!r}"
        value = stored[key]
        if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
            return f"its {key!r} is a JSON {_json_type(value)}"
    return None


def _entry_problem(stored, entry: dict, compare: bool) -> str | None:
    """Why a frame's entry read back is damaged (None: it is not)."""
    if not isinstance(stored, dict):
        return f"a JSON {_json_type(stored)}, not an object"
    for key in ("index", "values", "status", "error", "render_s"):
        if key not in stored:
            return f"no {key!r}"
    if not _is_int(stored["index"]) or stored["index"] != entry["index"]:
        return f"its index is not {entry['index']}"
    if stored["values"] != entry["values"]:
        return "its values are not the frame's"
    if stored["status"] not in _STATUSES:
        return f"its status is not one of {', '.join(_STATUSES)}"
    if not (stored["error"] is None or isinstance(stored["error"], str)):
        return "its error is not text"
    if not (stored["render_s"] is None or _is_number(stored["render_s"])):
        return "its render time is not a number"
    for key in ("rmse", "psnr"):
        if (key in stored and not _is_number(stored[key])) or \
                (compare and stored["status"] == "done" and key not in stored):
            return f"its {key} is missing or not a number"
    return None


def frames_to_do(all_frames, index, out_dir: Path, names) -> list:
    """The frames not done: those the index does not say are, and those it says are whose
    image is not usable (:func:`image_problem`, from the header: cheap), said in a warning."""
    todo, damaged = [], []
    for frame in all_frames:
        entry = index["frames"][frame["index"]]
        if entry["status"] == "done":
            problem = image_problem(out_dir / names[frame["index"]], image_size(frame["scene"]))
            if problem is None:
                continue
            damaged.append((names[frame["index"]], problem))
            for key in ("rmse", "psnr"):
                entry.pop(key, None)
            entry.update(status="todo", error=None, render_s=None)
        todo.append(frame)
    if damaged:
        n, (name, why) = len(damaged), damaged[0]
        warnings.warn(f"{out_dir}: {counted(n, 'done frame')} {'has' if n == 1 else 'have'} no "
                      f"usable image ({name}: {why}{', …' if n > 1 else ''}); rendering "
                      f"{pronoun_for(n)} again", stacklevel=3)
    return todo


def image_problem(path, size=None) -> str | None:
    """Why ``path`` is not a usable frame image (None: it is), read from its first and
    last bytes only: it must be a regular file (not a link, pipe or device), a PNG of
    ``size`` (width, height) if given, and end with the PNG end chunk (not truncated).
    What this cannot see (damage inside the compressed pixels) the contact sheet finds."""
    try:
        with open_regular(path, follow_links=False) as f:
            facts = png_facts(f)
    except FileNotFoundError:
        return "missing"
    except IsADirectoryError:
        return "a folder"
    except OSError as e:
        return _unreadable(e)
    if facts is None:
        return "not a PNG"
    width, height, complete = facts
    if size is not None and (width, height) != tuple(size):
        return f"{width}×{height} pixels, not {size[0]}×{size[1]}"
    return None if complete else "truncated"


def _unreadable(error: OSError) -> str:
    import errno
    if isinstance(error, NotRegularFile):
        return f"{error}"
    if error.errno == errno.ELOOP:
        return "a symbolic link, which is not followed"
    return f"cannot be read ({error.strerror or error})"


def write_index(out_dir: Path, index: dict, rendered=()) -> None:
    """``sweep.json``, whole, with this run's :func:`summary` so far (``rendered``: the
    frames this run has rendered)."""
    index["summary"] = summary(index, rendered)
    try:
        files.write_json(index, out_dir / INDEX)
    except OSError as e:                 # disk full, no permission: the sweep cannot keep count
        raise SweepError(f"{out_dir / INDEX}: cannot write the sweep's index "
                         f"({e.strerror or e})") from None


def summary(index: dict, rendered=()) -> dict:
    """What a run of the sweep did: {"frames", "already_done" (done before it, kept),
    "rendered_now" (done by it), "failed" (their last try failed), "left" (not tried)}.
    ``rendered``: the indices of the frames this run rendered."""
    statuses = [entry["status"] for entry in index["frames"]]
    now = sum(1 for k in set(rendered) if statuses[k] == "done")
    return {"frames": len(statuses), "already_done": statuses.count("done") - now,
            "rendered_now": now, "failed": statuses.count("failed"),
            "left": statuses.count("todo")}


def summary_sentence(index: dict) -> str:
    """``16 frames: 14 already done, 2 rendered now, 0 failed`` (``, 3 left`` if any)."""
    s = index.get("summary") or summary(index)
    return (f"{counted(s['frames'], 'frame')}: {s['already_done']} already done, "
            f"{s['rendered_now']} rendered now, {s['failed']} failed"
            + (f", {s['left']} left" if s["left"] else ""))


def image_size(scene) -> tuple[int, int]:
    """(width, height) of the scene's image."""
    return scene.image.width, scene.image.height


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _json_type(value) -> str:
    return {dict: "object", list: "array", str: "string", bool: "boolean", int: "number",
            float: "number", type(None): "null"}.get(type(value), type(value).__name__)


def counted(n: int, one: str, many: str | None = None) -> str:
    """``n`` and the noun: ``one`` for 1, else ``many`` (default ``one`` + "s")."""
    return f"{n} {one if n == 1 else many or one + 's'}"


def pronoun_for(n: int) -> str:
    """"it" for one thing, "them" for any other count."""
    return "it" if n == 1 else "them"


#: The lock file in a sweep's folder while a sweep writes there: held (``flock``), holding
#: its process id for the message a second sweep gets.
LOCK = ".sweep.lock"


class FolderLock:
    """An exclusive ``flock`` on :data:`LOCK` in the sweep's folder, taken without waiting
    (a second sweep into the folder is refused in one sentence while the first runs) and
    released when the block is left, the file removed then. The system drops the lock when
    the process ends, by a kill too, so a lock file a killed sweep left blocks nothing. The
    file is opened without following a link (a sweep folder is data). A lock taken on a
    file that its holder removed meanwhile is no lock (a third sweep could make a new one):
    the file locked must still be the one at the name, else it is taken again. Where
    ``fcntl`` does not exist (Windows), sweeps are not locked."""

    def __init__(self, folder: Path):
        self.path = Path(folder) / LOCK
        self.fd = None

    def __enter__(self):
        try:
            import fcntl
        except ImportError:
            return self
        for _ in range(100):             # each retry: a holder removed the file as we took it
            fd = self._open()
            try:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
                    who = f"process {holder}" if holder.isdigit() else "another process"
                    raise SweepError(f"{self.path.parent}: another sweep ({who}) is writing "
                                     f"into this folder; wait for it to end, or write this "
                                     f"one elsewhere") from None
                if self._still_named(fd):
                    os.ftruncate(fd, 0)
                    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
                    self.fd = fd
                    return self
            except BaseException:
                os.close(fd)
                raise
            os.close(fd)
        raise SweepError(f"{self.path}: cannot lock the sweep's folder (its lock file keeps "
                         f"being replaced)")

    def _open(self) -> int:
        import stat
        flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | \
            getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
        try:
            fd = os.open(self.path, flags, 0o666)
        except OSError as e:
            raise SweepError(f"{self.path}: cannot lock the sweep's folder "
                             f"({_unreadable(e)})") from None
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            os.close(fd)
            raise SweepError(f"{self.path}: is not a regular file, where the sweep's lock "
                             f"goes; move it away")
        return fd

    def _still_named(self, fd: int) -> bool:
        """Whether the file open as ``fd`` is the one at the lock's name."""
        held = os.fstat(fd)
        try:
            named = os.lstat(self.path)
        except FileNotFoundError:
            return False
        return (held.st_dev, held.st_ino) == (named.st_dev, named.st_ino)

    def __exit__(self, *exc):
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.unlink(self.path)     # while still held: no sweep takes it meanwhile
            os.close(self.fd)            # closing the file releases the lock
            self.fd = None
        return False
