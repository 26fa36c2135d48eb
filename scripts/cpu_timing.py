"""The README's 500² timings and the noise rate on this CPU, with and without +fast-gather.

    ./go python scripts/cpu_timing.py [--repeats 9]

Each LLVM target setting runs in its own process (the target is fixed before the
first kernel): MIMARBLE_LLVM_TARGET=default (Dr.Jit's detection) and unset
(mimarble's choice, mimarble/runtime/llvm_target.py). Medians of warm renders after a sync;
the machine is named on the first line. Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_CHILD = r"""
import json, sys, time, numpy as np, mimarble
from mimarble.runtime.machine import machine_facts, machine_line
dr, mi = mimarble.dr, mimarble.mi
repeats = int(sys.argv[1])
def median(f):
    f(); dr.sync_thread()
    times = []
    for _ in range(repeats):
        dr.sync_thread(); t = time.perf_counter(); f(); dr.sync_thread()
        times.append(time.perf_counter() - t)
    return sorted(times)[len(times) // 2]
out = {"machine": machine_line(machine_facts())}
for name in ("fig10a", "fig10d", "fig11a", "fig11b"):
    scene = mimarble.scene.load(f"scenes/{name}.scene")
    for spp in (1, 4):
        ms = mi.load_dict(mimarble.to_mitsuba(scene, spp=spp))
        out[f"{name} {spp} spp"] = 1000 * median(lambda: dr.eval(mi.render(ms)))
pts = np.random.default_rng(1).uniform(-50, 50, (2_000_000, 3)).astype(np.float32)
p = mi.Point3f(*(mi.Float(pts[:, a]) for a in range(3)))
seconds = median(lambda: dr.eval(mimarble.texture.noise.fractal3(p, 8)))
out["noise M octave-evals/s/core"] = 2e6 * 8 / seconds / (__import__("os").cpu_count() or 1) / 1e6
print(json.dumps(out))
"""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9)
    args = parser.parse_args()
    results = {}
    for label, setting in (("Dr.Jit's default", "default"), ("mimarble (+fast-gather)", None)):
        env = {k: v for k, v in os.environ.items() if k != "MIMARBLE_LLVM_TARGET"}
        if setting:
            env["MIMARBLE_LLVM_TARGET"] = setting
        run = subprocess.run([sys.executable, "-c", _CHILD, str(args.repeats)], cwd=ROOT, env=env,
                             capture_output=True, text=True, check=True)
        results[label] = json.loads(run.stdout.strip().splitlines()[-1])
    labels = list(results)
    print(f"Machine: {results[labels[-1]]['machine']}\n")
    print(f"| figure | {' | '.join(labels)} | ratio |\n|---|---|---|---|")
    for key in results[labels[0]]:
        if key == "machine":
            continue
        a, b = (results[label][key] for label in labels)
        unit = "" if "noise" in key else " ms"
        print(f"| {key} | {a:.1f}{unit} | {b:.1f}{unit} | {b / a if 'noise' in key else a / b:.2f}× |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
