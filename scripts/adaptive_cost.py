"""What an adaptive sample costs against a plain one (issue 43, item 1), interleaved.

    ./go python scripts/adaptive_cost.py [SCENE …] [--size 256] [--rounds 7] [--json OUT]

For each scene (default fig11a, fig09d and the three fine-vein scenes) at ``--size``²,
point-sampled marble: plain renders at 1, 9 and 16 spp and adaptive renders (first pass
1 spp, at most 81) at three thresholds, taken in turn — plain, adaptive, plain, … — for
``--rounds`` rounds after a warm-up, each after a sync, so that a load on the machine
falls on both alike. Prints the median time of each, the time per traced sample, and the
ratio of an adaptive render's time per traced sample to plain 16 spp's (the issue's
target: ≤ 1.3), with the kernels' share (Dr.Jit's kernel history of one more render).
Per-sample ratios are the figures to quote on a shared machine; the CPU and ``uptime``'s
load are printed with them.

``--covered``: the camera narrowed until the scene's first sphere covers the whole frame
(its corners too), so that plain renders trace the sphere's lanes only, as adaptive rounds
mostly do: the ratio is then the price of a round's sample against a plain sample of the
same surface, without what plain 16 saves on the background's cheap lanes.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import statistics
import time

import mimarble
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering import adaptive
from mimarble.mitsuba.rendering.adaptive import render_adaptive
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.runtime.machine import machine_facts
from mimarble.scene.edits import filling_the_view, resized

dr, mi = mimarble.dr, mimarble.mi

SCENES = ("scenes/fig11a.scene", "scenes/fig09d.scene",
          "scenes/fine-veins/veins-p4-d4-s2.scene", "scenes/fine-veins/veins-p4-d8-s4.scene",
          "scenes/fine-veins/veins-p6-d5-s3.scene")
THRESHOLDS = (6e-4, 7.5e-5, 9e-6)
PLAIN = (1, 9, 16)


def timed(render) -> tuple[float, object]:
    dr.sync_thread()
    start = time.perf_counter()
    result = render()
    dr.sync_thread()
    return 1000 * (time.perf_counter() - start), result


def kernel_ms(render) -> float:
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        dr.sync_thread()
        render()
        dr.sync_thread()
        return sum(k["execution_time"] for k in dr.kernel_history()
                   if k["type"] == dr.KernelType.JIT)


def covered(scene):
    """``scene`` with the camera narrowed until its first sphere covers a square frame: the
    fov that just fills it vertically (``filling_the_view``), then the frame's half-diagonal
    brought inside that half-height (tan(fov/2) / 1.5: √2 would put the corners on the
    silhouette)."""
    filled = filling_the_view(scene)
    fov = 2 * math.degrees(math.atan(math.tan(math.radians(filled.camera.fov) / 2) / 1.5))
    return dataclasses.replace(filled, camera=dataclasses.replace(filled.camera, fov=fov))


def measure(path: str, size: int, rounds: int, cover: bool = False) -> dict:
    scene = resized(mimarble.scene.load(path), size)
    if cover:
        scene = covered(scene)
    loaded = mi.load_dict(to_mitsuba(scene, spp=1))
    pixels = size * size
    renders = {f"plain {spp}": (lambda spp=spp: render_in_passes(loaded, spp)) for spp in PLAIN}
    renders.update({f"adaptive {t:g}": (lambda t=t: render_adaptive(loaded, 1, t, 81))
                    for t in THRESHOLDS})
    samples = {f"plain {spp}": spp * pixels for spp in PLAIN}
    for name, render in renders.items():               # compile, and the samples traced
        result = render()
        render()
        if name.startswith("adaptive"):
            samples[name] = result.traced
    times = {name: [] for name in renders}
    for _ in range(rounds):
        for name, render in renders.items():             # interleaved
            times[name].append(timed(render)[0])
    plain16 = statistics.median(times["plain 16"]) / samples["plain 16"]
    rows = {}
    for name, render in renders.items():
        ms = statistics.median(times[name])
        rows[name] = {"ms": ms, "spp": samples[name] / pixels,
                      "ns_per_sample": 1e6 * ms / samples[name],
                      "ratio_to_plain16": ms / samples[name] / plain16,
                      "kernel_ms": kernel_ms(render)}
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", default=SCENES)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--json")
    parser.add_argument("--covered", action="store_true",
                        help="the camera narrowed until the first sphere covers the frame")
    parser.add_argument("--doubt-kernel", action="store_true",
                        help="the first pass traces the marbles' doubts (issue 43's first code)")
    args = parser.parse_args()
    adaptive.DOUBT_KERNEL = args.doubt_kernel
    facts = machine_facts()
    cpu = f"{facts.get('processor', '?')} ({facts.get('llvm_target', {}).get('cpu', '?')})"
    print(f"{cpu}; load {os.getloadavg()}; {args.size}², medians of {args.rounds} "
          f"interleaved rounds{'; the sphere covering the frame' if args.covered else ''}")
    results = {"machine": facts, "load_before": os.getloadavg(), "size": args.size,
               "covered": args.covered,
               "rounds": args.rounds, "scenes": {}}
    for path in args.scenes:
        rows = measure(path, args.size, args.rounds, args.covered)
        results["scenes"][path] = rows
        print(path)
        for name, row in rows.items():
            print(f"  {name:18} {row['ms']:8.1f} ms  {row['spp']:6.2f} spp  "
                  f"{row['ns_per_sample']:6.1f} ns/sample  ×{row['ratio_to_plain16']:.2f} "
                  f"plain 16's  kernels {row['kernel_ms']:.1f} ms")
    results["load_after"] = os.getloadavg()
    print(f"load after {results['load_after']}")
    if args.json:
        with open(args.json, "w") as out:
            json.dump(results, out, indent=1)


if __name__ == "__main__":
    main()
