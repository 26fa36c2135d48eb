"""``mimarble bench``: run time against error, and what skipping saves — the measuring.

The benchmark's *runs* render every scene in every :class:`Mode` at every spp
(a grid over modes and spp, not ``mimarble sweep``'s over scene parameters), the
adaptive modes at every threshold instead; then each mode's time to plain 16 and
64 spp's RMSE (mimarble/bench/curves.py), the paper's render times, and on fig11a the
targets and the whole process (mimarble/bench/targets.py). The modes are
mimarble/bench/modes.py's, each render timed by mimarble/bench/timing.py.

Errors are against a *converged* image: the float64 reference tracer at many samples per
pixel, cached on disk (:func:`mimarble.runtime.files.cache_folder`) because it takes
seconds to minutes.

The results are a JSON-ready dict: mimarble/bench/report.py prints it,
mimarble/bench/plot.py draws it, mimarble/runtime/machine.py names its machine.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from mimarble import reference
from mimarble import scene as scene_language
from mimarble.bench.curves import adaptive_columns, speedups_at_equal_error, times_to_plain_rmse
from mimarble.bench.oracle import level_images, oracle_samples
from mimarble.bench.modes import (ADAPTIVE_FIRST_SPP, ADAPTIVE_THRESHOLDS, DEFAULT_CONVERGED_SPP,
                                  DEFAULT_MAX_SPP, DEFAULT_SPPS, MODES, PAPER_SECONDS,
                                  TARGET_SPPS)
from mimarble.bench.targets import against_povray, measure_targets, process_times
from mimarble.bench.timing import converged, samples_taken, time_adaptive, time_render
from mimarble.mitsuba.rendering.silhouettes import edge_mask
from mimarble.mitsuba.translate.scene_dict import to_mitsuba
from mimarble.runtime import environment, files
from mimarble.runtime.machine import machine_facts
from mimarble.runtime.progress import report
from mimarble.scene.edits import resized, with_marbles
from mimarble.tools.compare import image_metrics

dr, mi = environment.import_drjit_and_mitsuba()



def run_bench(scene_paths, size=256, spps=DEFAULT_SPPS, converged_spp=DEFAULT_CONVERGED_SPP,
              repeats=5, targets=None, paper=True, cache_dir=None, progress=True, povray=True,
              tolerance=None, modes=MODES, thresholds=ADAPTIVE_THRESHOLDS,
              max_spp=DEFAULT_MAX_SPP) -> dict:
    """The runs (every scene in every mode at every spp; an adaptive mode at every one of
    ``thresholds``, first pass 1 spp, at most ``max_spp``), each mode's time to plain 16
    and 64 spp's RMSE, the paper comparison, and (with ``targets``, a scene path) the
    targets.

    ``tolerance``: every marble's error budget for our renders (None: each scene's
    default); the converged reference is always the full sum. ``modes``: the
    :class:`Mode` of each scene's runs. Each run also has its RMSE inside the silhouettes
    (``interior_rmse``: pixels whose 3×3 neighbourhood sees one shape, at 16 spp) and the
    samples it traced per pixel (``mean_spp``; an adaptive run's replaced ones included,
    and its pixels' samples at the end, ``final_spp``, apart).
    ``cache_dir``: where converged references are kept (default
    :func:`mimarble.runtime.files.cache_folder`). ``progress``: as :func:`mimarble.runtime.progress.report`
    takes it, counting steps.
    """
    cache_dir = Path(cache_dir or files.cache_folder())
    scenes = [(Path(p).stem, scene_language.load(p)) for p in scene_paths]
    steps = len(scenes) * (1 + sum(len(thresholds) if m.adaptive else len(spps)
                                   for m in modes))
    steps += sum(1 for name, _ in scenes if name in PAPER_SECONDS) if paper else 0
    steps += 9 if targets else 0           # measure_targets' 7 steps, the whole process, calls
    step = _stepper(report(progress, "bench", unit="step"), steps)
    results = {"machine": machine_facts(), "date": time.strftime("%Y-%m-%d", time.gmtime()),
               "size": size, "converged_spp": converged_spp,
               "repeats": repeats, "tolerance": tolerance, "runs": [], "paper": [],
               "modes": [dataclasses.asdict(m) for m in modes], "targets": {}}
    if any(m.adaptive for m in modes):
        results["adaptive"] = {"thresholds": list(thresholds), "first_spp": ADAPTIVE_FIRST_SPP,
                               "max_spp": max_spp}

    for name, scene in scenes:
        small = resized(scene, size)
        truth = converged(small, converged_spp, cache_dir)
        interior = ~edge_mask(mi.load_dict(to_mitsuba(small, spp=16)), 16)
        step(f"{name}: converged reference")
        for mode in modes:
            variant = with_marbles(small, filter=mode.filter, tolerance=tolerance)

            def entry(timing, **fields):
                metrics = image_metrics(timing.image, truth)
                results["runs"].append({
                    "scene": name, "mode": mode.name, **fields,
                    "run_ms": timing.run_ms, "compile_ms": timing.compile_ms,
                    "kernels_compiled": timing.kernels_compiled,
                    "rmse": metrics["rmse"], "psnr": metrics["psnr"],
                    "interior_rmse": float(np.sqrt(np.mean(
                        np.square(timing.image - truth)[interior])))})

            if mode.adaptive:
                loaded = mi.load_dict(to_mitsuba(variant, spp=ADAPTIVE_FIRST_SPP))
                for threshold in thresholds:
                    timing = time_adaptive(variant, threshold, max_spp, repeats, loaded=loaded)
                    pixels = timing.image.shape[0] * timing.image.shape[1]
                    entry(timing, spp=ADAPTIVE_FIRST_SPP, edge_spp=None, threshold=threshold,
                          max_spp=max_spp, mean_spp=int(timing.result.traced) / pixels,
                          final_spp=float(np.mean(timing.result.samples)),
                          rounds=int(timing.result.rounds))
                    step(f"{name}: {mode.name} threshold {threshold:g}")
                # The oracle beside it: every pixel at its best level, knowing its error.
                plain = {r["spp"]: r["rmse"] for r in results["runs"]
                         if r["scene"] == name and r["mode"] == "plain"}
                images, costs = level_images(loaded, ADAPTIVE_FIRST_SPP, max_spp)
                results.setdefault("oracle", {}).setdefault(name, {})[mode.name] = {
                    str(spp): oracle_samples(images, truth, costs, plain[spp])
                    for spp in TARGET_SPPS if spp in plain}
                continue
            loaded = mi.load_dict(to_mitsuba(variant, spp=1)) if mode.edge_spp else None
            for spp in spps:
                timing = time_render(variant, spp, repeats, mode.edge_spp)
                entry(timing, spp=spp, edge_spp=mode.edge_spp,
                      mean_spp=samples_taken(loaded, spp, mode.edge_spp))
                step(f"{name}: {mode.name} {spp} spp")
    results["speedup_at_plain16_rmse"] = speedups_at_equal_error(results["runs"])
    results["time_to_rmse"] = times_to_plain_rmse(results["runs"])
    results["adaptive_columns"] = adaptive_columns(results)

    if paper:
        for name, scene in scenes:
            if name not in PAPER_SECONDS:
                continue
            ours = time_render(with_marbles(scene, tolerance=tolerance), scene.image.samples,
                               repeats)
            start = time.perf_counter()
            reference.render(scene)
            ref_s = time.perf_counter() - start
            results["paper"].append({
                "scene": name, "spp": scene.image.samples, "ours_s": ours.run_ms / 1000,
                "paper_s": PAPER_SECONDS[name], "ratio": ours.run_ms / 1000 / PAPER_SECONDS[name],
                "reference_s": ref_s})
            step(f"{name}: paper comparison")

    if targets:
        results["targets"] = measure_targets(targets, repeats, cache_dir, step, tolerance)
        results["process"] = process_times(targets, repeats)
        step("whole process: help, malformed scene, render warm and cold")
        if povray:
            results["povray"] = against_povray(targets, repeats,
                                               results["process"]["render_warm_s"])
        from mimarble.bench.calls import measure as measure_calls
        results["calls"] = measure_calls(targets)
        step("whole calls against their kernels")
    return results


def _stepper(update, total: int):
    """``step(label)``: one more of ``total`` steps done, ``label`` the one that finished;
    reported through ``update(done, total, label)`` (:func:`mimarble.runtime.progress.report`),
    starting now from 0."""
    done = 0
    update(done, total)

    def step(label: str) -> None:
        nonlocal done
        done += 1
        update(done, total, label)
    return step
