"""Issue 28: what ``mimarble sweep --workers 2`` costs to start, and where it starts to pay.

    ./go python scripts/sweep_workers_timing.py [OUT.json] [--repeats N]   # ~6 minutes
                                                [--part startup|steady|crossover]

Three measurements (``--part startup``, ``steady`` or ``crossover`` runs one, keeping the
others' in OUT.json), every figure a median of ``--repeats`` (default 3) runs, the ways
alternating within each repeat (the machine is shared and noisy):

* **start-up**: ``mimarble.sweep`` of a 4×4 sweep of fig11a (period × distortion) at
  128², each run in a new process as the command's is, on a LocalCluster of 2 workers,
  cut into what comes before the cluster (``import dask.distributed`` mostly), the
  cluster's start (``local_cluster``), its first frame back, the other frames, its stop
  and the contact sheet; with the LocalCluster as the sweep made it before issue 28
  (``before``: Dask's defaults — the workers import mimarble at their first frame and
  exit through Python's whole teardown, Dr.Jit's and Mitsuba's included) and as
  it makes it now (``now``: ``sweeps.local_cluster``), beside the same sweep in one
  process (``one_process``).
* **steady state**: a frame's time once everything is started and compiled (:func:`steady`),
  in one process and on a started cluster of 2 workers, at 32², 128² and 512².
* **the crossover**: the whole command, ``python -m mimarble sweep scenes/fig11a.scene
  --set marble.period=0.5:4:N --set marble.distortion=1:6:N --width S --height S -o …``,
  with and without ``--workers 2``, its wall time from start to exit, for N×N frames
  and S² pixels over a grid; the kernels are in the cache first (a sweep of each size
  before), as after any first run.

The figures depend on the machine (named in the JSON): a sweep in one process already
uses every core (Dr.Jit's threads), and on 2 cores two workers of one thread each won
nowhere (docs/benchmarks.md, "`--workers 2` against one process").
"""

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SIZES = (32, 64, 128, 256, 512)
SIDES = (2, 4, 8, 16)                  # N×N frames: 4, 16, 64, 256
LARGEST = 512 * 512 * 64               # pixels × frames of the largest sweep measured


def before_issue_28(workers, variant=None):
    """The LocalCluster as sweeps.py made it before issue 28."""
    from dask.distributed import LocalCluster
    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                        dashboard_address=None)


def startup_run(way: str, out: str) -> None:
    """One start-up measurement in this (new) process, printed as JSON: the 4×4 sweep at
    128² in one process (``one_process``) or on 2 workers made ``before`` issue 28 or
    ``now``, the sweep's phases timed from outside (its own functions wrapped)."""
    import mimarble
    mimarble.start()
    from mimarble.sweeps import cluster as sweep_cluster, run as sweeps
    from mimarble import scene as S
    from mimarble.scene.edits import resized
    scene = resized(S.load(ROOT / "scenes" / "fig11a.scene"), 128)
    setting = {"marble.period": [0.5, 1.5, 2.5, 4.0], "marble.distortion": [1.0, 2.5, 4.0, 6.0]}
    at = {}
    make = before_issue_28 if way == "before" else sweep_cluster.local_cluster
    stop, record = sweep_cluster._stop_dask, sweeps._record_written

    def cluster(*args, **kwargs):
        at["start"] = time.perf_counter()
        made = make(*args, **kwargs)
        at["up"] = time.perf_counter()
        return made

    def timed_stop(client, cluster):
        at["stop"] = time.perf_counter()
        stop(client, cluster)
        at["stopped"] = time.perf_counter()

    def timed_record(pending, rendered, wait=False):
        if pending:
            at.setdefault("first", time.perf_counter())
        return record(pending, rendered, wait)

    sweep_cluster.local_cluster, sweep_cluster._stop_dask, sweeps._record_written = \
        cluster, timed_stop, timed_record
    at["begin"] = time.perf_counter()
    index = sweeps.sweep(scene, setting, out, workers=None if way == "one_process" else 2)
    at["end"] = time.perf_counter()
    assert index["summary"]["rendered_now"] == 16, index["summary"]
    phases = {"sweep_s": at["end"] - at["begin"]}
    if way != "one_process":
        phases.update(before_cluster_s=at["start"] - at["begin"],
                      cluster_start_s=at["up"] - at["start"], first_frame_s=at["first"] - at["up"],
                      other_frames_s=at["stop"] - at["first"], stop_s=at["stopped"] - at["stop"],
                      after_s=at["end"] - at["stopped"])
    print(json.dumps(phases))


def startup(repeats: int) -> dict:
    """:func:`startup_run` ``repeats`` times each way, each in a new process (as the
    command is: the first LocalCluster of a process, ``dask.distributed`` imported by
    the sweep), the ways alternating; the kernels cached by a sweep before."""
    work = Path(tempfile.mkdtemp(prefix="sweep-workers-"))
    code = ("import sys; sys.path.insert(0, sys.argv[3]); import sweep_workers_timing as t; "
            "t.startup_run(sys.argv[1], sys.argv[2])")
    runs = {"one_process": [], "before": [], "now": []}
    for k in range(repeats + 1):                 # the first round only caches the kernels
        for way in runs:
            result = subprocess.run(
                [sys.executable, "-c", code, way, str(work / f"{way}-{k}"), str(ROOT / "scripts")],
                cwd=ROOT, capture_output=True, text=True)
            if result.returncode != 0:
                raise RuntimeError(f"{way}: {result.stderr}")
            if k:
                runs[way].append(json.loads(result.stdout.strip().splitlines()[-1]))
    medians = {way: {key: statistics.median(run[key] for run in found) for key in found[0]}
               for way, found in runs.items()}
    # What each worker process imports, as whole new processes (CPU seconds: user + system).
    imports = {"python": "pass", "dask_distributed": "import distributed",
               "mimarble_started": "import mimarble; mimarble.start()"}
    cpu = {name: [] for name in imports}
    for _ in range(repeats):
        for name, code in imports.items():
            before = os.times()
            subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True)
            after = os.times()
            cpu[name].append(after.children_user + after.children_system
                             - before.children_user - before.children_system)
    return {"frames": 16, "size": 128, "runs": runs, "medians": medians,
            "process_cpu_s": {name: statistics.median(v) for name, v in cpu.items()},
            "process_cpu_runs_s": cpu}


def steady(repeats: int, frames: int = 64) -> dict:
    """A frame's time once everything is started: ``frames`` frames' ``render_frame`` (the
    sweep's own, 8-bit sRGB out as on Dask) in this process on Dr.Jit's default threads,
    against the same frames submitted to a started LocalCluster of 2 workers and waited
    for (``sweeps.local_cluster``; one Dr.Jit thread each, as ``--workers 2`` gives them
    here); the wall time over ``frames``, median of ``repeats``, at each of three sizes."""
    import mimarble
    mimarble.start()
    from dask.distributed import Client
    from mimarble.sweeps import cluster as sweep_cluster, run as sweeps
    from mimarble import scene as S
    from mimarble.scene.edits import resized
    out = {}
    cluster = sweep_cluster.local_cluster(2, mimarble.mi.variant())
    client = Client(cluster)
    try:
        for size in (32, 128, 512):
            scene = resized(S.load(ROOT / "scenes" / "fig11a.scene"), size)
            made = sweeps.frames(scene, sweeps.settings_from(
                {"marble.period": [0.5 + 3.5 * k / frames for k in range(frames)]}))
            jobs = [{"index": f["index"], "scene": f["scene"], "spp": None, "compare": False,
                     "variant": mimarble.mi.variant(), "threads": None, "encode": True}
                    for f in made]
            on_dask = [dict(job, threads=1) for job in jobs]
            sweeps.render_frame(jobs[0])                       # loaded, compiled
            client.gather([client.submit(sweeps.render_frame, job, pure=False)
                           for job in on_dask[:4]])
            here, there = [], []
            for _ in range(repeats):
                start = time.perf_counter()
                for job in jobs:
                    sweeps.render_frame(job)
                here.append((time.perf_counter() - start) / frames)
                start = time.perf_counter()
                client.gather([client.submit(sweeps.render_frame, job, pure=False)
                               for job in on_dask])
                there.append((time.perf_counter() - start) / frames)
            out[str(size)] = {"one_process_frame_s": statistics.median(here),
                              "workers_2_frame_s": statistics.median(there),
                              "one_process_runs_s": here, "workers_2_runs_s": there}
            print(f"  {size}²: a frame {out[str(size)]['one_process_frame_s'] * 1e3:.1f} ms "
                  f"in one process, {out[str(size)]['workers_2_frame_s'] * 1e3:.1f} ms on "
                  f"2 workers", flush=True)
    finally:
        client.close()
        cluster.close()
    return {"frames": frames, "sizes": out}


def command_s(size: int, side: int, out: Path, workers: bool) -> float:
    args = [sys.executable, "-m", "mimarble", "sweep", "scenes/fig11a.scene",
            "--set", f"marble.period=0.5:4:{side}", "--set", f"marble.distortion=1:6:{side}",
            "--width", str(size), "--height", str(size), "-o", str(out)]
    args += ["--workers", "2"] if workers else []
    start = time.perf_counter()
    result = subprocess.run(args, cwd=ROOT, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if result.returncode != 0 or "0 failed" not in result.stdout:
        raise RuntimeError(f"{' '.join(args)}: {result.stdout}{result.stderr}")
    return seconds


def crossover(repeats: int) -> dict:
    work = Path(tempfile.mkdtemp(prefix="sweep-crossover-"))
    for size in SIZES:                                   # the kernels cached first
        command_s(size, 2, work / f"warm-{size}", workers=False)
    cells = []
    for size in SIZES:
        for side in SIDES:
            if size * size * side * side > LARGEST:
                continue
            one, two = [], []
            for k in range(repeats):
                one.append(command_s(size, side, work / f"{size}-{side}-one-{k}", False))
                two.append(command_s(size, side, work / f"{size}-{side}-two-{k}", True))
            cells.append({"size": size, "frames": side * side,
                          "one_process_s": statistics.median(one), "one_process_runs_s": one,
                          "workers_2_s": statistics.median(two), "workers_2_runs_s": two})
            print(f"  {size}², {side * side} frames: one process "
                  f"{cells[-1]['one_process_s']:.2f} s, --workers 2 "
                  f"{cells[-1]['workers_2_s']:.2f} s", flush=True)
    pays = {}
    for size in SIZES:
        row = [c for c in cells if c["size"] == size]
        won = [c["frames"] for c in row if c["workers_2_s"] < c["one_process_s"]]
        pays[str(size)] = min(won) if won else None
    return {"sizes": list(SIZES), "frames": [s * s for s in SIDES], "cells": cells,
            "workers_pay_from_frames": pays}


def main(argv) -> int:
    repeats, part = 3, "all"
    for option in ("--repeats", "--part"):
        if option in argv:
            at = argv.index(option)
            if option == "--repeats":
                repeats = int(argv[at + 1])
            else:
                part = argv[at + 1]
            del argv[at:at + 2]
    out_json = argv[0] if argv else None
    import mimarble
    mimarble.start()
    from mimarble.runtime.machine import machine_facts
    results = {}
    if part != "all" and out_json and Path(out_json).exists():    # the other part kept
        results = json.loads(Path(out_json).read_text())
    results.update({"machine": machine_facts(),
                    "command": "./go python scripts/sweep_workers_timing.py "
                               "docs/bench/sweep-workers.json [--part P --repeats N]"})
    if part in ("all", "startup"):
        print("start-up (4×4 at 128², a new process each run) …", flush=True)
        results["startup"] = dict(startup(repeats), repeats=repeats,
                                  date=time.strftime("%Y-%m-%d"))
        for way, found in results["startup"]["medians"].items():
            print(f"  {way}: " + ", ".join(f"{k} {v:.2f}" for k, v in found.items()))
        print("  a new process's CPU: " + ", ".join(
            f"{k} {v:.2f} s" for k, v in results["startup"]["process_cpu_s"].items()))
    if part in ("all", "steady"):
        print("a frame once started, one process against 2 workers …", flush=True)
        results["steady"] = dict(steady(max(repeats, 5)), repeats=max(repeats, 5),
                                 date=time.strftime("%Y-%m-%d"))
    if part in ("all", "crossover"):
        print("the whole command, one process against --workers 2 …", flush=True)
        results["crossover"] = dict(crossover(repeats), repeats=repeats,
                                    date=time.strftime("%Y-%m-%d"))
        print("  --workers 2 pays from (frames, by size):",
              results["crossover"]["workers_pay_from_frames"])
    if out_json:
        Path(out_json).write_text(json.dumps(results, indent=1, default=str) + "\n")
    return 0


if __name__ == "__main__":
    os.environ.setdefault("MIMARBLE_VARIANT", "llvm_ad_rgb")
    sys.exit(main(sys.argv[1:]))
