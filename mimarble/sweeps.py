"""Sweeps: one scene, some parameters varied, one image per combination.

    mimarble sweep scenes/fig11a.scene --set marble.period=0.5,1,2,4 \\
                   --set marble.distortion=1:8:4 -o out/
    mimarble.sweep("scenes/fig11a.scene", {"marble.period": [0.5, 1, 2, 4]}, "out/")

A setting is ``KEY=v1,v2,…`` or ``KEY=start:stop:count`` (``count`` values from
``start`` to ``stop``, both included). A key is a key path of the scene
(:func:`mimarble.scene_edits.with_value`): ``marble.K``, ``MATERIAL.K`` or
``MATERIAL.CHANNEL.K`` for K a sweepable marble parameter
(``marble_parameters.SWEEPABLE``), ``camera.fov``, ``image.samples`` or
``light.N.intensity``.

Frames are the combinations of all settings (the last varies fastest). Every frame's
scene is made before the first render, so a bad key or value (checked by the marble's
parameter table) is an error before any work.

**One compile per structure.** Frames are rendered through a cache of loaded Mitsuba
scenes keyed by their *structure* — the scene dict with the values a sweep can
change in place (``marble_parameters.IN_PLACE``) masked out — so frames that differ
only in ``scale``, ``period`` or ``distortion`` reuse one scene: the new values go in
through ``mi.traverse`` (they are opaque: the compiled kernels are reused). Another
structure (octaves, function, …) loads and compiles once.

**Nothing lost.** ``sweep.json`` in the output folder lists every frame with its
values, file, status, error and render time; it is rewritten whole (temporary
file, rename) at most every half second and when the sweep ends or is interrupted;
images are written whole or not at all, and a frame is done once its image is written
and indexed. Run the same sweep again (same scene, sizes, settings, spp, variant) and
only what is missing is done (failed frames are tried again); a frame that fails —
rendering, writing, or its Dask worker lost — is recorded with its error and the sweep
goes on.

**Several processes, several machines** on Dask distributed: ``workers=N`` starts a
``LocalCluster`` of N single-threaded worker processes, ``scheduler=ADDRESS`` joins a
running one. Each worker imports mimarble once and keeps its loaded scenes and
compiled kernels between frames (:func:`render_frame`); images come back to this
process, which writes them, so no shared file system is needed.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import os
import re
import time
from pathlib import Path

import numpy as np

from . import files
from . import scene as scene_language
from .marble_parameters import IN_PLACE
from .scene_edits import KeyPathError, with_value

INDEX = "sweep.json"
#: The index is rewritten at most this often while frames come in (and at the end).
INDEX_INTERVAL_S = 0.5
CONTACT_SHEET = "contact.png"


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


def settings_from(spec) -> tuple[Setting, ...]:
    """Settings from ``--set`` strings, or a mapping {key: values} (Python)."""
    if isinstance(spec, dict):
        # NumPy values (np.linspace, np.arange) become Python ones: JSON and checks take them.
        return tuple(Setting(k, tuple(np.asarray(v, dtype=object).ravel().tolist()
                                      if isinstance(v, (list, tuple, np.ndarray)) else
                                      [np.asarray(v).item()]))
                     for k, v in spec.items())
    return tuple(parse_setting(s) if isinstance(s, str) else s for s in spec)


def frames(scene, settings) -> list[dict]:
    """Every combination: [{"index", "values": {key: value}, "scene"}] (last setting fastest).
    Each frame's scene is built here, so a bad key or value fails before any render
    (SweepError ``--set KEY: …``)."""
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

class _SceneCache:
    """Loaded Mitsuba scenes (and their traversed parameters) by structure; a new frame
    of a known structure only updates the in-place values of its marbles."""

    def __init__(self, size: int = 8):
        self.size, self.scenes = size, {}

    def scene_for(self, frame_scene, spp: int):
        import mitsuba as mi
        from .mitsuba.translate import to_mitsuba
        scene_dict = to_mitsuba(frame_scene, spp=spp)
        structure, values = _structure(scene_dict)
        key = (mi.variant(), structure)
        if key not in self.scenes:
            if len(self.scenes) >= self.size:
                self.scenes.pop(next(iter(self.scenes)))
            mitsuba_scene = mi.load_dict(scene_dict)
            self.scenes[key] = (mitsuba_scene, mi.traverse(mitsuba_scene))
            return mitsuba_scene
        mitsuba_scene, params = self.scenes[key]
        try:   # every in-place value, every frame (cheap): nothing left from another frame
            for name, value in values.items():
                params[name] = value
            params.update()
        except BaseException:
            self.scenes.pop(key, None)   # a half-updated scene is never used again
            raise
        return mitsuba_scene


def _structure(scene_dict) -> tuple[str, dict]:
    """(the dict with in-place marble values masked, as JSON; those values by traverse key)."""
    values, masked = {}, {}
    for name, item in scene_dict.items():
        if isinstance(item, dict) and item.get("type") == "marble":
            item = dict(item)
            for key in IN_PLACE:
                values[f"{name}.{key}"] = item.pop(key)
        masked[name] = item
    return json.dumps(masked, sort_keys=True, default=str), values


_CACHE = _SceneCache()


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
        from .compare import image_metrics
        from .mitsuba.image_output import srgb8
        from .mitsuba.render import render_in_passes
        frame_scene = job["scene"]
        spp = job["spp"] or frame_scene.image.samples
        start = time.perf_counter()
        mitsuba_scene = _CACHE.scene_for(frame_scene, spp)
        image = render_in_passes(mitsuba_scene, spp)
        out["render_s"] = time.perf_counter() - start
        if job.get("compare"):
            from . import reference
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

    ``settings``: ``--set``-style strings, or {key: values}. ``workers`` / ``scheduler``:
    Dask (see the module docstring); neither: this process. ``compare``: each frame's
    RMSE and PSNR against the reference tracer. ``stop_after``: stop after that many
    frames (what an interruption does; the index says what is left). Already done frames
    of the same sweep in ``out_dir`` are kept, not rendered again. ``worker_threads``:
    Dr.Jit threads per Dask worker (default: a LocalCluster's share of this machine's
    cores; a scheduler's workers keep their own).
    """
    import mimarble
    from .progress import report
    scene = scene_or_path
    if isinstance(scene_or_path, (str, os.PathLike)):
        scene = scene_language.load(scene_or_path)
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
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    mimarble.start()
    variant = mimarble.mi.variant()
    index = _open_index(out_dir, scene_or_path, scene, settings, spp, compare, all_frames, variant)
    todo = [f for f in all_frames if not _done(index["frames"][f["index"]], out_dir)]
    finished = len(all_frames) - len(todo)
    if stop_after is not None:
        todo = todo[:stop_after]
    done = report(progress, "sweep", unit="frame")
    done(finished, len(all_frames))
    # A LocalCluster's workers share this machine's cores (Dr.Jit would start a thread per
    # core in each); a remote scheduler's workers keep their own machines' defaults.
    threads = worker_threads or (max(1, (os.cpu_count() or 1) // int(workers))
                                 if workers and not scheduler else None)
    jobs = [{"index": f["index"], "scene": f["scene"], "spp": spp, "compare": compare,
             "variant": variant, "threads": threads, "encode": bool(workers or scheduler)}
            for f in todo]
    # Images are written by one background thread while the next frames render (PNG
    # encoding takes a sixth of a 256² frame's time); the index, rewritten whole, at most
    # every INDEX_INTERVAL_S and at the end — a frame whose image is written but not yet
    # indexed is simply rendered again on resume.
    from concurrent.futures import ThreadPoolExecutor
    last_index = time.perf_counter()
    pending = []
    with ThreadPoolExecutor(max_workers=1) as writer:
        try:
            for result in _results(jobs, workers, scheduler):
                entry = index["frames"][result["index"]]
                if result["error"] is None:
                    pending.append((entry, result, writer.submit(
                        _write_frame, out_dir / entry["file"], result["image"])))
                else:
                    entry.update(status="failed", error=result["error"],
                                 render_s=result["render_s"])
                finished += 1
                done(finished, len(all_frames))
                pending = _record_written(pending)
                if time.perf_counter() - last_index >= INDEX_INTERVAL_S:
                    _write_index(out_dir, index)
                    last_index = time.perf_counter()
        finally:
            _record_written(pending, wait=True)
            _write_index(out_dir, index)
    if contact_sheet and any(_done(e, out_dir) for e in index["frames"]) \
            and all(e["status"] != "todo" for e in index["frames"]):
        write_contact_sheet(out_dir, index)
    return index


def _write_frame(path, image) -> None:
    """A frame's PNG, whole or not at all: 8-bit sRGB as it came from a worker, or the
    linear image converted exactly as ``write_image`` does."""
    from .mitsuba.image_output import write_image, write_rgb8
    (write_rgb8 if image.dtype == np.uint8 else write_image)(path, image)


def _record_written(pending, wait: bool = False) -> list:
    """Mark the frames whose image is written as done (or failed, if the write failed);
    the rest stay pending."""
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
    return still


def _results(jobs, workers, scheduler):
    """Each job's result as it completes: here, or on Dask (a task that fails there —
    a worker lost, say — is that frame's error, not the sweep's)."""
    if not workers and not scheduler:
        for job in jobs:
            yield render_frame(job)
        return
    from dask.distributed import Client, LocalCluster, as_completed
    cluster = client = None
    try:
        try:
            if scheduler is None:
                cluster = LocalCluster(n_workers=int(workers), threads_per_worker=1,
                                       processes=True, dashboard_address=None)
            client = Client(cluster if cluster is not None else scheduler, timeout="10s")
        except (OSError, ValueError, TimeoutError) as e:
            where = f"the scheduler at {scheduler}" if scheduler else "a LocalCluster"
            raise SweepError(f"cannot start or reach {where}: {e}") from None
        futures = {client.submit(render_frame, job, pure=False): job["index"] for job in jobs}
        for future in as_completed(futures):
            index = futures.pop(future)
            try:
                result = future.result()
            except Exception as e:
                result = {"index": index, "image": None, "render_s": None,
                          "error": f"on Dask: {error_text(e)}"}
            future.release()                 # the worker can drop the image now
            yield result
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()


def _open_index(out_dir: Path, source, scene, settings, spp, compare, all_frames,
                variant) -> dict:
    """The index in ``out_dir`` (made, or read back for a resumed sweep of the same kind:
    the same scene — by content, sizes included —, settings, spp, comparison and variant)."""
    import hashlib
    described = {"scene": str(source) if isinstance(source, (str, os.PathLike))
                 else getattr(source, "source", None) or "<scene>",
                 "scene_digest": hashlib.sha256(repr(scene).encode()).hexdigest()[:16],
                 "settings": [{"key": s.key, "values": list(s.values)} for s in settings],
                 "spp": spp, "compare": compare, "variant": variant}
    path = out_dir / INDEX
    if path.exists():
        try:
            index = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError) as e:
            raise SweepError(f"{path}: cannot read the sweep index ({e}); move it away to start "
                             f"again") from None
        same = ("scene_digest", "settings", "spp", "compare", "variant")
        if {k: index.get(k) for k in same} != {k: described[k] for k in same}:
            raise SweepError(f"{out_dir} holds another sweep ({path}: another scene, size, "
                             f"setting, spp or variant); write this one elsewhere")
        return index
    settings_list = list(settings)
    index = dict(described, frames=[
        {"index": f["index"], "values": f["values"], "file": file_name(f, settings_list),
         "status": "todo", "error": None, "render_s": None} for f in all_frames])
    _write_index(out_dir, index)
    return index


def _done(entry, out_dir: Path) -> bool:
    return entry["status"] == "done" and (out_dir / entry["file"]).exists()


def _write_index(out_dir: Path, index: dict) -> None:
    files.write_json(index, out_dir / INDEX)


# ---------------------------------------------------------------------------
# Contact sheet

def write_contact_sheet(out_dir, index: dict, cell: int = 160) -> Path:
    """``contact.png``: the frames with their values beside them — a row for one setting
    (the paper's figure layout), a grid of rows × columns for two (values along the top
    and the left), a grid of cells each captioned with every value for more. Cells are
    ``cell`` pixels wide; drawn with Pillow (a sheet of 64 frames in a fraction of a
    second)."""
    from PIL import Image, ImageDraw

    out_dir = Path(out_dir)
    settings, entries = index["settings"], index["frames"]
    if len(settings) == 2:
        rows, columns = len(settings[0]["values"]), len(settings[1]["values"])
    elif len(settings) == 1:
        rows, columns = 1, len(entries)
    else:
        columns = math.ceil(math.sqrt(len(entries)))
        rows = math.ceil(len(entries) / columns)
    line = 12                                            # the default font's line height
    caption = line * (1 if len(settings) <= 2 else len(settings)) + 4
    left = 0 if len(settings) != 2 else 8 * max(len(_label(settings[0], v))
                                                for v in settings[0]["values"]) + 8
    top = line + 8 + (caption if len(settings) == 2 else 0)
    row_height = cell + (caption if len(settings) != 2 else 4)
    sheet = Image.new("RGB", (left + columns * cell + 8, top + rows * row_height + 4), "white")
    draw = ImageDraw.Draw(sheet)
    draw.text((4, 4), f"{Path(index['scene']).name}: "
                      + ", ".join(s["key"] for s in settings), fill="black")
    for k, entry in enumerate(entries):
        r, c = divmod(k, columns)
        x, y = left + c * cell + 4, top + r * row_height
        if _done(entry, out_dir):
            image = Image.open(out_dir / entry["file"]).convert("RGB")
            image.thumbnail((cell - 4, cell - 4))
            sheet.paste(image, (x, y))
        else:                                            # a failed frame: a grey cell
            draw.rectangle((x, y, x + cell - 5, y + cell - 5), fill=(200, 200, 200))
            draw.text((x + 6, y + cell // 2 - 6), "failed", fill="black")
        values = entry["values"]
        if len(settings) == 2:
            if r == 0:
                draw.text((x, y - caption), _label(settings[1], values[settings[1]["key"]]),
                          fill="black")
            if c == 0:
                draw.text((4, y + cell // 2), _label(settings[0], values[settings[0]["key"]]),
                          fill="black")
        else:
            for n, setting in enumerate(settings):
                draw.text((x, y + cell - 2 + n * line), _label(setting, values[setting["key"]]),
                          fill="black")
    path = out_dir / CONTACT_SHEET
    files.write_atomically(path, lambda tmp: sheet.save(tmp, compress_level=1))
    return path


def _label(setting, value) -> str:
    return f"{_short(setting['key'])} = {_text(value)}"


def _short(key: str) -> str:
    return key.split(".", 1)[1] if key.startswith("marble.") else key


def _text(value) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)
