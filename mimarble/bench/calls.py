"""Whole calls against their kernels: what a warm render costs outside its kernels.

Each row times one warm call the way a user makes it — ``mimarble.render`` of a scene
model or file, a sweep, an inverse-rendering step — and, in the same run, the Dr.Jit
kernels it launches (Dr.Jit's kernel history: ``execution_time`` of the JIT kernels,
summed over one call). Their ratio is what tracing, loading and Python add; recorded
passes (mimarble/mitsuba/rendering/replay.py) and loaded scenes kept by structure
(mimarble/mitsuba/rendering/loaded_scenes.py) exist to bring it near 1. Every render row is
measured with replay on and off (``MIMARBLE_FREEZE=0``) in the same run.

Calls with and without the kernel history alternate (the history itself costs a
little), so the whole-call time is from calls without it, the kernels' from calls
with it; medians of ``repeats`` each, after warm-up calls.
"""

from __future__ import annotations

import contextlib
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from mimarble.runtime import environment
from mimarble import scene as scene_language
from mimarble.scene.edits import resized, with_constant_colours, with_marbles

dr, mi = environment.import_drjit_and_mitsuba()

#: Warm-up calls before timing (the first compiles and records).
WARM_UP = 3


@contextlib.contextmanager
def replay(on: bool):
    """Replay of recorded passes on or off (``MIMARBLE_FREEZE``) within the block."""
    before = os.environ.get("MIMARBLE_FREEZE")
    os.environ["MIMARBLE_FREEZE"] = "1" if on else "0"
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("MIMARBLE_FREEZE", None)
        else:
            os.environ["MIMARBLE_FREEZE"] = before


def kernels_of(history) -> tuple[float, int]:
    """(milliseconds of the JIT kernels, launches of any kind) in a kernel history."""
    return (sum(k["execution_time"] for k in history if k["type"] == dr.KernelType.JIT),
            len(history))


def time_call(call, repeats: int) -> dict:
    """{"whole_ms", "kernels_ms", "launches", "ratio"} of ``call()`` (module docstring)."""
    for _ in range(WARM_UP):
        call()
    whole, kernels, launches = [], [], []
    for _ in range(repeats):
        dr.sync_thread()
        start = time.perf_counter()
        call()
        dr.sync_thread()
        whole.append(1000 * (time.perf_counter() - start))
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
            dr.kernel_history()                        # (empties it)
            call()
            dr.sync_thread()
            ms, count = kernels_of(dr.kernel_history())
        kernels.append(ms)
        launches.append(count)
    row = {"whole_ms": statistics.median(whole), "kernels_ms": statistics.median(kernels),
           "launches": int(statistics.median(launches))}
    row["ratio"] = row["whole_ms"] / row["kernels_ms"] if row["kernels_ms"] else None
    return row


def render_rows(scene_path, repeats: int = 15) -> list[dict]:
    """Warm ``mimarble.render`` at 500², 1 spp, replay on and off: the scene with its
    marbles at 8 octaves (a model), the same with constant colours, and the file itself."""
    import mimarble
    scene = resized(scene_language.load(scene_path), 500)
    eight = with_marbles(scene, octaves=8)
    cases = [("8-octave marble sphere (model)", lambda: mimarble.render(eight, spp=1)),
             ("constant-colour sphere (model)",
              lambda s=with_constant_colours(eight): mimarble.render(s, spp=1)),
             (f"{Path(scene_path).name} (file, its own octaves)",
              lambda: mimarble.render(str(scene_path), spp=1))]
    rows = []
    for name, call in cases:
        for on in (True, False):
            with replay(on):
                rows.append({"call": f"mimarble.render: {name}", "replay": on,
                             **time_call(call, repeats)})
    return rows


def sweep_row(scene_path, frames: int = 64, size: int = 256, spp: int = 4) -> dict:
    """A ``frames``-frame period sweep in this process, against frames × one frame's
    kernels plus the compile of its first frame (codegen + backend of the kernels not
    found in a cache; 0 when every kernel was cached)."""
    from mimarble.sweeps import run as sweeps
    scene = resized(scene_language.load(scene_path), size)
    setting = {"marble.period": list(np.linspace(0.5, 4.0, frames))}
    with tempfile.TemporaryDirectory() as folder:
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
            dr.kernel_history()
            start = time.perf_counter()
            sweeps.sweep(scene, setting, Path(folder) / "sweep", spp=spp)
            dr.sync_thread()
            seconds = time.perf_counter() - start
            history = dr.kernel_history()
    jit = [k for k in history if k["type"] == dr.KernelType.JIT]
    compile_s = sum(k["codegen_time"] + k["backend_time"] for k in jit
                    if not k["cache_hit"]) / 1000
    kernels_s = sum(k["execution_time"] for k in jit) / 1000
    budget_s = kernels_s + compile_s
    return {"call": f"sweep: {frames} frames of marble.period at {size}², {spp} spp",
            "frames": frames, "whole_s": seconds, "kernels_s": kernels_s,
            "compile_s": compile_s, "ratio": seconds / budget_s}


def povray_row(scene, ours_ms: float, repeats: int = 5) -> dict | None:
    """POV-Ray 3.7's own "Trace Time" of ``scene`` (a model) at its size, 1 sample
    (mimarble/tools/povray.py), against ``ours_ms``; None without ``povray``."""
    from mimarble.tools.povray import time_povray
    theirs = time_povray(scene, scene.image.width, repeats=repeats)
    if theirs is None:
        return None
    return {**theirs, "ours_ms": ours_ms, "trace_over_ours": theirs["trace_s"] * 1000 / ours_ms}


def measure(scene_path, repeats: int = 15, sweep_frames: int = 64) -> dict:
    """Every row (a ``results["calls"]`` of the benchmark): the renders, the sweep, one
    Adam step of notebook 02 (mimarble/bench/adam.py), POV-Ray on the renders' 8-octave
    sphere, and the noise alone against its peers (mimarble/bench/peers.py)."""
    from mimarble.bench.adam import step_rows
    from mimarble.bench.peers import peer_rates
    renders = render_rows(scene_path, repeats)
    sphere = with_marbles(resized(scene_language.load(scene_path), 500), octaves=8)
    return {"renders": renders, "sweep": sweep_row(scene_path, sweep_frames),
            "adam_step": step_rows(),
            "povray": povray_row(sphere, renders[0]["whole_ms"]),   # the first row's sphere
            "peers": peer_rates()}
