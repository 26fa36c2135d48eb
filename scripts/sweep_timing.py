"""Issue 16's targets: a 64-frame period sweep of fig11a at 256², in one process and on a
LocalCluster of 2 workers, against 64 warm renders plus one compile.

    ./go python scripts/sweep_timing.py [OUT.json]      # prints the figures; ~1 minute

Runs with an empty Dr.Jit kernel cache (a temporary DRJIT_CACHE_DIR, set before Dr.Jit
loads), so the sweep's first frame really compiles, and measures:

* compile: the codegen + backend time of the kernels compiled during the sweep (Dr.Jit's
  kernel history, cache misses only: the first frame's);
* warm: the median of 9 renders of the loaded scene (render_in_passes, after a sync),
  and of 9 renders each written to a PNG (what ``mimarble render -o`` does);
* the one-process sweep's wall time (frames, PNGs, index, contact sheet) against
  64 × warm + compile (target ≤ 1.2×): the median of REPEATS sweeps, the later ones
  (kernels cached) with the first's compile time added back;
* the same sweep on a LocalCluster of 2 worker processes (its start-up included and
  apart; median of REPEATS sweeps on the same cluster), its throughput against the
  one-process sweep's (target within 20 %), and
  whether its images are the one-process images bit for bit.
"""

import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ["DRJIT_CACHE_DIR"] = tempfile.mkdtemp(prefix="drjit-sweep-")

import numpy as np  # noqa: E402

import mimarble  # noqa: E402
from mimarble.sweeps import run as sweeps  # noqa: E402
from mimarble import scene as S  # noqa: E402
from mimarble.runtime.machine import machine_facts  # noqa: E402
from mimarble.mitsuba.rendering.render import render_in_passes  # noqa: E402
from mimarble.mitsuba.rendering.loaded_scenes import LOADED  # noqa: E402
from mimarble.scene.edits import resized  # noqa: E402

dr, mi = mimarble.dr, mimarble.mi
ROOT = Path(__file__).resolve().parent.parent
FRAMES = 64
REPEATS = 3


def main(out_json=None):
    scene = resized(S.load(ROOT / "scenes" / "fig11a.scene"), 256)
    setting = {"marble.period": list(np.linspace(0.5, 4.0, FRAMES))}
    work = Path(tempfile.mkdtemp(prefix="sweep-timing-"))

    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        start = time.perf_counter()
        here = sweeps.sweep(scene, setting, work / "one-process")
        first_s = time.perf_counter() - start
        history = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    # Again, into new folders (the kernels now cached, the compile added back): the
    # machine is shared and noisy, so each sweep's time is the median of REPEATS.
    one_process_runs = [first_s]
    for k in range(1, REPEATS):
        start = time.perf_counter()
        sweeps.sweep(scene, setting, work / f"one-process-{k}")
        one_process_runs.append(time.perf_counter() - start)
    compile_s = sum(k["codegen_time"] + k["backend_time"] for k in history
                    if not k["cache_hit"]) / 1000
    mitsuba_scene = next(iter(LOADED.scenes.values()))[0]
    spp = scene.image.samples
    runs = []
    for _ in range(9):
        dr.sync_thread()
        t0 = time.perf_counter()
        render_in_passes(mitsuba_scene, spp)
        runs.append(time.perf_counter() - t0)
    warm_s = statistics.median(runs)
    budget_s = FRAMES * warm_s + compile_s
    one_process_s = statistics.median([one_process_runs[0]]
                                      + [t + compile_s for t in one_process_runs[1:]])
    # A render as `mimarble render -o x.png` does it: the image written too.
    from mimarble.mitsuba.rendering.image_output import write_image
    runs = []
    for k in range(9):
        dr.sync_thread()
        t0 = time.perf_counter()
        write_image(work / f"warm{k}.png", render_in_passes(mitsuba_scene, spp))
        runs.append(time.perf_counter() - t0)
    warm_written_s = statistics.median(runs)

    from dask.distributed import Client, LocalCluster
    start = time.perf_counter()
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=None)
    client = Client(cluster)
    client.run(lambda: __import__("mimarble").start())        # workers import mimarble
    startup_s = time.perf_counter() - start
    dask_runs = []
    for k in range(REPEATS):
        start = time.perf_counter()
        there = sweeps.sweep(scene, setting, work / f"dask-{k}", scheduler=cluster.scheduler_address,
                             worker_threads=1)      # as `--workers 2` gives each on 2 cores
        dask_runs.append(time.perf_counter() - start)
    dask_s = statistics.median(dask_runs)
    client.close()
    cluster.close()
    from PIL import Image
    identical = all(
        np.array_equal(np.asarray(Image.open(work / "one-process" / a["file"])),
                       np.asarray(Image.open(work / f"dask-{REPEATS - 1}" / b["file"])))
        for a, b in zip(here["frames"], there["frames"]))

    results = {
        "machine": machine_facts(), "frames": FRAMES, "size": 256, "spp": spp,
        "repeats": REPEATS, "compile_s": compile_s, "warm_render_s": warm_s,
        "one_process_s": one_process_s, "one_process_runs_s": one_process_runs,
        "dask_runs_s": dask_runs,
        "one_process_over_budget": one_process_s / budget_s,
        "warm_render_and_write_s": warm_written_s,
        "one_process_over_written_budget": one_process_s / (FRAMES * warm_written_s + compile_s),
        "dask_workers": 2, "dask_startup_s": startup_s, "dask_s": dask_s,
        "dask_throughput_over_one_process": one_process_s / dask_s,
        "dask_identical_images": identical,
        "failed": [f["index"] for f in here["frames"] + there["frames"] if f["status"] != "done"],
    }
    print(json.dumps(results, indent=1, default=str))
    if out_json:
        Path(out_json).write_text(json.dumps(results, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else None))
