"""Every kernel of one adaptive render, and what a neighbourhood's gathers cost (issue 43).

    ./go python scripts/adaptive_kernels.py SCENE [--threshold 2.5e-3] [--size 256]
    ./go python scripts/adaptive_kernels.py --neighbourhood [--size 256]

The first form: the scene point-sampled at ``--size``², three warm adaptive renders (first
pass 1 spp, at most 81), then the median of 7 of the render's wall time and of its kernels'
total, and one render's kernels in launch order (Dr.Jit's kernel history, turned on before
the first render: JIT flags are part of a recording's key) — size, operations, ms.
The second: a 3×3 neighbourhood (least and largest shape id, least, largest and summed
colour) of every pixel of a ``--size``² image in Morton order, read with four gathers a
neighbour (a UInt32 and a Color3f) or one packet gather of four float32
(``dr.gather(mi.Array4f, flat, index)``), alternately; medians of 21 of the kernels' time.
Prints the CPU and the load.
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

import mimarble
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering import adaptive
from mimarble.runtime.machine import machine_facts
from mimarble.scene.edits import resized

dr, mi = mimarble.dr, mimarble.mi


def kernels_since() -> list:
    """The JIT kernels launched since the last call (syncs first)."""
    dr.sync_thread()
    return [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]


def render_kernels(path: str, threshold: float, size: int) -> None:
    loaded = mi.load_dict(to_mitsuba(resized(mimarble.scene.load(path), size), spp=1))
    render = lambda: adaptive.render_adaptive(loaded, 1, threshold, 81)
    for _ in range(3):
        render()
    walls, totals, listings = [], [], []
    for _ in range(7):
        kernels_since()
        start = time.perf_counter()
        result = render()
        dr.sync_thread()
        walls.append(1000 * (time.perf_counter() - start))
        listing = kernels_since()
        totals.append(sum(k["execution_time"] for k in listing))
        listings.append(listing)
    print(f"{path}, {size}², threshold {threshold:g}: {result.traced / size ** 2:.2f} samples "
          f"a pixel traced; wall {statistics.median(walls):.2f} ms, kernels "
          f"{statistics.median(totals):.2f} ms (medians of 7); one render's kernels:")
    for k in listings[len(listings) // 2]:
        print(f"  {k['size']:8d} lanes {k['operation_count']:5d} ops {k['execution_time']:7.3f} ms")


def neighbourhood(size: int) -> None:
    rng = np.random.default_rng(1)
    count = size * size
    pixels = mi.UInt32(adaptive.morton_order(size, size))
    colour = mi.Color3f(*(mi.Float(rng.random(count).astype(np.float32)) for _ in range(3)))
    shape = mi.UInt32(rng.integers(0, 3, count).astype(np.uint32))
    packed = dr.ravel(mi.Array4f(colour.x, colour.y, colour.z,
                                 dr.reinterpret_array(mi.Float, shape)), order="F")
    dr.eval(pixels, colour, shape, packed)

    def read(packets: bool):
        least = most = low = high = total = None
        for around in adaptive._neighbours(pixels, size, size):
            if packets:
                mean, first = adaptive._read_neighbour(packed, around)
            else:
                mean, first = dr.gather(mi.Color3f, colour, around), \
                    dr.gather(mi.UInt32, shape, around)
            if least is None:
                least, most, low, high, total = first, first, mean, mean, mean
            else:
                least, most = dr.minimum(least, first), dr.maximum(most, first)
                low, high, total = dr.minimum(low, mean), dr.maximum(high, mean), total + mean
        dr.eval(least, most, low, high, total)

    times = {"four gathers a neighbour": [], "one packet gather a neighbour": []}
    for _ in range(3):
        read(False), read(True)
    for _ in range(21):
        for name, packets in zip(times, (False, True)):
            kernels_since()
            read(packets)
            times[name].append(sum(k["execution_time"] for k in kernels_since()))
    for name, values in times.items():
        print(f"{size}² pixels' 3×3 neighbourhoods, {name}: {statistics.median(values):.3f} ms")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?")
    parser.add_argument("--threshold", type=float, default=2.5e-3)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--neighbourhood", action="store_true")
    args = parser.parse_args()
    if not args.neighbourhood and args.scene is None:
        parser.error("give a SCENE or --neighbourhood")
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    facts = machine_facts()
    print(f"{facts.get('processor', '?')} ({(facts.get('llvm_target') or {}).get('cpu', '?')}); "
          f"load {os.getloadavg()}")
    if args.neighbourhood:
        neighbourhood(args.size)
    else:
        render_kernels(args.scene, args.threshold, args.size)
    print("load after", os.getloadavg())


if __name__ == "__main__":
    main()
