"""Issue 24, item 2: the pixel's phase as a Gaussian (Heitz et al. 2014) against the box.

For fig11a and fig09d at 256², 1 spp, renders each marble with

    none            the colour at the point
    prefilter       the box of mimarble/texture/prefilter.py (filter prefilter)
    gaussian        GaussianPrefilter() (scripts/experiments/phase_gaussian.py): one Gaussian of
                    variance (a² + b²)/12 + σ², by its Fourier series, 8 harmonics; one
                    box of the same variance where it is too narrow for them
    parallelogram   GaussianPrefilter(model="parallelogram"): the linear phase's two
                    boxes exactly, convolved with the left-out octaves' Gaussian σ²

and variants of the last two (:data:`CONFIGURATIONS`: harmonics, the narrow fallback,
the prefilter margin, a scaled linear variance), and measures against the float64
reference at 256 spp (``mimarble.bench.timing.converged``, cached) the RMSE inside the
silhouettes (pixels whose 3×3 neighbourhood sees one shape, ``edge_mask`` at 16 spp)
and over the whole image, and the render time: the median of 5 warm
``render_in_passes`` after a ``dr.sync_thread()``, taken in ``--rounds`` rounds that
visit every configuration in turn (the machine may be shared), the median of the
rounds' medians reported; beside it the process's CPU time per render (all threads:
what the render costs whatever else runs) and the JIT kernels' own execution time
(Dr.Jit's kernel history). The costs again at 1024² (``--cost-size``), where the
filters' differences stand out of the scheduling noise; and fig11a with 2 and 4 octaves,
unlit, where the phase is near linear across a pixel (:func:`few_octaves`); and the
averages' own kernels, without the noise (:func:`phase_kernels`).

The experimental filter is installed by this script alone: ``mimarble.texture.filters.choose``
is wrapped so that a marble loaded with ``filter prefilter`` gets a GaussianPrefilter
(marble.py calls ``pixel_filter.choose`` when its parameters change). Replay of recorded
passes is left on (each loaded scene records its own); MIMARBLE_FREEZE=0 in the
environment turns it off for all modes alike.

    ./go python scripts/experiments/phase_distribution_trial.py [-o docs/bench/phase-distribution.json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import mimarble
from mimarble.runtime import files
from mimarble.texture import filters as pixel_filter
from mimarble import scene as scene_language
from mimarble.bench.timing import converged
from mimarble.runtime.machine import machine_facts
from mimarble.mitsuba.rendering import replay
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.mitsuba.rendering.silhouettes import edge_mask
from mimarble.mitsuba.translate.scene_dict import to_mitsuba
from mimarble.scene.edits import resized

sys.path.insert(0, str(Path(__file__).resolve().parent))
import phase_gaussian  # noqa: E402  (this folder's: the experiment, not part of the package)

dr, mi = mimarble.dr, mimarble.mi

ROOT = Path(__file__).resolve().parents[2]
SCENES = ("fig11a", "fig09d")
SIZE, SPP, CONVERGED_SPP, REPEATS, ROUNDS = 256, 1, 256, 5, 5
#: The cost measurement: at 1024² a pass has 16× the lanes of 256², so the filters' few
#: percent stand out of the fixed costs and a shared machine's scheduling noise.
COST_SIZE = 1024
#: The few-octave check (:func:`few_octaves`).
FEW_OCTAVES = (2, 4)
FEW_OCTAVE_CONFIGURATIONS = ("none", "prefilter", "gaussian", "gaussian-narrow-prefilter",
                             "parallelogram", "parallelogram-narrow-prefilter")
COST_CONFIGURATIONS = ("none", "prefilter", "gaussian", "gaussian-h16",
                       "gaussian-narrow-prefilter", "parallelogram")

#: name -> (scene filter, GaussianPrefilter keywords or None)
CONFIGURATIONS = {
    "none": ("none", None),
    "prefilter": ("prefilter", None),
    # The choice: GaussianPrefilter's defaults (8 harmonics, one box where narrow).
    "gaussian": ("prefilter", {}),
    "gaussian-h16": ("prefilter", {"harmonics": 16}),
    "gaussian-h32": ("prefilter", {"harmonics": 32}),
    "gaussian-narrow-prefilter": ("prefilter", {"narrow": "prefilter"}),
    "gaussian-margin1": ("prefilter", {"margin": 1.0}),
    "gaussian-margin0": ("prefilter", {"margin": 0.0}),
    "gaussian-linear-x0.75": ("prefilter", {"linear_variance_scale": 0.75}),
    "gaussian-linear-x1.5": ("prefilter", {"linear_variance_scale": 1.5}),
    "gaussian-linear-x2": ("prefilter", {"linear_variance_scale": 2.0}),
    "parallelogram": ("prefilter", {"model": "parallelogram"}),
    "parallelogram-narrow-prefilter": ("prefilter", {"model": "parallelogram",
                                                     "narrow": "prefilter"}),
    "parallelogram-margin1": ("prefilter", {"model": "parallelogram", "margin": 1.0}),
    "parallelogram-margin0": ("prefilter", {"model": "parallelogram", "margin": 0.0}),
}

_original_choose = pixel_filter.choose


def installing(keywords):
    """``pixel_filter.choose`` that gives ``prefilter`` marbles a GaussianPrefilter made
    with ``keywords`` (None: the library's own choice)."""
    def choose(name, stripe, ramp):
        chosen = _original_choose(name, stripe, ramp)
        if keywords is not None and type(chosen) is pixel_filter.Prefilter:
            return phase_gaussian.GaussianPrefilter(stripe, ramp, **keywords)
        return chosen
    return choose


def load(small, filter_name, keywords):
    """``small`` loaded with every marble's filter ``filter_name``, the Gaussian installed
    per ``keywords``."""
    pixel_filter.choose = installing(keywords)
    try:
        return mi.load_dict(to_mitsuba(small, spp=SPP, filter=filter_name))
    finally:
        pixel_filter.choose = _original_choose


def warm_renders(mitsuba_scene, repeats: int) -> tuple[list, list]:
    """``repeats`` renders, each after a ``dr.sync_thread()``: (wall-clock ms, CPU ms of
    the process, all its threads: what the render costs, whatever else the machine runs)."""
    wall, cpu = [], []
    for _ in range(repeats):
        dr.sync_thread()
        start, start_cpu = time.perf_counter(), time.process_time()
        render_in_passes(mitsuba_scene, SPP)
        wall.append(1000 * (time.perf_counter() - start))
        cpu.append(1000 * (time.process_time() - start_cpu))
    return wall, cpu


def kernel_times(mitsuba_scene, repeats: int) -> list:
    """The JIT kernels' own execution time per render (Dr.Jit's kernel history), ms:
    less disturbed by a shared machine's scheduling than the wall time."""
    times = []
    for _ in range(repeats):
        dr.sync_thread()
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
            render_in_passes(mitsuba_scene, SPP)
            history = dr.kernel_history()
        times.append(sum(k["execution_time"] for k in history
                         if k["type"] == dr.KernelType.JIT))
    return times


def marbles(mitsuba_scene):
    """The scene's marble textures (through ``mi.traverse``'s object hierarchy)."""
    from mimarble.mitsuba.plugins.marble import Marble
    seen = {}
    for node in mi.traverse(mitsuba_scene).hierarchy:
        if isinstance(node, Marble):
            seen[id(node)] = node
    return list(seen.values())


def timed_rounds(loaded: dict, rounds: int, size: int) -> dict:
    """name -> timings of its loaded scene, in interleaved rounds (the machine is shared:
    a slow spell then falls on every configuration alike): each round REPEATS wall-clock
    renders then REPEATS with the kernel history, for every configuration in turn."""
    timings = {name: {"size": size, "rounds_ms": [], "cpus_ms": [], "kernels_ms": []}
               for name in loaded}
    for _ in range(rounds):
        for name, mitsuba_scene in loaded.items():
            wall, cpu = warm_renders(mitsuba_scene, REPEATS)
            timings[name]["rounds_ms"].append(wall)
            timings[name]["cpus_ms"].extend(cpu)
            timings[name]["kernels_ms"].extend(kernel_times(mitsuba_scene, REPEATS))
    for t in timings.values():
        medians = [statistics.median(r) for r in t["rounds_ms"]]
        t.update(run_ms=statistics.median(medians), round_medians_ms=medians,
                 cpu_ms=statistics.median(t["cpus_ms"]),
                 kernel_ms=statistics.median(t["kernels_ms"]), kernel_min_ms=min(t["kernels_ms"]))
    return timings


def few_octaves(configurations, octaves_list=FEW_OCTAVES) -> list:
    """fig11a with few octaves, unlit (the image is the texture), 256², 1 spp, interior
    RMSE against this renderer's own 256 spp with filter none: where the phase is close
    to linear across a pixel, the regime the box with two Gauss points is exact in."""
    import dataclasses
    from mimarble.scene.edits import with_marbles
    out = []
    base = resized(scene_language.load(str(ROOT / "scenes" / "fig11a.scene")), SIZE)
    for octaves in octaves_list:
        scene = dataclasses.replace(with_marbles(base, octaves=octaves), lights=(),
                                    ambient=(1.0, 1.0, 1.0))
        truth = render_in_passes(mi.load_dict(to_mitsuba(scene, spp=256, filter="none")), 256)
        interior = ~edge_mask(mi.load_dict(to_mitsuba(scene, spp=16)), 16)
        for name in configurations:
            image = render_in_passes(load(scene, *CONFIGURATIONS[name]), SPP)
            error = float(np.sqrt(np.mean(np.square(image - truth)[interior])))
            out.append({"scene": "fig11a", "octaves": octaves, "unlit": True,
                        "configuration": name, "interior_rmse": error})
            print(f"fig11a, {octaves} octaves, unlit: {name:30s} interior {error:.5f}", flush=True)
    return out


def phase_kernels(lanes: int = 1 << 21, repeats: int = 15) -> dict:
    """The averages alone, without the noise: the kernel time (min of ``repeats``, ms) of
    each over ``lanes`` random phases and deviations (abs_sine, the Fig. 5 ramp): the
    colour at the point, one box (PhaseAverage), the prefilter's two, the Gaussian series
    at 8/16/32 harmonics, and the series with one box blended in (GaussianPrefilter's)."""
    from mimarble.texture.prefilter import PhaseAverage
    from mimarble.texture.ramp import Ramp, ramp_storage
    from mimarble.scene.model import FIG5_RAMP
    from mimarble.texture.stripes import STRIPES
    stripe, ramp = STRIPES["abs_sine"], Ramp(ramp_storage(FIG5_RAMP))
    rng = np.random.default_rng(0)
    phase = mi.Float(rng.uniform(-20, 20, lanes))
    std = mi.Float(rng.uniform(0.0, 0.15, lanes))
    box = PhaseAverage(stripe, ramp)
    series = {h: phase_gaussian.PhaseGaussian(stripe, ramp, h, box=box) for h in (8, 16, 32)}
    width, across = np.sqrt(12.0) * std, 0.3 * std

    def two_boxes():
        return 0.5 * (box(phase - across, width)[0] + box(phase + across, width)[0])

    kernels = {"point": lambda: ramp(stripe.t(phase)),
               "one box": lambda: box(phase, width)[0],
               "two boxes (prefilter)": two_boxes}
    for h, gaussian in series.items():
        kernels[f"series, {h} harmonics"] = (lambda g=gaussian: g.series(phase, std * std)[0])
    kernels["series (8) + one box, blended"] = lambda: series[8](phase, std)[0]
    out = {}
    for name, kernel in kernels.items():
        times = []
        for _ in range(repeats):
            dr.sync_thread()
            with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
                dr.eval(kernel())
                dr.sync_thread()
                history = dr.kernel_history()
            times.append(sum(k["execution_time"] for k in history
                             if k["type"] == dr.KernelType.JIT))
        out[name] = min(times)
        print(f"{lanes} lanes: {name:32s} {out[name]:7.2f} ms", flush=True)
    return {"lanes": lanes, "repeats": repeats, "min_kernel_ms": out}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default=str(ROOT / "docs/bench/phase-distribution.json"))
    parser.add_argument("--configurations", nargs="*", default=list(CONFIGURATIONS),
                        choices=list(CONFIGURATIONS))
    parser.add_argument("--scenes", nargs="*", default=list(SCENES))
    parser.add_argument("--rounds", type=int, default=ROUNDS,
                        help="interleaved timing rounds of REPEATS renders each")
    parser.add_argument("--cost-size", type=int, default=COST_SIZE,
                        help="also time the configurations at this size, where the kernels "
                             "run long enough to tell their costs apart (0: not)")
    parser.add_argument("--cost-configurations", nargs="*", default=list(COST_CONFIGURATIONS),
                        choices=list(CONFIGURATIONS))
    parser.add_argument("--no-few-octaves", dest="few_octaves", action="store_false",
                        help="skip the few-octave check (fig11a unlit at 2 and 4 octaves)")
    parser.add_argument("--no-phase-kernels", dest="phase_kernels", action="store_false",
                        help="skip timing the averages alone (without the noise)")
    args = parser.parse_args(argv)
    mi.set_variant("llvm_ad_rgb")
    results = {"machine": machine_facts(), "date": time.strftime("%Y-%m-%d", time.gmtime()),
               "size": SIZE, "spp": SPP, "converged_spp": CONVERGED_SPP, "repeats": REPEATS,
               "rounds": args.rounds, "replay": replay.enabled(),
               "configurations": {name: {"filter": f, "gaussian": k}
                                  for name, (f, k) in CONFIGURATIONS.items()
                                  if name in args.configurations},
               "harmonics_default": phase_gaussian.HARMONICS,
               "truncation": phase_gaussian.TRUNCATION, "runs": [], "cost": []}
    for scene_name in args.scenes:
        scene = scene_language.load(str(ROOT / "scenes" / f"{scene_name}.scene"))
        small = resized(scene, SIZE)
        truth = converged(small, CONVERGED_SPP, files.cache_folder())
        interior = ~edge_mask(mi.load_dict(to_mitsuba(small, spp=16)), 16)
        loaded, runs = {}, {}
        for name in args.configurations:
            mitsuba_scene = load(small, *CONFIGURATIONS[name])
            start = time.perf_counter()
            image = render_in_passes(mitsuba_scene, SPP)       # compile (and record)
            first_ms = 1000 * (time.perf_counter() - start)
            squared = np.square(np.asarray(image, np.float64) - truth)
            loaded[name] = mitsuba_scene
            runs[name] = {
                "scene": scene_name, "configuration": name,
                "filter_classes": sorted({type(t.pixel_filter).__name__
                                          for t in marbles(mitsuba_scene)}),
                "interior_rmse": float(np.sqrt(np.mean(squared[interior]))),
                "rmse": float(np.sqrt(np.mean(squared))), "first_render_ms": first_ms}
        for name, timing in timed_rounds(loaded, args.rounds, SIZE).items():
            run = {**runs[name], **timing}
            results["runs"].append(run)
            print(f"{scene_name:7s} {name:24s} interior {run['interior_rmse']:.5f}  "
                  f"whole {run['rmse']:.5f}  {run['run_ms']:6.1f} ms  cpu {run['cpu_ms']:6.1f} ms  kernels "
                  f"{run['kernel_ms']:6.2f} (min {run['kernel_min_ms']:6.2f}) ms", flush=True)
        del loaded
        if args.cost_size:
            large = resized(scene, args.cost_size)
            loaded = {name: load(large, *CONFIGURATIONS[name])
                      for name in args.cost_configurations}
            for mitsuba_scene in loaded.values():
                render_in_passes(mitsuba_scene, SPP)
            for name, timing in timed_rounds(loaded, args.rounds, args.cost_size).items():
                results["cost"].append({"scene": scene_name, "configuration": name, **timing})
                print(f"{scene_name:7s} {name:24s} {args.cost_size}²: {timing['run_ms']:7.1f} ms"
                      f"  cpu {timing['cpu_ms']:7.1f} ms"
                      f"  kernels {timing['kernel_ms']:7.2f} (min {timing['kernel_min_ms']:7.2f})"
                      f" ms", flush=True)
            del loaded
    if args.phase_kernels:
        results["phase_kernels"] = phase_kernels()
    if args.few_octaves:
        results["few_octaves"] = few_octaves(FEW_OCTAVE_CONFIGURATIONS)
    Path(args.output).write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
