"""Translucent marble against Blender Cycles: the same scene (scripts/cycles_twin.py) rendered by
both at equal samples per pixel, twice each with different seeds; time, mean and noise.

    ./go python scripts/translucent_vs_cycles.py SCENE [--spp 64] [--seeds 1 2] [--size N]
        [--radius mfp|matched] [--cycles-scene OTHER] [--json OUT.json] [--images FOLDER]

Ours: ``mimarble.render(scene, spp=…, mode="path", seed=…)``, once first with seed 0 to
warm the kernel cache (its time, and whether it compiled kernels — files added to Dr.Jit's
cache folder —, are reported apart), then once per seed, each timed by the wall clock
around the call (it returns a synced NumPy image). Cycles: the twin once per seed (of
``--cycles-scene`` when given: the same geometry with another colour, e.g. the colour where
SCENE gives the albedo it inverts to); its time
is Cycles' logged render time without the scene's synchronization (with it in
``cycles_total_s``). Both also get ``cpu_s``, the CPU seconds of the process's threads
over the render call (``time.process_time``; Cycles': the ``bpy.ops.render.render`` call, its
sync included), the figure to read when other work shares the cores.

For each renderer, over the object's pixels (those whose whole pixel — centre and four
corners — sees a sphere, from the scene's camera; silhouette pixels are left out): the mean
colour, and the noise, the relative per-pixel standard deviation from the two renders a, b:
sqrt(mean((a − b)²)/2) / mean((a + b)/2), over all pixels and channels (the standard deviation
of one render's pixel, estimated from the difference of two independent renders). Then the
ratios ours / Cycles. Writes a JSON and prints a line table. Needs Blender (see
scripts/cycles_twin.py); nothing in the tests runs it.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cycles_twin  # noqa: E402  (the sibling script)


def object_mask(scene) -> np.ndarray:
    """(H, W) bool: the pixels whose centre and four corners all see one of the scene's
    spheres (pinhole camera, vertical fov, as path mode's sensor)."""
    cam, img = scene.camera, scene.image
    width, height = img.width, img.height
    eye = np.array(cam.eye, float)
    forward = np.array(cam.lookat, float) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.array(cam.up, float))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    t = math.tan(math.radians(cam.fov) / 2)
    inside = np.ones((height, width), bool)
    for dx, dy in ((0.5, 0.5), (0, 0), (1, 0), (0, 1), (1, 1)):
        i, j = np.meshgrid(np.arange(width) + dx, np.arange(height) + dy)
        d = ((2 * i / width - 1) * t * width / height)[..., None] * right \
            + ((1 - 2 * j / height) * t)[..., None] * up + forward
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        hit = np.zeros_like(inside)
        for sphere in scene.spheres:
            oc = eye - np.array(sphere.center, float)
            b = d @ oc
            hit |= b * b - (oc @ oc - sphere.radius ** 2) > 0
        inside &= hit
    return inside


def statistics_of(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> dict:
    """Mean colour and relative per-pixel noise of two renders over the masked pixels."""
    pa, pb = a[mask].astype(np.float64), b[mask].astype(np.float64)
    mean = (pa + pb) / 2
    noise = math.sqrt(float(np.mean((pa - pb) ** 2)) / 2) / float(np.mean(mean))
    return {"mean_rgb": [round(float(v), 5) for v in mean.mean(axis=0)],
            "mean": round(float(mean.mean()), 5), "noise": round(noise, 5)}


def _cache_files() -> int:
    folder = Path(os.environ.get("DRJIT_CACHE_DIR", Path.home() / ".drjit"))
    return sum(1 for _ in folder.iterdir()) if folder.is_dir() else 0


def ours(scene, spp: int, seeds) -> tuple[list, dict]:
    """Our path-mode renders for ``seeds`` after a warm-up; (images, times)."""
    import mimarble
    before = _cache_files()
    start = time.perf_counter()
    mimarble.render(scene, spp=spp, mode="path", seed=0)
    warm = time.perf_counter() - start
    compiled = _cache_files() - before
    images, times, cpu = [], [], []
    for seed in seeds:
        start, used = time.perf_counter(), time.process_time()
        images.append(mimarble.render(scene, spp=spp, mode="path", seed=seed))
        times.append(time.perf_counter() - start)
        cpu.append(time.process_time() - used)
    return images, {"times_s": [round(t, 3) for t in times],
                    "time_s": round(statistics.mean(times), 3),
                    "cpu_s": [round(t, 3) for t in cpu],
                    "warm_up_s": round(warm, 3), "kernels_compiled_in_warm_up": compiled}


def cycles(scene, spp: int, seeds, radius_rule: str) -> tuple[list, dict]:
    """The Cycles twin's renders for ``seeds``; (images, times and settings)."""
    images, infos = [], []
    for seed in seeds:
        image, info = cycles_twin.render_cycles(scene, spp, seed, 2, radius_rule)
        images.append(image)
        infos.append(info)
    render = [i["cycles_render_s"] for i in infos]
    return images, {"times_s": [round(t, 3) for t in render],
                    "time_s": round(statistics.mean(render), 3),
                    "total_times_s": [round(i["cycles_total_s"], 3) for i in infos],
                    "cpu_s": [round(i["blender_call_cpu_s"], 3) for i in infos],
                    "blender_call_s": [round(i["blender_call_s"], 3) for i in infos],
                    "blender": infos[0]["blender"],
                    "sampling_pattern": infos[0]["sampling_pattern"],
                    "radius_rule": radius_rule,
                    "subsurface_radius": infos[0]["subsurface_radius"],
                    "colour_kinds": infos[0]["colour_kinds"],
                    "colour_comparable": infos[0]["colour_comparable"]}


def boundary_of(scene) -> str:
    """Which boundary our path mode gives a subsurface on this checkout."""
    from mimarble.mitsuba.translate import scene_dict
    sphere_id = next(i for i, _ in scene.shapes())
    bsdf = scene_dict.to_mitsuba(scene, "path", 1)[sphere_id]["bsdf"]
    return bsdf.get("type", "?")


def table(result: dict) -> str:
    rows = [f"{'':10} {'time s':>9} {'cpu s':>9} {'mean':>9} {'noise':>9}"]
    for name in ("ours", "cycles"):
        r = result[name]
        rows.append(f"{name:10} {r['time_s']:9.2f} {statistics.mean(r['cpu_s']):9.2f} "
                    f"{r['mean']:9.4f} {r['noise']:9.4f}")
    q = result["ours_over_cycles"]
    rows.append(f"{'ours/cyc':10} {q['time']:9.3f} {q['cpu']:9.3f} {q['mean']:9.4f} "
                f"{q['noise']:9.4f}")
    return "\n".join(rows)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--seeds", type=int, nargs=2, default=[1, 2])
    parser.add_argument("--size", type=int, help="render at size² (default: the scene's)")
    parser.add_argument("--radius", choices=("mfp", "matched"), default="mfp")
    parser.add_argument("--cycles-scene", help="the scene Cycles renders (default: SCENE)")
    parser.add_argument("--json")
    parser.add_argument("--images", help="save the four images here as .npy")
    args = parser.parse_args(argv)
    import mimarble
    from mimarble import scene as scene_language
    from mimarble.runtime import machine, packaged_scenes
    path = packaged_scenes.resolve(args.scene)
    scene = twin = scene_language.load(path)
    if args.cycles_scene:
        twin = scene_language.load(packaged_scenes.resolve(args.cycles_scene))
    if args.size:
        from mimarble.scene.edits import resized
        scene, twin = resized(scene, args.size), resized(twin, args.size)
    try:
        cycles_twin.twin_spec(twin, args.spp, 0, 2, args.radius)   # refuse before rendering
    except cycles_twin.Unsupported as problem:
        print(f"{path}: {problem}", file=sys.stderr)
        return 2
    mask = object_mask(scene)
    load_before = os.getloadavg()
    our_images, our_times = ours(scene, args.spp, args.seeds)
    cyc_images, cyc_times = cycles(twin, args.spp, args.seeds, args.radius)
    result = {
        "scene": str(path), "cycles_scene": args.cycles_scene or str(path),
        "size": [scene.image.width, scene.image.height], "spp": args.spp,
        "seeds": args.seeds, "object_pixels": int(mask.sum()),
        "our_boundary": boundary_of(scene),
        "machine": machine.machine_line(machine.machine_facts()),
        "cpu": platform.processor() or platform.machine(),
        "load_average_before_after": [round(load_before[0], 2), round(os.getloadavg()[0], 2)],
        "versions": {"mitsuba": mimarble.mi.__version__, "python": platform.python_version()},
        "ours": {**our_times, **statistics_of(*our_images, mask)},
        "cycles": {**cyc_times, **statistics_of(*cyc_images, mask)},
        "command": "./go python scripts/translucent_vs_cycles.py " + " ".join(
            sys.argv[1:] if argv is None else argv),
    }
    result["ours_over_cycles"] = {
        key: round(result["ours"][key] / result["cycles"][key], 4)
        for key in ("time_s", "mean", "noise")}
    result["ours_over_cycles"]["time"] = result["ours_over_cycles"].pop("time_s")
    result["ours_over_cycles"]["cpu"] = round(statistics.mean(result["ours"]["cpu_s"])
                                              / statistics.mean(result["cycles"]["cpu_s"]), 4)
    if args.images:
        folder = Path(args.images)
        folder.mkdir(parents=True, exist_ok=True)
        for name, images in (("ours", our_images), ("cycles", cyc_images)):
            for seed, image in zip(args.seeds, images):
                np.save(folder / f"{Path(path).stem}-{name}-seed{seed}.npy", image)
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result, indent=1))
    print(table(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
