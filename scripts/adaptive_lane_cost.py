"""A round's lanes against plain lanes on the same pixels (issue 43): where the samples go, or
what a round adds.

    ./go python scripts/adaptive_lane_cost.py [SCENE …] [--size 256] [--threshold 6e-4]
                                              [--rounds 9]

For each scene (default fig11a and veins-p4-d8-s4), point-sampled: an adaptive render at
``--threshold`` (first pass 1 spp, at most 81) gives the pixel list of its first round's
pass into the 3×3 grid (the pixels it refines, in Morton order). Then, taken in turn for
``--rounds`` rounds after a warm-up, each pass alone after a sync, Dr.Jit's kernel history
on from the start (JIT flags are part of a recording's key):

- *round*: that pass as the render traces it (8 new strata a pixel, with estimates);
- *round, rows*: the same pass over the same pixels in row order;
- *plain 9 / 16 there*: the plain kernel (no estimates) at 9 and 16 stratum centres over
  the same pixels;
- *plain 16 elsewhere*: the plain kernel at 16 over every other pixel;
- *plain 16 image*: a plain 16-spp render of the whole image (``render_in_passes``).

Prints the main kernel's time per lane (the kernel of most operations × lanes; medians, ns)
and the pass's whole time per lane (sync to sync), with the CPU and the load: the round
against plain 16 on the same pixels is what the round adds; plain 16 on them against plain
16 over the image is where the samples go.
"""
from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np

import mimarble
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering import adaptive, passes
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.scene.edits import resized

sys.path.insert(0, str(Path(__file__).resolve().parent))
from adaptive_pass_cost import run_command_line  # noqa: E402  (the sibling script)

dr, mi = mimarble.dr, mimarble.mi


def first_round_pixels(loaded, threshold: float):
    """The pixel list (UInt32, Morton order) and count of the first round's pass into the
    3×3 grid of an adaptive render of ``loaded``."""
    taken = []
    trace_sums = adaptive.trace_sums

    def watched(target, spp, pixels, count, **kwargs):
        if kwargs.get("parent_axis") == 1 and not taken:
            taken.append((mi.UInt32(pixels), count))
        return trace_sums(target, spp, pixels, count, **kwargs)

    adaptive.trace_sums = watched
    try:
        adaptive.render_adaptive(loaded, 1, threshold, 81)
    finally:
        adaptive.trace_sums = trace_sums
    return taken[0]


def timed(run) -> tuple[float, float, int]:
    """(main kernel ms, whole ms, lanes of the main kernel) of one call of ``run``."""
    dr.sync_thread()
    dr.kernel_history()
    start = time.perf_counter()
    run()
    dr.sync_thread()
    whole = 1000 * (time.perf_counter() - start)
    kernels = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    main = max(kernels, key=lambda k: k["size"] * k["operation_count"])
    return main["execution_time"], whole, main["size"]


def measure(path: str, size: int, threshold: float, rounds: int) -> None:
    scene = resized(mimarble.scene.load(path), size)
    loaded = mi.load_dict(to_mitsuba(scene, spp=1))
    target = passes.Target.of(loaded, "whitted", adaptive.LOADED.parameters_of(loaded))
    facts = adaptive.scene_facts(target.scene, target.params)
    pixels, count = first_round_pixels(loaded, threshold)
    listed = pixels.numpy()[:count]
    rows = mi.UInt32(np.sort(listed))
    others = np.setdiff1d(np.arange(size * size, dtype=np.uint32), listed)

    def pass_over(pixel_list, number, spp, **kwargs):
        def run():
            for part in passes.trace_sums(target, spp, pixel_list, number, key=facts,
                                          **kwargs):
                dr.eval(part.sums)
        return run

    round_pass = dict(with_estimates=True, doubts=False, parent_axis=1, per_cell=8)
    runs = {
        "round": pass_over(pixels, count, 9, **round_pass),
        "round, rows": pass_over(rows, count, 9, **round_pass),
        "plain 9 there": pass_over(pixels, count, 9, with_estimates=False),
        "plain 16 there": pass_over(pixels, count, 16, with_estimates=False),
        "plain 16 elsewhere": pass_over(mi.UInt32(others), len(others), 16,
                                        with_estimates=False),
        "plain 16 image": lambda: render_in_passes(loaded, 16),
    }
    for run in runs.values():                  # recorded, then replayed once
        run(), run()
    times = {name: [] for name in runs}
    for _ in range(rounds):
        for name, run in runs.items():
            times[name].append(timed(run))
    print(f"{path}, {size}², threshold {threshold:g}: the first round refines {count} pixels "
          f"({100 * count / size ** 2:.0f} %)")
    image = statistics.median(1e6 * t[0] / t[2] for t in times["plain 16 image"])
    for name, rows_of in times.items():
        kernel = statistics.median(1e6 * t[0] / t[2] for t in rows_of)
        whole = statistics.median(1e6 * t[1] / t[2] for t in rows_of)
        print(f"  {name:20} main kernel {kernel:6.1f} ns a lane (×{kernel / image:.2f} plain 16 "
              f"image's)  whole pass {whole:6.1f} ns a lane")


if __name__ == "__main__":
    run_command_line(__doc__.splitlines()[0], measure)
