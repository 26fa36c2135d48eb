"""Sweeps: one scene, some parameters varied, one image per combination.

    mimarble sweep scenes/fig11a.scene --set marble.period=0.5,1,2,4 \\
                   --set marble.distortion=1:8:4 -o out/
    mimarble.sweep("scenes/fig11a.scene", {"marble.period": [0.5, 1, 2, 4]}, "out/")

A setting is ``KEY=v1,v2,…`` or ``KEY=start:stop:count`` (``count`` values from
``start`` to ``stop``, both included). A key is a key path of the scene
(:func:`mimarble.scene.edits.with_value`): ``marble.K``, ``MATERIAL.K`` or
``MATERIAL.CHANNEL.K`` for K a sweepable marble parameter
(``marble_parameters.SWEEPABLE``), ``camera.fov``, ``image.samples`` or
``light.N.intensity``.

Frames are the combinations of all settings (the last varies fastest). Every frame's
scene is made before the first render, so a bad key or value (checked by the marble's
parameter table) is an error before any work.

**One compile per structure.** Frames are rendered through the loaded scenes kept by
structure (mimarble/mitsuba/rendering/loaded_scenes.py) — so frames that differ only in
``scale``, ``period`` or ``distortion`` reuse one scene: the new values go in through
``mi.traverse`` (they are opaque: the compiled kernels and the recorded passes are
replayed). Another structure (octaves, function, …) loads and compiles once.

**Nothing lost.** ``sweep.json`` in the output folder lists every frame with its
values, file, status, error and render time; it is rewritten whole (temporary
file, rename) at most every half second and when the sweep ends or is interrupted;
images are written whole or not at all, and a frame is done once its image is written
and indexed. Run the same sweep again (same scene, sizes, settings, spp, variant) and
only what is missing is done (failed frames are tried again); a frame that fails —
rendering, writing, or its Dask worker lost — is recorded with its error and the sweep
goes on. The index's ``summary`` says what this run did (:func:`summary`: frames already
done, rendered now, failed, left), as the command's last line does.

**Several processes, several machines** on Dask distributed: ``workers=N`` starts a
``LocalCluster`` of N single-threaded worker processes (:func:`local_cluster`),
``scheduler=ADDRESS`` joins a running one. Each worker imports mimarble once, as it
starts, and keeps its loaded scenes and compiled kernels between frames
(:func:`render_frame`); images come back to this process, which writes them, so no
shared file system is needed. Starting a LocalCluster costs seconds and one process
already uses every core: on 2 cores ``workers`` was slower at every size measured
(docs/benchmarks.md, "Sweeps"). Ctrl-C stops the workers with the sweep: they never
see it themselves, and it is raised here only between Dask's calls (:class:`_Interrupts`).

**One sweep at a time in a folder.** A sweep holds a lock on its folder while it runs
(:class:`_FolderLock`, an ``flock`` the system drops when the process ends, by a kill
too): a second sweep into it is refused in one sentence before it reads or writes there.

**A sweep folder is data, not instructions.** A frame's image is always named by
:func:`file_name` from its index and values inside the output folder; the ``file`` field
of the index is written for readers and never read back. A damaged index (not JSON, the
wrong shape, a frame with a missing key or a wrong type) is said in one warning and
started afresh (a damaged frame entry: that frame alone is rendered again); a done
frame whose image is missing, not a regular file, not a PNG of the frame's size or
truncated is rendered again, and so is one that does not decode in the contact sheet.
Links, pipes and devices in the folder are never followed or read.

**Limits** (stated once, below, with why): :data:`MAX_FRAMES` frames and
:data:`MAX_SETTINGS` settings per sweep (checked before a frame or a range's values
are made), :data:`WORKERS_PER_CORE` LocalCluster workers per core, a scheduler's answer
within :data:`SCHEDULER_TIMEOUT_S`, an index of :data:`MAX_INDEX_BYTES`, a contact sheet
of ``contact_sheet.CONTACT_SHEET_PIXELS``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import json
import math
import os
import re
import time
import warnings
from pathlib import Path

import numpy as np

from mimarble.runtime import files, packaged_scenes
from mimarble import scene as scene_language
from .contact_sheet import draw_contact_sheet
from mimarble.scene.image_header import check_image_maps, png_facts
from mimarble.scene.python_numbers import plain_number, plain_numbers
from mimarble.scene.rules import number_problem, shortened, spp_problem
from mimarble.scene.reading import NotRegularFile, open_regular
from mimarble.scene.edits import KeyPathError, with_value

INDEX = "sweep.json"
#: The index is rewritten at most this often while frames come in (and at the end).
INDEX_INTERVAL_S = 0.5
CONTACT_SHEET = "contact.png"

#: Frames of one sweep at most (the product of the settings' value counts), checked
#: before any frame, or a range's values, is made. A sweep is a figure or a study: every
#: frame's scene is built and checked before the first render (10 000: 0.6 s), the
#: index — an entry a frame — is rewritten whole every INDEX_INTERVAL_S (10 000 entries:
#: ~2.6 MB), and the contact sheet holds every frame (its cells shrink past ~1 700).
#: 10 000 is a 100 × 100 grid, minutes at the README's 160²; more is several sweeps.
MAX_FRAMES = 10_000
#: Settings (``--set`` options) of one sweep at most: each is a value in every index
#: entry and a caption line in every contact-sheet cell; 16 settings of two values
#: each would already be 65 536 frames.
MAX_SETTINGS = 16
#: LocalCluster workers per core of this machine at most. Each worker is a process with
#: Mitsuba and Dr.Jit loaded (~160 MB before its first frame), and the frames already
#: use every core (Dr.Jit's threads are shared out among the workers), so more workers
#: add memory, not speed; 4 per core leaves room for one worker's Python work
#: (translating a scene, encoding a PNG) to overlap another's render.
WORKERS_PER_CORE = 4
#: A Dask scheduler must accept the connection, answer Dask's handshake and say it is a
#: scheduler within this (seconds). Dask's own connect timeout does not cover the
#: handshake: a server that accepts and says nothing would keep the sweep waiting forever.
SCHEDULER_TIMEOUT_S = 10
#: An index file larger than this is not one a sweep wrote (MAX_FRAMES entries of
#: MAX_SETTINGS values each stay under 10 MB): it is taken as damaged, not read.
MAX_INDEX_BYTES = 32 * 2**20


class SweepError(ValueError):
    """A sweep that cannot be run as asked (a bad setting, another sweep's folder)."""


# ---------------------------------------------------------------------------
# Settings

@dataclasses.dataclass(frozen=True)
class Setting:
    """One varied parameter: its key and its values, in order."""

    key: str
    values: tuple

    @property
    def name(self) -> str:
        """The last part of the key (``period``), for labels and file names."""
        return self.key.rsplit(".", 1)[-1]


def parse_setting(text: str) -> Setting:
    """``KEY=v1,v2,…`` or ``KEY=start:stop:count`` → a :class:`Setting`."""
    key, sep, values = text.partition("=")
    key, values = key.strip(), values.strip()
    if not sep or not key or not values:
        raise SweepError(f"--set {text!r}: write KEY=v1,v2,… or KEY=start:stop:count")
    if ":" in values:
        parts = values.split(":")
        try:
            start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
        except (ValueError, IndexError):
            raise SweepError(f"--set {text!r}: a range is start:stop:count, e.g. 1:8:4") from None
        if len(parts) != 3 or count < 1:
            raise SweepError(f"--set {text!r}: a range is start:stop:count with count ≥ 1")
        if count > MAX_FRAMES:           # before np.linspace allocates them
            raise SweepError(f"--set {text!r}: {count} values; a sweep renders at most "
                             f"{MAX_FRAMES} frames")
        return Setting(key, tuple(float(v) for v in np.linspace(start, stop, count)))
    return Setting(key, tuple(_value(v.strip()) for v in values.split(",")))


def _value(text: str):
    """A number if it is one (int when integral and written so), else the word."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        return text
    return value


#: How a sweep's settings are given, for the sentence that refuses another form.
SETTINGS_FORMS = ("a mapping {key: values} (e.g. {'marble.period': [0.5, 1, 2]}), or "
                  "--set strings ('marble.period=0.5,1,2', one or a list of them)")


def settings_from(spec) -> tuple[Setting, ...]:
    """Settings from ``--set`` strings (one string is one setting), or a mapping
    {key: values} (Python); values are numbers (NumPy's too, as the Python numbers they
    hold: mimarble/scene/python_numbers.py) or words. Any other form is a SweepError."""
    if isinstance(spec, str):
        spec = (spec,)
    if isinstance(spec, dict):
        for key, values in spec.items():
            if not isinstance(key, str):
                raise SweepError(f"setting key {shortened(repr(key), 40)} is not a string: a "
                                 f"key is a key path, e.g. 'marble.period'")
            count = (values.size if isinstance(values, np.ndarray) else
                     len(values) if isinstance(values, (list, tuple, range)) else 1)
            if count > MAX_FRAMES:       # before a range or an array is made into a list
                raise SweepError(f"--set {key}: {count} values; a sweep renders at most "
                                 f"{MAX_FRAMES} frames")
        # NumPy values (np.linspace, np.arange, np.float32(…) in a list) become Python ones:
        # JSON and the checks take them.
        return tuple(Setting(k, tuple(plain_number(x) for x in (
            np.asarray(v, dtype=object).ravel().tolist()
            if isinstance(v, (list, tuple, range, np.ndarray)) else [v])))
            for k, v in spec.items())
    if not isinstance(spec, (list, tuple)):
        raise SweepError(f"settings {shortened(repr(spec), 40)}: give {SETTINGS_FORMS}")
    for item in spec:
        if not isinstance(item, (str, Setting)):
            raise SweepError(f"setting {shortened(repr(item), 40)}: give {SETTINGS_FORMS}")
    return tuple(parse_setting(s) if isinstance(s, str) else s for s in spec)


def frame_count(settings) -> int:
    """How many frames ``settings`` make, refused (SweepError) past :data:`MAX_FRAMES` or
    :data:`MAX_SETTINGS`, with no value or with a key given twice — before any is made."""
    if len(settings) > MAX_SETTINGS:
        raise SweepError(f"{len(settings)} settings; a sweep takes at most {MAX_SETTINGS}")
    keys = [s.key for s in settings]
    for setting in settings:
        if not setting.values:
            raise SweepError(f"--set {setting.key}: no values")
        if keys.count(setting.key) > 1:
            raise SweepError(f"--set {setting.key}: given twice; give it once with every value")
    count = math.prod(len(s.values) for s in settings)
    if count > MAX_FRAMES:
        raise SweepError(f"{count} frames ({' × '.join(str(len(s.values)) for s in settings)} "
                         f"values); a sweep renders at most {MAX_FRAMES}: split it into "
                         f"several sweeps")
    return count


def frames(scene, settings) -> list[dict]:
    """Every combination: [{"index", "values": {key: value}, "scene"}] (last setting fastest).
    Each frame's scene is built here, so a bad key or value fails before any render
    (SweepError ``--set KEY: …``), and their number is checked first (:func:`frame_count`)."""
    frame_count(settings)
    for setting in settings:             # every number of a scene: as the parser reads one
        for value in setting.values:
            problem = _number_problem(value)
            if problem:
                raise SweepError(f"--set {setting.key}: {problem}")
    out = []
    for index, combination in enumerate(itertools.product(*(s.values for s in settings))):
        frame_scene = scene
        for setting, value in zip(settings, combination):
            try:
                frame_scene = with_value(frame_scene, setting.key, value)
            except KeyPathError as e:
                raise SweepError(f"--set {e}") from None
        out.append({"index": index, "values": dict(zip((s.key for s in settings), combination)),
                    "scene": frame_scene})
    return out


def _number_problem(value) -> str | None:
    """The scene language's rule for any number (scene/rules.py ``number_problem``: finite,
    within float32's range, as the renderers are single precision), said as the parser
    says it of a number in a file; None for a value that is no number (a word)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        problem = number_problem(float(value))
    except OverflowError:                # an int past any double
        problem = "is too large"
    return None if problem is None else f"number {shortened(repr(value), 40)} {problem}"


def file_name(frame, settings) -> str:
    """``0007_period-2_distortion-3.5.png``: the index, then each value."""
    parts = [f"{frame['index']:04d}"]
    for setting in settings:
        value = frame["values"][setting.key]
        text = f"{value:g}" if isinstance(value, float) else str(value)
        parts.append(re.sub(r"[^A-Za-z0-9.+-]", "_", f"{setting.name}-{text}"))
    return "_".join(parts) + ".png"


# ---------------------------------------------------------------------------
# Rendering one frame (in this process, or in a Dask worker)

def render_frame(job: dict) -> dict:
    """Render one frame: {"index", "scene", "spp", "compare", "variant", "threads",
    "encode"} → {"index", "image" (linear, or 8-bit sRGB with "encode"), "render_s",
    "error", metrics}. Runs where it is called — in a Dask worker too, which
    keeps its loaded scenes (and their compiled kernels) between frames."""
    out = {"index": job["index"], "image": None, "error": None, "render_s": None}
    try:
        import mimarble
        if job.get("variant"):
            mimarble.use_variant(job["variant"])          # a worker renders as the client does
        mimarble.start()
        if job.get("threads"):                            # a LocalCluster's share of the cores
            mimarble.dr.set_thread_count(job["threads"])
        from mimarble.tools.compare import image_metrics
        from mimarble.mitsuba.rendering.image_output import srgb8
        from mimarble.mitsuba.rendering.loaded_scenes import LOADED
        from mimarble.mitsuba.rendering.render import render_in_passes
        frame_scene = job["scene"]
        spp = job["spp"] or frame_scene.image.samples
        start = time.perf_counter()
        mitsuba_scene = LOADED.scene_of(frame_scene, spp=spp)
        image = render_in_passes(mitsuba_scene, spp)
        out["render_s"] = time.perf_counter() - start
        if job.get("compare"):
            from mimarble import reference
            metrics = image_metrics(image, reference.render(frame_scene, spp=spp))
            out.update(rmse=metrics["rmse"], psnr=metrics["psnr"])
        # On Dask, 8-bit sRGB where the frame was rendered (in parallel, and a quarter of
        # the bytes to send back); here, the writer thread converts it: the same bits.
        out["image"] = srgb8(image) if job.get("encode") else image
    except Exception as e:   # recorded in the index; the sweep goes on
        out["error"] = error_text(e)
    return out


def error_text(error: Exception) -> str:
    """One line for the index: the last line of a plugin error Mitsuba wrapped (its message
    carries the Python traceback of the plugin's constructor), else the error itself."""
    lines = [line for line in str(error).strip().splitlines() if line.strip()]
    return lines[-1].strip() if len(lines) > 1 else f"{type(error).__name__}: {error}"


# ---------------------------------------------------------------------------
# The sweep

def sweep(scene_or_path, settings, out_dir, spp: int | None = None, workers: int | None = None,
          scheduler: str | None = None, compare: bool = False, progress=False,
          contact_sheet: bool = True, stop_after: int | None = None,
          worker_threads: int | None = None) -> dict:
    """Render every combination of ``settings`` into ``out_dir``; returns the index.

    ``scene_or_path``: a scene model, a scene file's path or, when no such file exists, a
    packaged scene's name (``"fig11a"``, as ``render`` takes it). ``settings``:
    ``--set``-style strings (one string is one setting), or {key: values}; every number
    in them is checked by the scene language's rule for numbers before any frame.
    ``workers`` / ``scheduler``: Dask (see the module docstring); neither: this process.
    ``compare``: each frame's RMSE and PSNR against the reference tracer. ``stop_after``:
    a whole number ≥ 0, stop after that many frames (what an interruption does; the index
    says what is left). NumPy's numbers are the Python numbers they hold
    (mimarble/scene/python_numbers.py). Already done frames of the same sweep in
    ``out_dir`` are kept, not rendered again; a damaged index or image there is said in a
    warning and rendered again; a folder another sweep is writing into is refused
    (:class:`_FolderLock`). ``worker_threads``: Dr.Jit threads per Dask worker (default: a
    LocalCluster's share of this machine's cores; a scheduler's workers keep their own).
    Every limit (module docstring) and the folder's name (``files.output_name_problem``)
    are checked before anything is written.
    """
    import mimarble
    from mimarble.runtime.progress import report
    spp, stop_after, workers, worker_threads = plain_numbers(spp, stop_after, workers,
                                                             worker_threads)
    problem = files.output_name_problem(out_dir) if isinstance(out_dir, (str, bytes,
                                                                          os.PathLike)) \
        else f"the sweep's folder must be a path, not {type(out_dir).__name__}"
    if problem:
        raise SweepError(f"{shortened(repr(out_dir), 60)}: {problem}")
    if stop_after is not None and (isinstance(stop_after, bool) or not isinstance(stop_after, int)
                                   or stop_after < 0):
        raise SweepError(f"stop_after={shortened(repr(stop_after), 40)} must be a whole number "
                         f"≥ 0 (the frames to render before stopping), or None")
    scene = scene_or_path
    if isinstance(scene_or_path, (str, os.PathLike)):   # a file, else a packaged scene's name
        scene_or_path = packaged_scenes.resolve(scene_or_path)
        scene = scene_language.load(scene_or_path)
    elif not isinstance(scene_or_path, scene_language.Scene):
        raise TypeError(f"sweep: {shortened(repr(scene_or_path), 80)} is not a scene: give a "
                        f"scene file's path, a packaged scene's name or a mimarble.scene.Scene")
    settings = settings_from(settings)
    if not settings:
        raise SweepError("a sweep needs at least one setting (--set KEY=VALUES)")
    if spp is not None and any(s.key == "image.samples" for s in settings):
        raise SweepError("image.samples is swept: leave out --spp (it would override it)")
    all_frames = frames(scene, settings)
    if spp is None:                      # whitted renders an n×n grid: check every frame now
        for frame in all_frames:
            try:
                scene_language.model.samples_per_axis(frame["scene"].image.samples)
            except ValueError as e:
                raise SweepError(f"the scene's samples: {e}; give --spp") from None
    else:                                # the sample limit, before anything is written
        width, height = _size(scene)
        problem = spp_problem(spp, width, height)
        if problem:
            raise SweepError(problem)
        try:
            scene_language.model.samples_per_axis(spp)
        except ValueError as e:
            raise SweepError(str(e)) from None
    check_image_maps(scene)              # built in Python: the parser never read its maps
    if workers is not None:
        check_workers(workers)
    if scheduler is not None:
        check_scheduler(scheduler)
    out_dir = Path(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:                 # a file there, a name too long, no permission
        raise SweepError(f"{out_dir}: cannot make the sweep's folder "
                         f"({e.strerror or e})") from None
    # One sweep at a time in a folder: a second one is refused while this one runs
    # (_FolderLock: the lock dies with the process, so a killed sweep leaves none).
    with _FolderLock(out_dir):
        mimarble.start()
        variant = mimarble.mi.variant()
        index = _open_index(out_dir, scene_or_path, scene, settings, spp, compare, all_frames,
                            variant)
        # The only names ever written or read in the folder: derived, never taken from the index.
        names = [file_name(f, settings) for f in all_frames]
        todo = _todo(all_frames, index, out_dir, names)
        finished = len(all_frames) - len(todo)
        if stop_after is not None:
            todo = todo[:stop_after]
        done = report(progress, "sweep", unit="frame")
        done(finished, len(all_frames))
        rendered = set()                     # the frames this run rendered (for the summary)

        def one_more():
            nonlocal finished
            finished += 1
            done(finished, len(all_frames))
        # A LocalCluster's workers share this machine's cores (Dr.Jit would start a thread per
        # core in each); a remote scheduler's workers keep their own machines' defaults.
        threads = worker_threads or (max(1, (os.cpu_count() or 1) // int(workers))
                                     if workers and not scheduler else None)
        options = {"spp": spp, "compare": compare, "variant": variant, "threads": threads,
                   "encode": bool(workers or scheduler)}
        _render(todo, options, index, out_dir, names, workers, scheduler, one_more, rendered)
        # An image that passed its header check but does not decode is found by the contact
        # sheet: it is rendered again once, and the sheet drawn again.
        for attempt in range(2):
            if not (contact_sheet and any(e["status"] == "done" for e in index["frames"])
                    and all(e["status"] != "todo" for e in index["frames"])):
                break
            was_done = [k for k, e in enumerate(index["frames"]) if e["status"] == "done"]
            try:
                write_contact_sheet(out_dir, index, size=_size(scene))
            except OSError as e:             # the frames are there; only their overview is not
                warnings.warn(f"{out_dir / CONTACT_SHEET}: cannot write the contact sheet "
                              f"({e.strerror or e})", stacklevel=2)
            undecodable = [k for k in was_done if index["frames"][k]["status"] != "done"]
            if not undecodable:
                break
            _write_index(out_dir, index, rendered)
            if attempt == 0:
                warnings.warn(f"{out_dir}: {_count(len(undecodable), 'frame image')} did not "
                              f"decode ({names[undecodable[0]]}"
                              f"{', …' if len(undecodable) > 1 else ''}); rendering "
                              f"{_them(len(undecodable))} again", stacklevel=2)
                _render([all_frames[k] for k in undecodable], options, index, out_dir, names,
                        workers, scheduler, lambda: None, rendered)
        return index


def check_workers(workers) -> int:
    """``workers``, if a LocalCluster of that many can be started here: an integer from 1
    to :data:`WORKERS_PER_CORE` × this machine's cores (SweepError otherwise)."""
    cores = os.cpu_count() or 1
    most = WORKERS_PER_CORE * cores
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise SweepError(f"--workers {workers!r}: must be a whole number, at least 1")
    if workers > most:
        raise SweepError(f"--workers {workers}: at most {most} here ({WORKERS_PER_CORE} per "
                         f"core, {cores} cores): each worker is a process with Mitsuba "
                         f"loaded, and the frames already share every core")
    return int(workers)


def check_scheduler(address) -> None:
    """Refuse ``address`` (SweepError, one sentence) unless a Dask scheduler answers there
    within :data:`SCHEDULER_TIMEOUT_S`: connected to, it must answer Dask's handshake and
    say it is a scheduler. Something else listening there (a web server, a Dask worker)
    is told apart from nothing listening."""
    import asyncio
    import gc
    import logging
    try:
        from distributed.comm import connect
        from distributed.comm.addressing import parse_address
        from distributed.comm.registry import get_backend
        from distributed.security import Security
    except ImportError:
        raise SweepError("--scheduler needs Dask distributed: pip install "
                         "'dask[distributed]'") from None
    if not isinstance(address, str):
        raise SweepError(f"--scheduler {address!r}: give an address, e.g. tcp://host:8786")
    try:
        get_backend(parse_address(address)[0])
    except ValueError as e:
        raise SweepError(f"--scheduler {address}: not an address Dask knows ({e})") from None

    async def identity():             # with the client's security (tls://), as Client connects
        comm = await connect(address, timeout=SCHEDULER_TIMEOUT_S,
                             **Security().get_connection_args("client"))
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    # What Dask logs of a garbled answer (a traceback at CRITICAL) is not for the user:
    # the sentence below says it.
    logger = logging.getLogger("distributed")
    level = logger.level
    logger.setLevel(logging.CRITICAL + 1)
    # On a thread of its own, with its own event loop: the caller may be running one (Jupyter).
    from concurrent.futures import ThreadPoolExecutor
    try:
        with ThreadPoolExecutor(max_workers=1) as thread:
            answer = thread.submit(asyncio.run, asyncio.wait_for(
                identity(), SCHEDULER_TIMEOUT_S + 2)).result()
    except (TimeoutError, asyncio.TimeoutError):
        raise SweepError(f"--scheduler {address}: no Dask scheduler answered there within "
                         f"{SCHEDULER_TIMEOUT_S} s (something accepted the connection and "
                         f"said nothing Dask understands)") from None
    except OSError as e:                 # refused, unreachable, closed: Dask's own timeout
        raise SweepError(f"cannot start or reach the scheduler at {address}: {e}") from None
    except Exception:                    # bytes that are not Dask's ("Unable to allocate 3 EiB")
        answer = None
    finally:
        gc.collect()                     # its unclosed streams are logged when collected
        logger.setLevel(level)
    if not (isinstance(answer, dict) and answer.get("type") == "Scheduler"):
        what = (f"a Dask {answer['type'].lower()}" if isinstance(answer, dict)
                and isinstance(answer.get("type"), str) and len(answer["type"]) < 40
                else "something that is not Dask")
        raise SweepError(f"--scheduler {address}: is not a Dask scheduler ({what} answered "
                         f"there); give a running scheduler's address, e.g. tcp://host:8786")


def _render(todo, options, index, out_dir: Path, names, workers, scheduler, one_more,
            rendered: set) -> None:
    """Render the frames ``todo`` and write their images, recording each in ``index``
    (and in ``rendered``, the indices of the frames done by this run)."""
    jobs = [dict(options, index=f["index"], scene=f["scene"]) for f in todo]
    # Images are written by one background thread while the next frames render (PNG
    # encoding takes a sixth of a 256² frame's time); the index, rewritten whole, at most
    # every INDEX_INTERVAL_S and at the end — a frame whose image is written but not yet
    # indexed is simply rendered again on resume.
    from concurrent.futures import ThreadPoolExecutor
    last_index = time.perf_counter()
    pending = []
    with ThreadPoolExecutor(max_workers=1) as writer, \
            contextlib.closing(_results(jobs, workers, scheduler)) as results:
        try:
            for result in results:
                entry = index["frames"][result["index"]]
                if result["error"] is None:
                    pending.append((entry, result, writer.submit(
                        _write_frame, out_dir / names[result["index"]], result["image"])))
                else:
                    entry.update(status="failed", error=result["error"],
                                 render_s=result["render_s"])
                one_more()
                pending = _record_written(pending, rendered)
                if time.perf_counter() - last_index >= INDEX_INTERVAL_S:
                    _write_index(out_dir, index, rendered)
                    last_index = time.perf_counter()
        finally:
            _record_written(pending, rendered, wait=True)
            _write_index(out_dir, index, rendered)


def _write_frame(path, image) -> None:
    """A frame's PNG, whole or not at all: 8-bit sRGB as it came from a worker, or the
    linear image converted exactly as ``write_image`` does."""
    from mimarble.mitsuba.rendering.image_output import write_image, write_rgb8
    (write_rgb8 if image.dtype == np.uint8 else write_image)(path, image)


def _record_written(pending, rendered: set, wait: bool = False) -> list:
    """Mark the frames whose image is written as done (and add them to ``rendered``) or
    failed, if the write failed; the rest stay pending."""
    still = []
    for entry, result, future in pending:
        if not (wait or future.done()):
            still.append((entry, result, future))
            continue
        try:
            future.result()
        except Exception as e:           # disk full, permission: the frame failed, not the sweep
            entry.update(status="failed", error=f"writing the image: {error_text(e)}",
                         render_s=result["render_s"])
            continue
        entry.update(status="done", error=None, render_s=result["render_s"],
                     **{k: result[k] for k in ("rmse", "psnr") if k in result})
        rendered.add(result["index"])
    return still


def _results(jobs, workers, scheduler):
    """Each job's result as it completes: here, or on Dask (a task that fails there —
    a worker lost, say — is that frame's error, not the sweep's). No jobs: nothing is
    started (a resumed sweep with nothing left starts no cluster)."""
    if not jobs:
        return
    if not workers and not scheduler:
        for job in jobs:
            yield render_frame(job)
        return
    from dask.distributed import Client, as_completed
    cluster = client = None
    # Ctrl-C (SIGINT) on Dask is held and raised only while waiting for the next frame
    # and after each: raised inside Dask's own calls (starting the cluster, fetching a
    # result), it leaves a cluster half-made or a callback that logs a traceback. A
    # terminal sends it to the whole process group: the workers never see it (below);
    # they are this process's to stop.
    with _Interrupts() as interrupts:
        try:
            if scheduler is None:
                # Multiprocessing's resource tracker is started first, here: the thread
                # that starts it has SIGINT unblocked afterwards (resource_tracker.py).
                from multiprocessing import resource_tracker
                resource_tracker.ensure_running()
            try:
                with interrupts.blocked_in_new_threads():   # and in the workers they spawn
                    if scheduler is None:
                        cluster = local_cluster(int(workers), jobs[0].get("variant"))
                    client = Client(cluster if cluster is not None else scheduler,
                                    timeout=f"{SCHEDULER_TIMEOUT_S}s")
            except (OSError, ValueError, TimeoutError, RuntimeError) as e:
                # RuntimeError: Dask's "Nanny failed to start." (a worker that could not)
                where = f"the scheduler at {scheduler}" if scheduler else "a LocalCluster"
                raise SweepError(f"cannot start or reach {where}: {e}") from None
            futures = {client.submit(render_frame, job, pure=False): job["index"]
                       for job in jobs}
            completed = as_completed(futures)
            while True:
                with interrupts.raised():
                    future = next(completed, None)
                if future is None:
                    break
                index = futures.pop(future)
                try:
                    result = dict(future.result(), index=index)   # the frame asked for, by this side
                except Exception as e:
                    result = {"index": index, "image": None, "render_s": None,
                              "error": f"on Dask: {error_text(e)}"}
                future.release()                 # the worker can drop the image now
                interrupts.check()
                yield result
                interrupts.check()
        finally:
            _stop_dask(client, cluster)          # a second Ctrl-C is held till it is done


#: LocalCluster workers log at this level and above (Dask's default, WARNING, prints
#: "Event loop was unresponsive" while a frame holds the interpreter, and the like):
#: a frame's failure is in the index, the sweep's in its own error.
WORKER_LOG_LEVEL = "ERROR"


def local_cluster(workers: int, variant: str | None = None):
    """A Dask ``LocalCluster`` of ``workers`` single-threaded worker processes (Dr.Jit runs
    its own threads), no dashboard. Each worker preloads this module (Dask's preload):
    mimarble and Mitsuba start in ``variant`` as the worker starts, not at its first
    frame, SIGINT is ignored there (:func:`dask_setup`), and a worker asked to close
    skips Dr.Jit's and Mitsuba's teardown (:func:`dask_teardown`)."""
    import logging
    from dask.distributed import LocalCluster
    from mimarble.runtime.environment import VARIANT_ENV
    env = {VARIANT_ENV: variant} if variant else {}
    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                        dashboard_address=None, silence_logs=getattr(logging, WORKER_LOG_LEVEL),
                        preload=[__name__], env=env)


def dask_setup(worker=None) -> None:
    """Run in each :func:`local_cluster` worker as it starts (Dask calls a preloaded
    module's ``dask_setup``): SIGINT ignored (the sweep's process stops its workers), and
    mimarble started in the client's variant (``$MIMARBLE_VARIANT``, set by the cluster;
    importing this module started it already, unless that failed). A worker where
    mimarble cannot start still starts: its frames say why."""
    import signal
    with contextlib.suppress(ValueError):     # not the worker's main thread: leave it
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        import mimarble
        mimarble.start()
    except Exception:        # render_frame starts it again, and records the error
        pass


def dask_teardown(worker=None) -> None:
    """Run in each :func:`local_cluster` worker as it is closed: once Python's exit
    begins, the process ends at once, its output flushed. Dr.Jit's and Mitsuba's own
    teardown frees nothing a process that ends needs freed, and writes nothing (compiled
    kernels are cached as they are compiled), and it made the cluster's stop several times
    longer (docs/benchmarks.md, "Sweeps")."""
    import atexit
    atexit.register(_exit_now)


def _exit_now() -> None:
    import sys
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):
            pass
    os._exit(0)


def _stop_dask(client, cluster) -> None:
    """Close the client, then the cluster (its workers stopped, or killed if a frame keeps
    one past Dask's few seconds): quietly — what Dask logs of its own stop is not the
    user's."""
    import logging
    # Dask's logging configuration gives some of them levels and handlers of their own
    # (distributed.client, tornado.application): each is silenced, not only the roots.
    names = {"distributed", "tornado", "asyncio"}
    names.update(name for name in list(logging.root.manager.loggerDict)
                 if name.split(".")[0] in ("distributed", "tornado", "asyncio"))
    loggers = [logging.getLogger(name) for name in sorted(names)]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL + 1)
    try:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    finally:
        for logger, level in zip(loggers, levels):
            logger.setLevel(level)


class _Interrupts:
    """Within, SIGINT (Ctrl-C) is held: raised as KeyboardInterrupt only at
    :meth:`check`, inside :meth:`raised`, and when the block is left — never inside
    code that must not be cut short. :meth:`blocked_in_new_threads`: SIGINT is blocked
    in the threads started within too, and so in the processes they start (a
    LocalCluster's workers inherit the mask). Only in the main thread (where Python runs
    signal handlers) and where SIGINT raises KeyboardInterrupt or calls a Python
    handler; elsewhere it does nothing."""

    def __init__(self):
        self.previous = None
        self.held = self.raising = False

    def __enter__(self):
        import signal
        import threading
        if threading.current_thread() is threading.main_thread() and \
                callable(signal.getsignal(signal.SIGINT)):
            self.previous = signal.signal(signal.SIGINT, self._handle)
        return self

    def _handle(self, signum, frame):
        self.held = True
        if self.raising:
            self.check()

    def check(self) -> None:
        """Raise the interrupt held, if one is (as the previous handler would have)."""
        if self.held and self.previous is not None:
            import signal
            self.held = False
            self.previous(signal.SIGINT, None)

    @contextlib.contextmanager
    def raised(self):
        """Within, SIGINT is raised at once (a wait that can be cut short)."""
        self.raising = True       # first: an interrupt from here on is raised, not held
        try:
            self.check()
            yield
        finally:
            self.raising = False

    @contextlib.contextmanager
    def blocked_in_new_threads(self):
        import signal
        mask = None
        if self.previous is not None and hasattr(signal, "pthread_sigmask"):
            mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            yield
        finally:
            if mask is not None:
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)

    def __exit__(self, kind, value, traceback):
        import signal
        if self.previous is None:
            return False
        signal.signal(signal.SIGINT, self.previous)
        if kind is None or kind is GeneratorExit:   # closed early: still say it was asked
            self.check()
        return False


# ---------------------------------------------------------------------------
# One sweep at a time in a folder

#: The lock file in a sweep's folder while a sweep writes there: held (``flock``), holding
#: its process id for the message a second sweep gets.
LOCK = ".sweep.lock"


class _FolderLock:
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


# ---------------------------------------------------------------------------
# The index, and the images it says are done

#: What makes two sweeps the same sweep (a resumed one must match on each), with the
#: JSON type each has in an index that is not damaged.
_SAME = {"scene_digest": str, "settings": list, "spp": (int, type(None)), "compare": bool,
         "variant": str}
_STATUSES = ("todo", "done", "failed")


def _open_index(out_dir: Path, source, scene, settings, spp, compare, all_frames,
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
            warnings.warn(f"{path}: {_count(n, 'frame entry', 'frame entries')} of the sweep "
                          f"index {'is' if n == 1 else 'are'} damaged (frame {first}: {why}); "
                          f"rendering {_them(n)} again", stacklevel=3)
    _write_index(out_dir, index)
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


def _todo(all_frames, index, out_dir: Path, names) -> list:
    """The frames not done: those the index does not say are, and those it says are whose
    image is not usable (:func:`image_problem`, from the header: cheap), said in a warning."""
    todo, damaged = [], []
    for frame in all_frames:
        entry = index["frames"][frame["index"]]
        if entry["status"] == "done":
            problem = image_problem(out_dir / names[frame["index"]], _size(frame["scene"]))
            if problem is None:
                continue
            damaged.append((names[frame["index"]], problem))
            for key in ("rmse", "psnr"):
                entry.pop(key, None)
            entry.update(status="todo", error=None, render_s=None)
        todo.append(frame)
    if damaged:
        n, (name, why) = len(damaged), damaged[0]
        warnings.warn(f"{out_dir}: {_count(n, 'done frame')} {'has' if n == 1 else 'have'} no "
                      f"usable image ({name}: {why}{', …' if n > 1 else ''}); rendering "
                      f"{_them(n)} again", stacklevel=3)
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


def _write_index(out_dir: Path, index: dict, rendered=()) -> None:
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
    return (f"{_count(s['frames'], 'frame')}: {s['already_done']} already done, "
            f"{s['rendered_now']} rendered now, {s['failed']} failed"
            + (f", {s['left']} left" if s["left"] else ""))


def _size(scene) -> tuple[int, int]:
    return scene.image.width, scene.image.height


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _json_type(value) -> str:
    return {dict: "object", list: "array", str: "string", bool: "boolean", int: "number",
            float: "number", type(None): "null"}.get(type(value), type(value).__name__)


def _count(n: int, one: str, many: str | None = None) -> str:
    return f"{n} {one if n == 1 else many or one + 's'}"


def _them(n: int) -> str:
    return "it" if n == 1 else "them"


# ---------------------------------------------------------------------------
# Contact sheet

def write_contact_sheet(out_dir, index: dict, cell: int = 160, size=None) -> Path:
    """``contact.png`` of the sweep in ``out_dir`` (mimarble/sweeps/contact_sheet.py). Each done
    frame's image is read from its derived name (:func:`file_name`) in ``out_dir``,
    nothing else; one that does not decode (or is not ``size``, (width, height), if
    given) is drawn as a failed cell and marked failed in ``index``, with why, so that it
    is rendered again."""
    out_dir = Path(out_dir)
    named = [Setting(s["key"], tuple(s["values"])) for s in index["settings"]]
    cells = [(entry["values"], out_dir / file_name({"index": k, "values": entry["values"]}, named)
              if entry["status"] == "done" else None)
             for k, entry in enumerate(index["frames"])]
    path = out_dir / CONTACT_SHEET
    title = f"{Path(index['scene']).name}: " + ", ".join(s["key"] for s in index["settings"])
    undecodable = draw_contact_sheet(path, title, index["settings"], cells, cell, size)
    for k, error in undecodable.items():
        index["frames"][k].update(status="failed",
                                  error=f"its image does not decode ({error_text(error)})")
    return path
