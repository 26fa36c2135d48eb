"""The fast preview against the random walk (issue 40): time at equal spp, and the preview's
error against a converged walk.

    ./go python scripts/preview_speed.py [--scenes A B …] [--extra 2] [--shrink K] [-o OUT_DIR]
    ./go python scripts/preview_speed.py -o OUT_DIR --pair carrara docs/gallery/preview-vs-walk.png

For each scene (default: every scene of scenes/translucent/) at its own size and spp (with
``--shrink K``: each side over K and the spp over K², a K⁴-th of the work, each mode's
cost a sample kept), through ``mimarble.render`` as a user renders: one render of each
mode at the measured size and spp first, twice (the kernels compiled, the recordings made:
a recording is keyed on the spp, and made again at the second call), then two pairs of renders alternating ``--mode preview``
and ``--mode path`` (the walk) at that spp, seeds 1 and 2, so that other work on the
machine slows both alike; then the walk at ``--extra`` × the spp (seed 100; none with 0).
The converged walk W is the mean of all the walk's samples (4 + extra times the spp, the
warm renders' included). Reports the median seconds of each mode and their ratio,
wall-clock and the process's CPU seconds (both modes run on all cores: the CPU ratio is
the one other work on the machine disturbs least); the walk's noise σ at the spp (per
pixel and channel, from its two seeds: mean (w₁ − w₂)²/2); the preview's RMSE against W,
as measured and with the noise of W and the preview's own taken out
(√(RMSE² − σ²/n − σ_p²), n = 4 + extra: its difference from the walk's expected image);
each also over W's mean. Writes the images (.npy, linear: the preview's first, W) and
results.json (with the machine and its load average) to OUT_DIR (default
/tmp/preview_speed); ``--pair`` makes a side-by-side PNG of them.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import time
from pathlib import Path

import numpy as np

import mimarble
from mimarble.runtime import machine, packaged_scenes

ROOT = Path(__file__).resolve().parent.parent
SCENES = tuple(sorted(str(p) for p in (ROOT / "scenes" / "translucent").glob("*.scene")))


def timed(scene, mode: str, spp: int, seed: int) -> tuple[float, float, np.ndarray]:
    """(wall seconds, CPU seconds of this process, the image) of one render."""
    start, cpu = time.perf_counter(), time.process_time()
    image = mimarble.render(scene, mode=mode, spp=spp, seed=seed)   # NumPy: synchronised
    return time.perf_counter() - start, time.process_time() - cpu, image


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a.astype(np.float64) - b) ** 2)))


def shrunk(scene, k: int):
    """``scene`` with each image side over k (at least 1) and its spp over k² (at least 1)."""
    image = dataclasses.replace(scene.image, width=max(scene.image.width // k, 1),
                                height=max(scene.image.height // k, 1),
                                samples=max(scene.image.samples // (k * k), 1))
    return dataclasses.replace(scene, image=image)


def measure(path: str, extra: int, out: Path, shrink: int = 1) -> dict:
    scene = shrunk(mimarble.scene.load(packaged_scenes.resolve(path)), shrink)
    spp, name = scene.image.samples, Path(str(packaged_scenes.resolve(path))).stem
    # Warm each mode at the measured spp, twice (a render's recording is keyed on its spp
    # and width, and Dr.Jit records again on the second call, making the values that
    # changed — the seed — opaque: ~1 CPU s on carrara at 240×160); the walk's warm renders
    # are two more samples of the converged walk.
    warm_walk = 0.0
    for seed in (98, 99):
        mimarble.render(scene, mode="preview", spp=spp, seed=seed)
        warm_walk = warm_walk + mimarble.render(scene, mode="path", spp=spp,
                                                seed=seed).astype(np.float64)
    seconds = {"preview": [], "path": []}
    cpu = {"preview": [], "path": []}
    images = {"preview": [], "path": []}
    for seed in (1, 2):
        for mode in ("preview", "path"):
            t, c, image = timed(scene, mode, spp, seed)
            seconds[mode].append(t)
            cpu[mode].append(c)
            images[mode].append(image.astype(np.float64))
            print(f"{name}: {mode} {spp} spp seed {seed}: {t:.2f} s ({c:.2f} CPU s)", flush=True)
    walk, t_extra = images["path"][0] + images["path"][1] + warm_walk, 0.0
    if extra:
        t_extra, _, more = timed(scene, "path", extra * spp, 100)
        walk += extra * more.astype(np.float64)
        print(f"{name}: walk {extra * spp} spp: {t_extra:.1f} s", flush=True)
    n = 4 + extra
    walk /= n
    preview = images["preview"][0]
    np.save(out / f"{name}-preview.npy", preview.astype(np.float32))
    np.save(out / f"{name}-walk.npy", walk.astype(np.float32))
    noise = float(np.mean((images["path"][0] - images["path"][1]) ** 2) / 2)     # σ²
    preview_noise = float(np.mean((images["preview"][0] - images["preview"][1]) ** 2) / 2)
    measured = rmse(preview, walk)
    mean = float(walk.mean())
    result = {"scene": name, "size": [scene.image.width, scene.image.height], "spp": spp,
              "preview_s": statistics.median(seconds["preview"]),
              "walk_s": statistics.median(seconds["path"]), "all_s": seconds,
              "preview_cpu_s": statistics.median(cpu["preview"]),
              "walk_cpu_s": statistics.median(cpu["path"]), "all_cpu_s": cpu,
              "converged_spp": n * spp, "extra_s": t_extra, "walk_mean": mean,
              "preview_mean": float(preview.mean()),
              "walk_noise": noise ** 0.5, "preview_noise": preview_noise ** 0.5,
              "preview_rmse": measured,
              "preview_bias_rmse": max(measured ** 2 - noise / n - preview_noise, 0.0) ** 0.5}
    result["speedup"] = result["walk_s"] / result["preview_s"]
    result["speedup_cpu"] = result["walk_cpu_s"] / result["preview_cpu_s"]
    for key in ("walk_noise", "preview_rmse", "preview_bias_rmse"):
        result[key + "_rel"] = result[key] / mean
    return result


def write_pair(out: Path, name: str, target: Path) -> None:
    """``target``: the preview (left) and the walk (right) of ``name`` side by side, each at
    half size (2×2 pixels averaged in linear light), 8-bit sRGB, 4 black pixels between."""
    from mimarble.mitsuba.rendering.image_output import write_image
    halves = []
    for key in ("preview", "walk"):
        image = np.load(out / f"{name}-{key}.npy").astype(np.float64)
        h, w = image.shape[0] // 2 * 2, image.shape[1] // 2 * 2
        halves.append(image[:h, :w].reshape(h // 2, 2, w // 2, 2, 3).mean(axis=(1, 3)))
    gap = np.zeros((halves[0].shape[0], 4, 3))
    write_image(str(target), np.concatenate([halves[0], gap, halves[1]], axis=1).astype(np.float32))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES))
    parser.add_argument("--extra", type=int, default=2)
    parser.add_argument("--shrink", type=int, default=1,
                        help="each image side over K, the spp over K² (default 1: as the scene)")
    parser.add_argument("-o", "--output", default="/tmp/preview_speed")
    parser.add_argument("--pair", nargs=2, metavar=("NAME", "PNG"),
                        help="only write the side-by-side image of a scene measured before "
                             "into OUT_DIR (e.g. carrara docs/gallery/preview-vs-walk.png)")
    args = parser.parse_args()
    out = Path(args.output)
    if args.pair:
        write_pair(out, args.pair[0], Path(args.pair[1]))
        return
    out.mkdir(parents=True, exist_ok=True)
    results = {"machine": machine.machine_line(machine.machine_facts()),
               "load_at_start": os.getloadavg(), "shrink": args.shrink,
               "variant": mimarble.mi.variant(), "scenes": []}
    for path in args.scenes:
        results["scenes"].append(measure(path, args.extra, out, args.shrink))
        results["load_at_end"] = os.getloadavg()
        (out / "results.json").write_text(json.dumps(results, indent=1))
    for r in results["scenes"]:
        print(f"{r['scene']} {r['size'][0]}x{r['size'][1]} {r['spp']} spp: preview "
              f"{r['preview_s']:.2f} s, walk {r['walk_s']:.2f} s ({r['speedup']:.1f}x; CPU "
              f"{r['preview_cpu_s']:.2f} / {r['walk_cpu_s']:.2f} s, {r['speedup_cpu']:.1f}x); against the walk at {r['converged_spp']} spp: preview "
              f"RMSE {r['preview_rmse']:.4f} ({100 * r['preview_rmse_rel']:.1f} % of the mean), "
              f"noise taken out {r['preview_bias_rmse']:.4f} "
              f"({100 * r['preview_bias_rmse_rel']:.1f} %); the walk's noise at {r['spp']} spp "
              f"{r['walk_noise']:.4f} ({100 * r['walk_noise_rel']:.1f} %)")


if __name__ == "__main__":
    main()
