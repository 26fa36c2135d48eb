"""``mimarble bench``: run time against error, and what skipping saves — the measuring.

The benchmark's *runs* render every scene in every :class:`Mode` at every spp
(a grid over modes and spp, not ``mimarble sweep``'s over scene parameters), the
adaptive modes at every threshold instead; then each mode's time to plain 16 and
64 spp's RMSE (:func:`time_to_rmse`), the paper's render times, and on fig11a the
targets and the whole process.

Every timing is a median of warm runs taken after a sync (LLVM kernel launches
are asynchronous; converting the image to NumPy waits for it), with the first
render's compile time reported apart from Dr.Jit's kernel history. Errors are
against a *converged* image: the float64 reference tracer at many samples per
pixel, cached on disk (:func:`mimarble.runtime.files.cache_folder`) because it takes
seconds to minutes.

The results are a JSON-ready dict: mimarble/bench/report.py prints it,
mimarble/bench/plot.py draws it, mimarble/runtime/machine.py names its machine.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import statistics
import time
from pathlib import Path

import numpy as np

from mimarble.runtime import environment, files, kernel_cache
from mimarble import reference
from mimarble.tools import stress
from mimarble import scene as scene_language
from mimarble.bench.report import setting
from mimarble.tools.compare import image_metrics
from mimarble.runtime.machine import machine_facts
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.mitsuba.rendering.silhouettes import edge_mask
from mimarble.mitsuba.translate.scene_dict import marble_tolerance, to_mitsuba
from mimarble.runtime.progress import report
from mimarble.scene.edits import filling_the_view, resized, with_constant_colours, with_marbles

dr, mi = environment.import_drjit_and_mitsuba()

#: Edge samples of the runs' prefilter+edges mode unless --edge-spp says otherwise.
DEFAULT_EDGE_SPP = 64
#: The adaptive modes' thresholds unless --adaptive says otherwise: the estimated
#: per-pixel error (linear colour) above which a pixel gets more samples, coarse to fine.
ADAPTIVE_THRESHOLDS = (0.005, 0.0025, 0.00125, 0.0006, 0.0003, 0.00015, 7.5e-5, 3.7e-5,
                       1.8e-5, 9e-6, 4.5e-6)
#: The adaptive modes' first pass and cap on any pixel's samples (both perfect squares).
ADAPTIVE_FIRST_SPP = 1
DEFAULT_MAX_SPP = 64
#: The runs' spp (the adaptive modes' are their thresholds') and the converged reference's:
#: finer than the runs' finest, so that plain 64 spp's RMSE is an error, not zero.
DEFAULT_SPPS = (1, 4, 16, 64)
DEFAULT_CONVERGED_SPP = 256
#: The plain spp whose RMSE every mode's time is measured to (:func:`times_to_plain_rmse`).
TARGET_SPPS = (16, 64)


@dataclasses.dataclass(frozen=True)
class Mode:
    """How the benchmark renders a scene: every marble's ``filter``, and edge samples
    (None: none); ``adaptive``: through :func:`~mimarble.mitsuba.rendering.adaptive.render_adaptive`
    (a first pass, then more samples where a pixel's estimated error is above a
    threshold), once per threshold instead of once per spp."""

    name: str
    filter: str = "none"
    edge_spp: int | None = None
    adaptive: bool = False


def modes(filter: str | None = None, edge_spp: int | None = None,
          adaptive: bool = True) -> tuple[Mode, ...]:
    """The runs' modes: plain, bandlimit, prefilter and prefilter with edge samples, then
    (``adaptive``) adaptive sampling of plain and of prefiltered marble; with ``filter``,
    that filter alone (with edge samples when ``edge_spp`` is given), and adaptive
    sampling of it."""
    if filter is None:
        fixed = (Mode("plain"), Mode("bandlimit", "bandlimit"), Mode("prefilter", "prefilter"),
                 Mode("prefilter+edges", "prefilter", edge_spp or DEFAULT_EDGE_SPP))
        filters = ("none", "prefilter")
    else:
        name = "plain" if filter == "none" else filter
        fixed = (Mode(name + ("+edges" if edge_spp else ""), filter, edge_spp),)
        filters = (filter,)
    if not adaptive:
        return fixed
    return fixed + tuple(Mode("adaptive" + ("" if f == "none" else "+" + f), f, adaptive=True)
                         for f in filters)


MODES = modes()
#: The modes the fig11a targets compare (octaves 32 vs 8, time to RMSE ≤ 0.01).
TARGET_MODES = MODES[:2]


def is_paper_scene(name: str) -> bool:
    """Whether a run's scene is one of the paper's figures (``fig…``): the means are over
    these; every other scene (the fine veins, …) is reported on its own."""
    return name.startswith("fig")
# The paper's "render" column (seconds on a 2 GHz Pentium 4, 500×500) for Figs. 7–11.
PAPER_SECONDS = {
    "fig07a": 2.0, "fig07b": 2.0, "fig07c": 2.0, "fig07d": 2.0,
    "fig08a": 2.0, "fig08b": 2.0, "fig08c": 2.0, "fig08d": 2.0,
    "fig09a": 2.0, "fig09b": 2.0, "fig09c": 2.0, "fig09d": 2.0,
    "fig10a": 0.8, "fig10b": 1.0, "fig10c": 1.4, "fig10d": 2.0,
    "fig11a": 2.8, "fig11b": 6.3, "fig11c": 2.1, "fig11d": 2.1,
}


# ---------------------------------------------------------------------------
# Measurements

@dataclasses.dataclass
class Timing:
    run_ms: float                 # median of the warm runs
    runs_ms: list
    compile_ms: float             # codegen + backend of the first render's kernels
    kernels_compiled: int         # kernels of the first render not found in any cache
    image: np.ndarray = dataclasses.field(repr=False)
    result: object = dataclasses.field(default=None, repr=False)   # the last render's own


def _timed(render, repeats: int, image_of=lambda result: result) -> Timing:
    """Render once (compile), then ``repeats`` warm renders, each after a sync."""
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        result = render()
        first = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    runs = []
    for _ in range(repeats):
        dr.sync_thread()
        start = time.perf_counter()
        result = render()
        runs.append(1000 * (time.perf_counter() - start))
    return Timing(run_ms=statistics.median(runs), runs_ms=runs,
                  compile_ms=sum(k["codegen_time"] + k["backend_time"] for k in first),
                  kernels_compiled=kernel_cache.compiled(first), image=image_of(result),
                  result=result)


def time_render(scene, spp: int, repeats: int, edge_spp: int | None = None) -> Timing:
    """Load once, render once (compile), then ``repeats`` warm renders after a sync, as
    ``mimarble.render`` renders (``render_in_passes``: one kernel for every spp, ray
    differentials from the eye, edge samples)."""
    mitsuba_scene = mi.load_dict(to_mitsuba(scene, spp=spp))
    return _timed(lambda: render_in_passes(mitsuba_scene, spp, edge_spp=edge_spp), repeats)


def time_adaptive(scene, threshold: float, max_spp: int, repeats: int,
                  spp: int = ADAPTIVE_FIRST_SPP, loaded=None) -> Timing:
    """As :func:`time_render`, through ``render_adaptive`` (first pass ``spp``, more
    samples where a pixel's estimated error is above ``threshold``, at most ``max_spp``);
    the Timing's ``result`` is the last render's (``samples``, ``traced``, ``rounds``).
    ``loaded``: ``scene`` already loaded into Mitsuba (one load for every threshold)."""
    from mimarble.mitsuba.rendering.adaptive import render_adaptive
    mitsuba_scene = loaded if loaded is not None else mi.load_dict(to_mitsuba(scene, spp=spp))
    return _timed(lambda: render_adaptive(mitsuba_scene, spp, threshold, max_spp), repeats,
                  image_of=lambda result: np.asarray(result.image))


def samples_taken(mitsuba_scene, spp: int, edge_spp: int | None) -> float:
    """Mean samples traced per pixel by ``render_in_passes(mitsuba_scene, spp, edge_spp=…)``:
    ``spp``, plus ``edge_spp`` more on each silhouette pixel (its replaced samples count)."""
    if edge_spp is None or edge_spp <= spp:
        return float(spp)
    return spp + edge_spp * float(np.mean(edge_mask(mitsuba_scene, spp)))


def _reference_source_digest() -> str:
    """A digest of the reference tracer's code: a fixed tracer invalidates cached images."""
    digest = hashlib.sha256()
    for path in sorted(Path(reference.__file__).parent.glob("*.py")):
        digest.update(path.read_bytes())
    return digest.hexdigest()


def converged(scene, spp: int, cache_dir: Path) -> np.ndarray:
    """The reference tracer's image at ``spp``, cached by scene, spp and tracer code."""
    key = hashlib.sha256(repr((scene, spp, _reference_source_digest())).encode()).hexdigest()[:20]
    path = cache_dir / f"converged-{key}.npy"
    if path.exists():
        return np.load(path)
    image = reference.render(scene, spp=spp)
    cache_dir.mkdir(parents=True, exist_ok=True)
    files.write_atomically(path, lambda tmp: np.save(tmp, image))
    return image


def hit_fraction(image_alpha_free: np.ndarray, background) -> float:
    return float(np.mean(np.any(image_alpha_free != np.asarray(background, np.float32), axis=-1)))


# ---------------------------------------------------------------------------
# The benchmark

def targets_scene(scene_paths):
    """The scene the targets are measured on: fig11a among ``scene_paths``, else the
    repository's ``scenes/fig11a.scene`` when there is one, else None."""
    for path in scene_paths:
        if Path(path).stem == "fig11a":
            return str(path)
    beside_package = Path(__file__).resolve().parents[2] / "scenes" / "fig11a.scene"
    return str(beside_package) if beside_package.is_file() else None


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
                continue
            loaded = mi.load_dict(to_mitsuba(variant, spp=1)) if mode.edge_spp else None
            for spp in spps:
                timing = time_render(variant, spp, repeats, mode.edge_spp)
                entry(timing, spp=spp, edge_spp=mode.edge_spp,
                      mean_spp=samples_taken(loaded, spp, mode.edge_spp))
                step(f"{name}: {mode.name} {spp} spp")
    results["speedup_at_plain16_rmse"] = speedups_at_equal_error(results["runs"])
    results["time_to_rmse"] = times_to_plain_rmse(results["runs"])

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


def _process_seconds(args, repeats: int, expect: int = 0, fresh_caches=False) -> float:
    """Median wall time of ``python -m mimarble ARGS`` (the command's whole process), which
    must exit with status ``expect``.

    ``fresh_caches``: each run gets empty kernel and parser caches, as a new user has.
    """
    import subprocess
    import sys
    import tempfile
    times = []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as folder:
            run_env = dict(os.environ)
            if fresh_caches:
                run_env.update(DRJIT_CACHE_DIR=str(Path(folder) / "drjit"),
                               XDG_CACHE_HOME=str(Path(folder) / "cache"))
            start = time.perf_counter()
            result = subprocess.run([sys.executable, "-m", "mimarble", *map(str, args)],
                                    env=run_env, capture_output=True, text=True)
            times.append(time.perf_counter() - start)
            if result.returncode != expect:
                raise RuntimeError(f"mimarble {' '.join(map(str, args))}: exit status "
                                   f"{result.returncode}, expected {expect}: {result.stderr}")
    return statistics.median(times)


def process_times(scene_path, repeats) -> dict:
    """Whole-process seconds of the command (issue 17): help, a malformed scene, and a
    render of ``scene_path`` at 500², 1 spp with warm caches and with empty ones."""
    import tempfile
    with tempfile.TemporaryDirectory() as folder:
        bad = Path(folder) / "malformed.scene"
        bad.write_text("camera {\n  eye < 0 0 10 >\n  foo\n}\n")
        out = Path(folder) / "out.png"
        render = ["render", scene_path, "--spp", "1", "--width", "500", "--height", "500",
                  "-o", out]
        _process_seconds(render, 1)                  # fills the caches
        return {"help_s": _process_seconds(["--help"], repeats),
                "malformed_scene_s": _process_seconds(["render", bad, "-o", out], repeats,
                                                      expect=2),
                "render_warm_s": _process_seconds(render, repeats),
                "render_cold_s": _process_seconds(render, min(repeats, 3), fresh_caches=True),
                "repeats": repeats}


def against_povray(scene_path, repeats, ours_process_s) -> dict | None:
    """POV-Ray 3.7 and mimarble on the same kind of marble sphere (fig11a, 500², 1 sample):
    render against trace time, and whole process against whole process (warm caches)."""
    from mimarble.bench.calls import povray_row
    from mimarble.tools.povray import available
    scene = resized(scene_language.load(scene_path), 500)
    if not available():
        return None
    row = povray_row(scene, time_render(scene, 1, repeats).run_ms, repeats=3)
    return {**row, "ours_process_s": ours_process_s,
            "process_over_ours": row["process_s"] / ours_process_s}


def measure_targets(scene_path, repeats, cache_dir, step, tolerance=None) -> dict:
    """The issue's targets on fig11a at 500×500, the sphere filling the view (its marbles
    at ``tolerance``, None: the scene's default); ``step(label)`` after each of its 7
    steps."""
    base = with_marbles(filling_the_view(resized(scene_language.load(scene_path), 500)),
                        tolerance=tolerance)
    t = {}

    def run(scene, spp=1):
        return time_render(scene, spp, repeats)

    for mode in TARGET_MODES:
        t8 = run(with_marbles(base, octaves=8, filter=mode.filter)).run_ms
        t32 = run(with_marbles(base, octaves=32, filter=mode.filter)).run_ms
        step(f"targets: octaves 32 vs 8 ({mode.name})")
        t[f"octaves32_over_8_{mode.name}"] = {"t8_ms": t8, "t32_ms": t32, "ratio": t32 / t8}
    # What the error budget costs in colour at 32 octaves: the texture at its tolerance
    # against the float64 reference's full sum (mimarble.tools.stress.tolerance_error).
    marble32 = next(c for m in with_marbles(base, octaves=32).materials.values()
                    for c in m.channels().values()
                    if isinstance(c, scene_language.MarbleChannel))
    t["tolerance_error_32"] = stress.tolerance_error(marble32,
                                                     marble_tolerance(base, marble32, tolerance))

    marble8 = run(with_marbles(base, octaves=8))
    constant = run(with_constant_colours(base))
    step("targets: marble vs constant")
    t["marble8_over_constant"] = {"marble_ms": marble8.run_ms, "constant_ms": constant.run_ms,
                                  "ratio": marble8.run_ms / constant.run_ms}

    # Octave evaluations per second per core: the marginal cost of 24 octaves over
    # none, per evaluated octave (one texture evaluation per hit: the paper scenes'
    # ambient and diffuse marble is one shared texture).
    no_noise = run(with_marbles(base, octaves=0)).run_ms
    many = run(with_marbles(base, octaves=24, tolerance=0.0)).run_ms   # all 24 evaluated
    hits = hit_fraction(constant.image, base.image.background) * 500 * 500
    cores = os.cpu_count() or 1
    # On a busy machine the difference can vanish in the noise: then there is no rate.
    rate = hits * 24 / ((many - no_noise) / 1000) / cores if many > no_noise else None
    step("targets: octave evaluations per second")
    t["octave_evals_per_s_per_core"] = {"rate": rate, "hits": hits, "cores": cores,
                                        "t24_ms": many, "t0_ms": no_noise}

    # Time to RMSE ≤ 0.01 against the converged image, per mode.
    truth = converged(base, 64, cache_dir)
    step("targets: converged reference at 500x500")
    reach = {}
    for mode in TARGET_MODES:
        curve = []
        for spp in (1, 4, 9, 16, 25, 36, 64):
            timing = run(with_marbles(base, filter=mode.filter), spp)
            rmse = image_metrics(timing.image, truth)["rmse"]
            curve.append({"spp": spp, "run_ms": timing.run_ms, "rmse": rmse})
            if rmse <= 0.01:
                break
        first = next((c for c in curve if c["rmse"] <= 0.01), None)
        reach[mode.name] = {"curve": curve, "ms_to_rmse_0.01": first["run_ms"] if first else None}
        step(f"targets: time to RMSE 0.01 ({mode.name})")
    plain, limited = reach["plain"]["ms_to_rmse_0.01"], reach["bandlimit"]["ms_to_rmse_0.01"]
    t["rmse_0.01"] = {"by_mode": reach,
                      "speedup": plain / limited if plain and limited else None}
    return t


def _crossing(rmses, target: float):
    """Where a curve's RMSEs (coarse to fine) reach ``target``: ``(i, f)``, the crossing at
    fraction ``f`` in log(RMSE) from point ``i`` to point ``i + 1`` (``(0, 0.0)``: the
    first point already reaches it); None when no point does."""
    rmses = [float(e) for e in rmses]
    if not rmses:
        return None
    if rmses[0] <= target:
        return 0, 0.0
    for i, (e0, e1) in enumerate(zip(rmses, rmses[1:])):
        if e0 > target >= e1:
            if e1 <= 0 or target <= 0:        # no logarithm: the later point
                return i, 1.0
            return i, float((np.log(e0) - np.log(target)) / (np.log(e0) - np.log(e1)))
    return None


def _log_between(a: float, b: float, f: float) -> float:
    """Linear in the logarithm from ``a`` (f = 0) to ``b`` (f = 1)."""
    if f == 0.0:
        return float(a)
    if f == 1.0 or a <= 0 or b <= 0:
        return float(b)
    return float(np.exp(np.log(a) + f * (np.log(b) - np.log(a))))


def time_to_rmse(curve, target: float) -> float | None:
    """When a mode's curve on one scene, its ``(run_ms, rmse)`` points in the order of the
    mode's settings (coarse to fine: spp up, an adaptive threshold down), reaches RMSE
    ``target``: between the first two neighbouring points that bracket it (the coarser
    above, the finer at or below), linearly in log(time) against log(RMSE); the coarsest
    (cheapest) point's time when it already reaches it; None when no point does (no
    extrapolation beyond the measured points). The settings' order, not the times', so
    that a noisy timing cannot reorder the curve (on a quiet machine they agree)."""
    curve = [(float(t), float(e)) for t, e in curve]
    at = _crossing([e for _, e in curve], target)
    if at is None:
        return None
    i, f = at
    return _log_between(curve[i][0], curve[min(i + 1, len(curve) - 1)][0], f)


def _interpolated(curve, target: float, key: str) -> float | None:
    """``key`` of a curve's runs (dicts, coarse to fine) where :func:`time_to_rmse` puts
    the crossing, interpolated as the time is (its logarithm linear in log RMSE)."""
    at = _crossing([r["rmse"] for r in curve], target)
    if at is None:
        return None
    i, f = at
    return _log_between(curve[i][key], curve[min(i + 1, len(curve) - 1)][key], f)


def times_to_plain_rmse(runs, target_spps=TARGET_SPPS) -> dict:
    """Each mode's time to plain ``spp``'s RMSE for every spp of ``target_spps``
    (:func:`time_to_rmse` on the mode's curve), per scene, and the speed-ups (plain's
    own time at that spp over the mode's), with means over the paper scenes and each
    other scene (fine veins, …) on its own.

    ``{"targets": [16, 64], "by_scene": {scene: {"16": {"rmse", "plain_ms", "by_mode":
    {mode: {"ms", "speedup", "mean_spp"} or None (never reached)}}}}, "groups": {"paper"
    or scene: {"scenes": [...], "16": {mode: {"mean_speedup", "worst_speedup",
    "mean_ms", "mean_spp", "reached", "missed": [scenes]}}}}}`` — a mode that never
    reaches the target on a scene counts as missed there: the mean is over the scenes
    it reached, and ``missed`` names the others. ``mean_spp``: the samples traced per
    pixel at the crossing (interpolated as the time)."""
    by_scene = {}
    for scene in sorted({r["scene"] for r in runs}):
        mine = [r for r in runs if r["scene"] == scene]
        modes = list(dict.fromkeys(r["mode"] for r in mine))
        out = {}
        for spp in target_spps:
            plain = next((r for r in mine if r["mode"] == "plain" and r["spp"] == spp), None)
            if plain is None:
                continue
            by_mode = {}
            for mode in modes:
                curve = sorted((r for r in mine if r["mode"] == mode), key=setting)
                ms = time_to_rmse([(r["run_ms"], r["rmse"]) for r in curve], plain["rmse"])
                by_mode[mode] = None if ms is None else {
                    "ms": ms, "speedup": plain["run_ms"] / ms,
                    "mean_spp": _interpolated(curve, plain["rmse"], "mean_spp")
                    if all("mean_spp" in r for r in curve) else None}
            out[str(spp)] = {"rmse": plain["rmse"], "plain_ms": plain["run_ms"],
                             "by_mode": by_mode}
        if out:
            by_scene[scene] = out
    groups = {}
    paper = [s for s in by_scene if is_paper_scene(s)]
    for group, members in ([("paper", paper)] if paper else []) + [
            (s, [s]) for s in by_scene if not is_paper_scene(s)]:
        summary = {"scenes": members}
        for spp in map(str, target_spps):
            at = [by_scene[s][spp] for s in members if spp in by_scene[s]]
            if not at:
                continue
            modes = list(dict.fromkeys(m for a in at for m in a["by_mode"]))
            summary[spp] = {}
            for mode in modes:
                reached = {s: by_scene[s][spp]["by_mode"].get(mode) for s in members
                           if spp in by_scene[s]}
                got = [v for v in reached.values() if v]
                spps = [v["mean_spp"] for v in got if v["mean_spp"] is not None]
                summary[spp][mode] = {
                    "reached": len(got), "of": len(reached),
                    "missed": [s for s, v in reached.items() if not v],
                    "mean_speedup": float(np.mean([v["speedup"] for v in got])) if got else None,
                    "worst_speedup": float(min(v["speedup"] for v in got)) if got else None,
                    "mean_ms": float(np.mean([v["ms"] for v in got])) if got else None,
                    "mean_spp": float(np.mean(spps)) if spps else None}
        groups[group] = summary
    return {"targets": list(target_spps), "by_scene": by_scene, "groups": groups}


def speedups_at_equal_error(runs) -> dict:
    """Per scene and mode: the fastest run of the mode whose RMSE is at most plain 16 spp's,
    and plain 16 spp's time over its time (None: no run of the mode got there)."""
    out = {}
    for scene in sorted({r["scene"] for r in runs}):
        mine = [r for r in runs if r["scene"] == scene]
        plain16 = next((r for r in mine if r["mode"] == "plain" and r["spp"] == 16), None)
        if plain16 is None:
            continue
        out[scene] = {}
        for mode in sorted({r["mode"] for r in mine} - {"plain"}):
            good = [r for r in mine if r["mode"] == mode and r["rmse"] <= plain16["rmse"]]
            best = min(good, key=lambda r: r["run_ms"]) if good else None
            out[scene][mode] = None if best is None else {
                "spp": best["spp"], "edge_spp": best.get("edge_spp"),
                "threshold": best.get("threshold"), "run_ms": best["run_ms"],
                "rmse": best["rmse"], "plain16_ms": plain16["run_ms"],
                "plain16_rmse": plain16["rmse"], "speedup": plain16["run_ms"] / best["run_ms"]}
    return out
