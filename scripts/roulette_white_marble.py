"""volpath's Russian roulette on white marble, measured: rr_depth 5 (Mitsuba's default), rr_depth = max_depth (no roulette), and no roulette with the ``roulette_isotropic`` phase function (the analog walk, and path mode's survival power), on a small white translucent sphere.

    ./go python scripts/roulette_white_marble.py [--size 32] [--spp 16] [--renders 8]
        [--albedo 0.9995] [--mean-free-path 0.05] [--scene FILE] [--json OUT]

The scene: a unit sphere of single-scattering albedo ``--albedo`` (0.9995 is what
``reflectance`` 0.95 inverts to at ior 1.5), ior 1.5, under a white sky (ambient 1) and one
point light, path mode's translation (``subsurface_boundary`` around ``marble_medium``,
``volpath`` max_depth ``contract.VOLPATH_MAX_DEPTH``), llvm_ad_rgb; or ``--scene FILE``
at size² (e.g. scenes/translucent/fig11a-translucent.scene). For each of rr_depth 5 with
the ``isotropic`` phase function, rr_depth max_depth with ``isotropic``, and rr_depth
max_depth with ``roulette_isotropic`` at survival power 1 (the analog walk) and at path
mode's ``media.WALK_SURVIVAL_POWER`` and ``WALK_POWER_ALBEDOS`` (the medium's phase set in
the translated dict):
``--renders`` renders of different seeds after a warm-up, each timed (``dr.sync_thread``
before the clock); over the pixels the sphere covers: the mean, the relative per-pixel
standard deviation across the renders (std/mean of each pixel, averaged), the largest
pixel value, and the efficiency 1/(relative variance × seconds) (higher is better: the
inverse of the time to a given noise).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

import mimarble
from mimarble import scene as S
from mimarble.contract import ROULETTE_DEPTH, VOLPATH_MAX_DEPTH
from mimarble.mitsuba.translate.media import WALK_POWER_ALBEDOS, WALK_SURVIVAL_POWER
from mimarble.mitsuba.translate.scene_dict import to_mitsuba
from mimarble.scene.edits import resized

dr, mi = mimarble.dr, mimarble.mi

SCENE = """image {{ width {size} height {size} }}
camera {{ eye < 0 0.4 5 > lookat < 0 0 0 > fov 30 }}
ambient < 1 1 1 >
light {{ position < 2 3 4 > }}
material "white" {{ subsurface {{ albedo color < {a} {a} {a} > mean_free_path {mfp} ior 1.5 }} }}
sphere {{ material "white" }}
"""


def measure(scene, spp: int, renders: int, rr_depth: int, phase: str, power: float = 1.0) -> dict:
    scene_dict = to_mitsuba(scene, "path", spp=spp)
    scene_dict["integrator"] = dict(scene_dict["integrator"], rr_depth=rr_depth)
    lo, hi = WALK_POWER_ALBEDOS if power != 1.0 else (0.0, 1.0)
    given = {"survival_power": power, "power_albedo_min": lo, "power_albedo_max": hi} \
        if phase == "roulette_isotropic" else {}
    for shape in scene_dict.values():
        if isinstance(shape, dict) and "interior" in shape:
            shape["interior"] = dict(shape["interior"], phase={"type": phase, **given})
    loaded = mi.load_dict(scene_dict)
    dr.eval(mi.render(loaded, seed=0))
    dr.sync_thread()
    images, seconds = [], []
    for seed in range(1, renders + 1):
        start = time.perf_counter()
        image = mi.render(loaded, seed=seed)
        dr.eval(image)
        dr.sync_thread()
        seconds.append(time.perf_counter() - start)
        images.append(np.array(image, dtype=np.float64)[..., :3].mean(axis=2))
    stack = np.stack(images)
    mean = stack.mean(axis=0)
    covered = mean > 0.05 * mean.max()
    relative = stack.std(axis=0, ddof=1)[covered] / mean[covered]
    s = statistics.median(seconds)
    return {"rr_depth": rr_depth, "phase": phase, "survival_power": power if given else None,
            "seconds": s, "covered_mean": float(mean[covered].mean()),
            "covered_mean_spread": float(stack[:, covered].mean(axis=1).std(ddof=1)),
            "relative_std": float(relative.mean()), "largest_pixel": float(stack.max()),
            "efficiency": float(1.0 / (np.mean(relative ** 2) * s))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=32)
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--renders", type=int, default=8)
    parser.add_argument("--albedo", type=float, default=0.9995)
    parser.add_argument("--mean-free-path", type=float, default=0.05)
    parser.add_argument("--scene", help="a scene file instead of the white sphere")
    parser.add_argument("--json")
    args = parser.parse_args()
    mi.set_variant("llvm_ad_rgb")
    if args.scene:
        with open(args.scene) as text:
            scene = resized(S.parse(text.read(), filename=args.scene), args.size)
    else:
        scene = S.parse(SCENE.format(size=args.size, a=args.albedo, mfp=args.mean_free_path))
    rows = [measure(scene, args.spp, args.renders, rr, phase, power) for rr, phase, power in
            ((ROULETTE_DEPTH, "isotropic", 1.0), (VOLPATH_MAX_DEPTH, "isotropic", 1.0),
             (VOLPATH_MAX_DEPTH, "roulette_isotropic", 1.0),
             (VOLPATH_MAX_DEPTH, "roulette_isotropic", WALK_SURVIVAL_POWER))]
    for row in rows:
        power = "" if row["survival_power"] is None else f" p {row['survival_power']:g}"
        print(f"rr_depth {row['rr_depth']:5d} {row['phase'] + power:24s}: {row['seconds']:.2f} s/render, covered mean "
              f"{row['covered_mean']:.4f} ± {row['covered_mean_spread']:.4f} (spread over "
              f"renders), relative per-pixel std {row['relative_std']:.3f}, largest pixel "
              f"{row['largest_pixel']:.2f}, efficiency {row['efficiency']:.3g}")
    if args.json:
        with open(args.json, "w") as out:
            json.dump({"args": vars(args), "rows": rows}, out, indent=1)


if __name__ == "__main__":
    main()
