"""The first pass of an adaptive render with and without whitted's doubt kernel (issue 43).

    ./go python scripts/adaptive_first_pass.py [SCENE …] [--size 256] [--rounds 9] [--filters …]

For each scene, point-sampled and prefiltered: the first pass and its estimates alone (a
threshold no pixel is above, 1 spp)
traced with the doubt kernel and with the plain one (the doubt then read from the image),
and a plain 1-spp render, taken in turn after a sync; prints the medians of the whole call
and of its kernels (Dr.Jit's kernel history), with the CPU and the load.
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

import mimarble
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering import adaptive
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.runtime.machine import machine_facts
from mimarble.scene.edits import resized, with_marbles

dr, mi = mimarble.dr, mimarble.mi


def first_pass(loaded, doubt_kernel: bool):
    """The first pass with the doubt kernel, or without it: the doubt from the image, also
    where ``traces_doubts`` would choose the kernel (a prefiltered marble), so that the two
    differ in every scene."""
    def render():
        decide = adaptive.traces_doubts
        adaptive.traces_doubts = lambda scene: doubt_kernel
        try:
            return adaptive.render_adaptive(loaded, 1, 1e9, 81)   # no pixel refined
        finally:
            adaptive.traces_doubts = decide
    return render


def timed(render) -> tuple[float, float]:
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        dr.sync_thread()
        start = time.perf_counter()
        render()
        dr.sync_thread()
        wall = 1000 * (time.perf_counter() - start)
        kernels = sum(k["execution_time"] for k in dr.kernel_history()
                      if k["type"] == dr.KernelType.JIT)
    return wall, kernels


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", default=["scenes/fig11a.scene",
                                                      "scenes/fine-veins/veins-p4-d8-s4.scene"])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--filters", nargs="+", default=["none", "prefilter"])
    args = parser.parse_args()
    facts = machine_facts()
    print(f"{facts.get('processor', '?')} ({facts.get('llvm_target', {}).get('cpu', '?')}); "
          f"load {os.getloadavg()}; {args.size}², medians of {args.rounds}")
    for path in args.scenes:
        for filter_name in args.filters:
            scene = with_marbles(resized(mimarble.scene.load(path), args.size), filter=filter_name)
            loaded = mi.load_dict(to_mitsuba(scene, spp=1))
            renders = {"plain 1 spp": lambda: render_in_passes(loaded, 1),
                       "first pass, doubt kernel": first_pass(loaded, True),
                       "first pass, doubt from the image": first_pass(loaded, False)}
            for render in renders.values():
                render(), render()
            times = {name: [] for name in renders}
            for _ in range(args.rounds):
                for name, render in renders.items():
                    times[name].append(timed(render))
            print(f"{path} filter {filter_name}")
            for name, pairs in times.items():
                wall = statistics.median(p[0] for p in pairs)
                kernels = statistics.median(p[1] for p in pairs)
                print(f"  {name:34} {wall:6.2f} ms, kernels {kernels:6.2f} ms")
    print(f"load after {os.getloadavg()}")


if __name__ == "__main__":
    main()
