"""The bias of one of the random walk's stated approximations, the walk as path mode renders it
against the walk without it, both converged, and the time of each: ``--rule band-limit``
(default) band-limiting a translucent material's marbles to its mean free path
(mimarble/scene/band_limit.py), ``--rule albedo-grid`` reading the albedo from its grid
(mimarble/scene/albedo_grid.py; both walks band-limited), or ``--rule survival-power``
the walk's roulette at ``media.WALK_SURVIVAL_POWER`` (unbiased by design: the check that
it is; both walks band-limited and on the grid).

    ./go python scripts/band_limit_bias.py SCENE [--rule band-limit|albedo-grid|survival-power]
        [--size 100] [--spp 512] [--json OUT.json]

The walk without the rule ("full") is the same translation with ``band_limited`` replaced by
the identity, ``albedo_grid`` by no grid, or the survival power by 1, the analog walk
(this script's own switch; the package has none), the loaded scenes cleared before each. Each is rendered twice (seeds 1, 2) after
a warm-up. Over the object's pixels (scripts/translucent_vs_cycles.py's mask), relative to
the full walk's mean m ("limited": the walk with the rule):

* ``mean_shift``: (mean(limited) − mean(full)) / m, with its standard error from the
  renders' own noise (se);
* ``rms_difference``: sqrt(mean(D²)) / m, D = the mean over the seeds of d_k = L_k − F_k
  (limited minus full with the same seed: the same random numbers, so d_k is far less
  noisy than either image), per pixel and channel; ``rms_noise``: the part of it the noise
  explains, sqrt(mean((d_1 − d_2)²/2) / 2) / m; ``rms_bias``: the rest,
  sqrt(max(0, rms_difference² − rms_noise²)), the per-pixel bias the band limit leaves.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from translucent_vs_cycles import object_mask  # noqa: E402  (the sibling script)


#: Each rule's switch: the name in mimarble/mitsuba/translate/media.py, and what stands in
#: for it in the walk without the rule.
RULES = {"band-limit": ("band_limited", lambda subsurface: subsurface),
         "albedo-grid": ("albedo_grid", lambda subsurface, shapes: None),
         "survival-power": ("WALK_SURVIVAL_POWER", 1.0)}


def renders(scene, spp: int, full: bool, rule: str = "band-limit"):
    """Two path renders (seeds 1, 2) after a warm-up; with ``full`` without ``rule``."""
    import mimarble
    from mimarble.mitsuba.translate import media
    from mimarble.mitsuba.rendering.loaded_scenes import LOADED
    LOADED.clear()           # a model once translated is not translated again
    name, without = RULES[rule]
    kept = getattr(media, name)
    if full:
        setattr(media, name, without)
    try:
        mimarble.render(scene, spp=spp, mode="path", seed=0)
        images, cpu = [], []
        for seed in (1, 2):
            used = time.process_time()
            images.append(mimarble.render(scene, spp=spp, mode="path", seed=seed))
            cpu.append(time.process_time() - used)
    finally:
        setattr(media, name, kept)
    return np.asarray(images, np.float64), cpu


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--rule", choices=sorted(RULES), default="band-limit")
    parser.add_argument("--size", type=int, default=100)
    parser.add_argument("--spp", type=int, default=512)
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    from mimarble import scene as scene_language
    from mimarble.runtime import packaged_scenes
    from mimarble.scene.edits import resized
    scene = resized(scene_language.load(packaged_scenes.resolve(args.scene)), args.size)
    mask = object_mask(scene)
    full, full_cpu = renders(scene, args.spp, True, args.rule)
    limited, limited_cpu = renders(scene, args.spp, False, args.rule)
    f, lim = full[:, mask], limited[:, mask]                 # (2, pixels, 3)
    m = f.mean()
    # Same seed, same random numbers: L_k − F_k is far less noisy than either (paired).
    d = lim - f                                              # (2, pixels, 3)
    diff = d.mean(axis=0)
    noise2 = float(np.mean(np.square(d[0] - d[1]) / 2.0) / 2.0)   # variance of diff, per pixel
    rms = float(np.sqrt(np.mean(np.square(diff))))
    result = {
        "scene": args.scene, "rule": args.rule, "size": args.size, "spp": args.spp, "pixels": int(mask.sum()),
        "mean_full": float(m), "mean_limited": float(lim.mean()),
        "mean_shift": float(diff.mean() / m),
        "mean_shift_se": float(np.sqrt(noise2 / diff.size) / m),
        "rms_difference": rms / m, "rms_noise": float(np.sqrt(noise2)) / m,
        "rms_bias": float(np.sqrt(max(0.0, rms ** 2 - noise2))) / m,
        "cpu_full_s": [round(t, 2) for t in full_cpu],
        "cpu_limited_s": [round(t, 2) for t in limited_cpu],
        "cpu": platform.processor() or platform.machine()}
    print(json.dumps(result, indent=1))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
