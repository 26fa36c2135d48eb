"""A sweep's frames: every combination of the settings as a scene (made before any
render, so that a bad key or value is an error before any work), its image's name, and
rendering one frame — in this process or in a Dask worker, which imports this module's
:func:`render_frame` by its name (it must stay a function at module level here).
"""

from __future__ import annotations

import itertools
import re
import time

from mimarble.scene.edits import KeyPathError, with_value
from mimarble.scene.rules import number_problem, shortened
from mimarble.sweeps.settings import SweepError, frame_count


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
