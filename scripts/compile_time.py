"""Compile time of the render kernel against the number of marbles, and of the paper scenes.

    ./go python scripts/compile_time.py          # prints the tables of docs/benchmarks.md

Each scene is rendered once with an empty kernel cache (a folder of its own), at 16² and
1 spp for the products of n distinct 4-octave marbles, at 500² and 4 spp for the paper
scenes; Dr.Jit's kernel history gives LLVM's backend time and the operation count. The
paper scenes are then rendered warm 15 times (median, after a sync).
"""

import os
import statistics
import subprocess
import sys
import tempfile
import time

CHILD = r'''
import statistics, sys, time
import mimarble
from mimarble import scene as S
from mimarble.runtime.machine import machine_facts
from mimarble.mitsuba.rendering.render import render_in_passes
mi, dr = mimarble.mi, mimarble.dr
what = sys.argv[1]
if what.isdigit():
    marbles = tuple(S.MarbleChannel(period=1.0 + 0.01 * k, octaves=4,
                                    ramp=((0.9, 0.9, 0.9), (1.0, 1.0, 1.0)))
                    for k in range(int(what)))
    scene = S.Scene(image=S.Image(16, 16), camera=S.Camera(eye=(0, 0, 6)),
                    lights=(S.Light((4, 4, 4)),),
                    materials={"m": S.Material("m", diffuse=S.Multiply(marbles))},
                    spheres=(S.Sphere("m"),))
    spp = 1
else:
    scene, spp = mimarble.scene.load(f"scenes/{what}.scene"), 4
loaded = mi.load_dict(mimarble.to_mitsuba(scene, spp=spp))
with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
    render_in_passes(loaded, spp)
    kernels = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
backend = sum(k.get("backend_time", 0) for k in kernels) / 1e3
operations = max(k["operation_count"] for k in kernels)
warm = ""
if not what.isdigit():
    times = []
    for _ in range(15):
        dr.sync_thread(); t = time.perf_counter(); render_in_passes(loaded, spp)
        dr.sync_thread(); times.append(time.perf_counter() - t)
    warm = f"{statistics.median(times) * 1e3:.1f}"
facts = machine_facts()
print(f"{backend:.2f}|{operations}|{warm}|{facts['processor']}, {facts['cores']} cores")
'''


def measure(what: str) -> list[str]:
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, DRJIT_CACHE_DIR=cache)
        out = subprocess.run([sys.executable, "-c", CHILD, what], env=env, check=True,
                             capture_output=True, text=True).stdout
    return out.strip().splitlines()[-1].split("|")


def main() -> None:
    machine = None
    print("| marbles multiplied | LLVM backend | operations |\n|---|---|---|")
    for n in (10, 20, 40, 80):
        backend, operations, _, machine = measure(str(n))
        print(f"| {n} | {backend} s | {operations} |", flush=True)
    print("\n| paper scene (500², 4 spp) | LLVM backend | warm render |\n|---|---|---|")
    for name in ("fig10d", "fig11a", "fig11b"):
        backend, _, warm, machine = measure(name)
        print(f"| {name} | {backend} s | {warm} ms |", flush=True)
    print(f"\n({machine}, {time.strftime('%Y-%m-%d')})")


if __name__ == "__main__":
    main()
