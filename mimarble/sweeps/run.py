"""Sweeps: one scene, some parameters varied, one image per combination — the
``sweep`` function, which orders the work.

    mimarble sweep scenes/fig11a.scene --set marble.period=0.5,1,2,4 \\
                   --set marble.distortion=1:8:4 -o out/
    mimarble.sweep("scenes/fig11a.scene", {"marble.period": [0.5, 1, 2, 4]}, "out/")

The package's modules, in the order a sweep uses them: settings.py (``KEY=v1,v2,…`` or
``KEY=start:stop:count``, and the limits), frames.py (every combination as a scene, a
frame's image name, rendering one frame), index.py (the folder: ``sweep.json``, the
images it says are done, the lock), cluster.py (Dask, and Ctrl-C on it),
contact_sheet.py.

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
goes on. The index's ``summary`` says what this run did (index.py, ``summary``: frames
already done, rendered now, failed, left), as the command's last line does.

**Several processes, several machines** on Dask distributed (cluster.py): ``workers=N``
starts a ``LocalCluster`` of N single-threaded worker processes, ``scheduler=ADDRESS``
joins a running one. Starting a LocalCluster costs seconds and one process already uses
every core: on 2 cores ``workers`` was slower at every size measured
(docs/benchmarks.md, "Sweeps"). Ctrl-C stops the workers with the sweep.

**One sweep at a time in a folder.** A sweep holds a lock on its folder while it runs
(index.py, ``FolderLock``: an ``flock`` the system drops when the process ends, by a
kill too): a second sweep into it is refused in one sentence before it reads or writes
there.

**A sweep folder is data, not instructions.** A frame's image is always named by
``file_name`` (frames.py) from its index and values inside the output folder; the
``file`` field of the index is written for readers and never read back. A damaged index
(not JSON, the wrong shape, a frame with a missing key or a wrong type) is said in one
warning and started afresh (a damaged frame entry: that frame alone is rendered again);
a done frame whose image is missing, not a regular file, not a PNG of the frame's size
or truncated is rendered again, and so is one that does not decode in the contact sheet.
Links, pipes and devices in the folder are never followed or read.

**Limits** (each stated once, with why, where it is checked): ``MAX_FRAMES`` frames and
``MAX_SETTINGS`` settings per sweep (settings.py, checked before a frame or a range's
values are made), ``WORKERS_PER_CORE`` LocalCluster workers per core and a scheduler's
answer within ``SCHEDULER_TIMEOUT_S`` (cluster.py), an index of ``MAX_INDEX_BYTES``
(index.py), a contact sheet of ``CONTACT_SHEET_PIXELS`` (contact_sheet.py).
"""

from __future__ import annotations

import contextlib
import os
import time
import warnings
from pathlib import Path

import numpy as np

from mimarble.runtime import files, packaged_scenes
from mimarble import scene as scene_language
from mimarble.scene.image_header import check_image_maps
from mimarble.scene.python_numbers import plain_numbers
from mimarble.scene.rules import shortened, spp_problem
from mimarble.sweeps.cluster import check_scheduler, check_workers, dask_results
from mimarble.sweeps.contact_sheet import CONTACT_SHEET, write_contact_sheet
from mimarble.sweeps.frames import error_text, file_name, frames, render_frame
from mimarble.sweeps.index import (INDEX_INTERVAL_S, FolderLock, counted, open_index, image_size,
                                   pronoun_for, frames_to_do, write_index)
from mimarble.sweeps.settings import SweepError, settings_from


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
    (index.py, ``FolderLock``). ``worker_threads``: Dr.Jit threads per Dask worker (default: a
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
        width, height = image_size(scene)
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
    # (FolderLock: the lock dies with the process, so a killed sweep leaves none).
    with FolderLock(out_dir):
        mimarble.start()
        variant = mimarble.mi.variant()
        index = open_index(out_dir, scene_or_path, scene, settings, spp, compare, all_frames,
                            variant)
        # The only names ever written or read in the folder: derived, never taken from the index.
        names = [file_name(f, settings) for f in all_frames]
        todo = frames_to_do(all_frames, index, out_dir, names)
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
                write_contact_sheet(out_dir, index, size=image_size(scene))
            except OSError as e:             # the frames are there; only their overview is not
                warnings.warn(f"{out_dir / CONTACT_SHEET}: cannot write the contact sheet "
                              f"({e.strerror or e})", stacklevel=2)
            undecodable = [k for k in was_done if index["frames"][k]["status"] != "done"]
            if not undecodable:
                break
            write_index(out_dir, index, rendered)
            if attempt == 0:
                warnings.warn(f"{out_dir}: {counted(len(undecodable), 'frame image')} did not "
                              f"decode ({names[undecodable[0]]}"
                              f"{', …' if len(undecodable) > 1 else ''}); rendering "
                              f"{pronoun_for(len(undecodable))} again", stacklevel=2)
                _render([all_frames[k] for k in undecodable], options, index, out_dir, names,
                        workers, scheduler, lambda: None, rendered)
        return index


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
                    write_index(out_dir, index, rendered)
                    last_index = time.perf_counter()
        finally:
            _record_written(pending, rendered, wait=True)
            write_index(out_dir, index, rendered)


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
    yield from dask_results(jobs, workers, scheduler)
