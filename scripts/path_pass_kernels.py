"""Full-width kernels, recordings and time of a replayed path-mode pass, per scene: whether a
pass traces its samples once (one kernel as wide as its lanes) and records once.

    ./go python scripts/path_pass_kernels.py [--size 160] [--spp 16] [--repeats 5] SCENE...

Each scene is loaded once and rendered ``repeats + 1`` times in path mode (seeds 0, 1, …;
the first records the pass and is left out); Dr.Jit's kernel history (switched on before the
first render: JIT flags are part of a recording's key) counts the JIT kernels of exactly
``size² · spp`` lanes per render and sums their execution time; the wall time of a render
call (it returns a synced image). Prints one line per scene: median wall s, the full-width
kernels per render, their summed execution ms (median), and the recordings made.
"""
import argparse
import statistics
import time

import mimarble
from mimarble.mitsuba.rendering import passes
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.runtime import packaged_scenes
from mimarble.scene.edits import resized

dr, mi = mimarble.dr, mimarble.mi


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="+")
    parser.add_argument("--size", type=int, default=160)
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    lanes = args.size * args.size * args.spp
    for name in args.scenes:
        scene = resized(mimarble.scene.load(packaged_scenes.resolve(name)), args.size)
        loaded = mi.load_dict(mimarble.to_mitsuba(scene, mode="path", spp=args.spp))
        before = passes.traced_pass.recordings
        walls, counts, kernel_ms = [], [], []
        for seed in range(args.repeats + 1):
            dr.kernel_history()
            start = time.perf_counter()
            render_in_passes(loaded, args.spp, "path", seed=seed)
            wall = time.perf_counter() - start
            wide = [k for k in dr.kernel_history()
                    if k["type"] == dr.KernelType.JIT and k["size"] == lanes]
            if seed:
                walls.append(wall)
                counts.append(len(wide))
                kernel_ms.append(sum(k["execution_time"] for k in wide))
        print(f"{name:32} wall {statistics.median(walls):8.3f} s  kernels/render "
              f"{max(counts)}  kernel time {statistics.median(kernel_ms):9.1f} ms  "
              f"recordings {passes.traced_pass.recordings - before}", flush=True)


if __name__ == "__main__":
    main()
