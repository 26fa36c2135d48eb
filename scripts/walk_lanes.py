"""Where volpath's time goes on a translucent scene: its kernels, and the walks' lengths against the lanes of its loop.

    ./go python scripts/walk_lanes.py SCENE [--size 500] [--spp 4] [--walk-size 48]
        [--walk-spp 64] [--walk-rr-depth N] [--json OUT]

1. **Mitsuba**: path mode's translation of SCENE at size², ``--spp`` (llvm_ad_rgb), one
   render after a warm-up, under ``dr.JitFlag.KernelHistory``: the wall time, each
   kernel's execution time, the largest kernel's share (volpath's loop), and the time
   scaled to 64 spp (a megakernel's time is linear in its lanes).
2. **Walk lengths**: the float64 reference walk (the same boundary model, its own code) at
   walk-size², walk-spp, with path mode's max_depth and roulette (its roulette keeps
   q = min(max β, 1) where volpath's caps q at 0.95: close where β falls fast), gives
   each path's vertex count (``steps["depths"]``, volpath's depth where the path ended)
   in lane order (a pixel's samples together, as Mitsuba orders them): their mean,
   median, 90th and 99th percentiles and largest; and, a lane looping depth + 1 times
   (its events and the last segment), for packets of W consecutive lanes (W = Dr.Jit's
   LLVM vector width, and 2W) the **lane efficiency** Σ (depth + 1) / Σ_packets
   W·max(depth + 1 in the packet) — the share of lane-iterations doing work in a loop
   that runs each packet until its longest walk ends.
3. **Cost of a lane-iteration**: the largest kernel's time over the lane-iterations it
   ran, estimated as size²·spp·mean depth / efficiency (the walk's lengths at walk-size²
   taken to hold at size²: the geometry is the same, only the pixels finer).

``--walk-rr-depth N`` gives the walk a roulette from depth N whatever path mode's is (its
q = min(max β, 1) keeps weights bounded at any albedo, where volpath's 0.95 cap does not):
how long the walks would be under such a roulette.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

import mimarble
from mimarble import scene as S
from mimarble.mitsuba.translate.scene_dict import to_mitsuba
from mimarble.reference import volume
from mimarble.runtime import llvm_target
from mimarble.scene.edits import resized

dr, mi = mimarble.dr, mimarble.mi


def kernels(scene, spp: int) -> dict:
    """Wall time and kernel history of one path-mode render (after a warm-up)."""
    loaded = mi.load_dict(to_mitsuba(scene, "path", spp=spp))
    dr.eval(mi.render(loaded, seed=0))
    dr.sync_thread()
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        start = time.perf_counter()
        dr.eval(mi.render(loaded, seed=1))
        dr.sync_thread()
        wall = time.perf_counter() - start
        history = dr.kernel_history()
    times = sorted((k.get("execution_time") or 0.0 for k in history), reverse=True)
    return {"wall_s": wall, "kernels": len(history), "kernel_ms": times[:5],
            "largest_share": times[0] / max(sum(times), 1e-30)}


def packet_efficiency(depths: np.ndarray, width: int) -> float:
    """Σ depth / Σ_packets width·max(depth) over consecutive packets of ``width`` lanes
    (a last, short packet padded with idle lanes)."""
    pad = (-len(depths)) % width
    packets = np.concatenate([depths, np.zeros(pad, dtype=depths.dtype)]).reshape(-1, width)
    return float(depths.sum() / (width * packets.max(axis=1)).sum())


def walk_lengths(scene, spp: int, max_depth: int, rr_depth: int) -> np.ndarray:
    steps = {"depths": []}
    rr = None if rr_depth >= max_depth else rr_depth
    volume.render_translucent(scene, spp, seed=1, max_depth=max_depth, rr_depth=rr, steps=steps)
    return np.concatenate(steps["depths"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--size", type=int, default=500)
    parser.add_argument("--spp", type=int, default=4)
    parser.add_argument("--walk-size", type=int, default=48)
    parser.add_argument("--walk-spp", type=int, default=64)
    parser.add_argument("--walk-rr-depth", type=int)
    parser.add_argument("--json")
    args = parser.parse_args()
    mi.set_variant("llvm_ad_rgb")
    with open(args.scene) as text:
        scene = S.parse(text.read(), filename=args.scene)
    integrator = to_mitsuba(resized(scene, 8), "path", spp=1)["integrator"]
    width = llvm_target.configure().target.vector_width
    out = {"scene": args.scene, "size": args.size, "spp": args.spp, "integrator": integrator,
           "vector_width": width, "walk_rr_depth": args.walk_rr_depth}
    out.update(kernels(resized(scene, args.size), args.spp))
    out["wall_s_at_64_spp"] = out["wall_s"] * 64 / args.spp
    start = time.perf_counter()
    depths = walk_lengths(resized(scene, args.walk_size), args.walk_spp,
                          integrator["max_depth"], args.walk_rr_depth
                          if args.walk_rr_depth is not None else integrator.get("rr_depth", 5))
    out["walk_s"] = time.perf_counter() - start
    out["depth"] = {"mean": float(depths.mean()), "median": float(np.median(depths)),
                    "p90": float(np.percentile(depths, 90)),
                    "p99": float(np.percentile(depths, 99)), "max": int(depths.max())}
    loops = depths + 1
    out["efficiency"] = {str(w): packet_efficiency(loops, w) for w in (width, 2 * width)}
    iterations = args.size ** 2 * args.spp * loops.mean() / out["efficiency"][str(width)]
    out["ns_per_lane_iteration"] = out["kernel_ms"][0] * 1e6 / iterations
    print(json.dumps(out, indent=1))
    if args.json:
        with open(args.json, "w") as file:
            json.dump(out, file, indent=1)


if __name__ == "__main__":
    main()
