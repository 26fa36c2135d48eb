"""Translucent marble, timed: marble_medium against the same scene with its albedo baked on a
grid (Mitsuba's ``heterogeneous`` medium on a ``gridvolume``), and the delta tracking's steps
per path (the float64 reference random walk, which tracks with the same majorant).

    ./go python scripts/translucent_bench.py [--size 128] [--spp 64] [--grid 64] [--json OUT]

For each scene of scenes/translucent/ at size² pixels: the median of 3 path-mode renders after
a warm-up (``dr.sync_thread`` before each clock reading), with ``marble_medium`` and with the
grid (baked by ``mimarble.tools.bake.bake_volume`` at grid³ voxels, before timing); then the
reference's counts over size² · 4 paths: real and null collisions per path, and the majorant's
efficiency real / (real + null). Writes the results as JSON when asked (docs/bench/).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import mimarble
from mimarble.tools import bake
from mimarble.runtime import machine
from mimarble import reference
from mimarble import scene as S
from mimarble.mitsuba.translate.scene_dict import to_mitsuba
from mimarble.scene.edits import resized

dr, mi = mimarble.dr, mimarble.mi
ROOT = Path(__file__).resolve().parent.parent


def timed(scene_dict, spp: int) -> float:
    """Median seconds of 3 renders of the loaded dict, after one to warm the kernels."""
    loaded = mi.load_dict(scene_dict)
    mi.render(loaded, spp=spp, seed=0)
    dr.sync_thread()
    times = []
    for seed in (1, 2, 3):
        start = time.perf_counter()
        dr.eval(mi.render(loaded, spp=spp, seed=seed))
        dr.sync_thread()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def with_grid(scene_dict: dict, shape_id: str, grid_path: str) -> dict:
    """The dict with the shape's marble_medium replaced by a heterogeneous medium: the albedo
    a trilinear grid, σ_t the same constant over a box around the shape."""
    out = dict(scene_dict)
    shape = dict(out[shape_id])
    medium = shape["interior"]
    if "density" in medium:
        raise SystemExit(f"{shape_id}: a density channel is not baked by this script")
    lo, hi = mi.load_dict({k: v for k, v in shape.items() if k != "interior"}).bbox().min, \
        mi.load_dict({k: v for k, v in shape.items() if k != "interior"}).bbox().max
    extent = [float(h - l) * 1.1 for l, h in zip(lo, hi)]
    corner = [float(l) - 0.05 * e / 1.1 for l, e in zip(lo, extent)]
    box = mi.ScalarTransform4f().translate(corner) @ mi.ScalarTransform4f().scale(extent)
    shape["interior"] = {
        "type": "heterogeneous", "scale": 1.0,
        "albedo": {"type": "gridvolume", "filename": grid_path, "use_grid_bbox": True,
                   "raw": True, "filter_type": "trilinear", "wrap_mode": "clamp"},
        "sigma_t": {"type": "constvolume", "value": medium["scale"], "to_world": box},
        "has_spectral_extinction": False, "sample_emitters": medium["sample_emitters"]}
    out[shape_id] = shape
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--grid", type=int, default=64)
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for path in sorted((ROOT / "scenes" / "translucent").glob("*.scene")):
            scene = resized(S.load(path), args.size)
            scene_dict = to_mitsuba(scene, "path", args.spp)
            grid = str(Path(folder) / f"{path.stem}.vol")
            bake.bake_volume(scene, "sphere_0", grid, size=args.grid, channel="albedo")
            medium_s = timed(scene_dict, args.spp)
            grid_s = timed(with_grid(scene_dict, "sphere_0", grid), args.spp)
            steps: dict = {}
            reference.render_translucent(scene, 4, seed=0, steps=steps)
            total = steps.get("real", 0) + steps.get("null", 0)
            row = {"scene": path.stem, "marble_medium_s": medium_s, "gridvolume_s": grid_s,
                   "grid": args.grid, "paths": steps["paths"],
                   "real_per_path": steps.get("real", 0) / steps["paths"],
                   "null_per_path": steps.get("null", 0) / steps["paths"],
                   "efficiency": steps.get("real", 0) / total if total else 1.0}
            rows.append(row)
            print(f"{row['scene']}: marble_medium {medium_s:.2f} s, gridvolume {grid_s:.2f} s "
                  f"({grid_s / medium_s:.2f}×); steps per path {row['real_per_path']:.1f} real, "
                  f"{row['null_per_path']:.1f} null (efficiency {row['efficiency']:.3f})",
                  flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({
            "machine": machine.machine_line(machine.machine_facts()),
            "size": args.size, "spp": args.spp, "variant": mi.variant(), "rows": rows},
            indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
