"""Samples a pixel adaptive sampling needs for plain N spp's RMSE, under rule variants (issue 43).

    CONFIGS='base;BAR_POWER=3,JUMP=243/1024,JUMPED_BAR=1' TARGET=16 \\
        ./go python scripts/adaptive_rule_sweep.py SCENE …

256², point-sampled, against the float64 reference at 256 spp (cached). For each config (``;``
between configs, ``,`` between settings of adaptive.py's module constants, ``JUMP=lo/hi`` or
``JUMP=none``; ``base`` the code as it is): the thresholds 0.005·2^(−k/2) until a render
reaches plain ``TARGET`` spp's RMSE (16 unless given), and the samples a pixel traced there,
interpolated log-log between the two bracketing thresholds (mimarble/bench/curves.py's
crossing, on samples instead of time). Samples do not depend on the machine's load.
"""
import os
import sys
from pathlib import Path

import numpy as np

import mimarble
from mimarble.bench.curves import value_at_crossing
from mimarble.bench.timing import converged
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering import adaptive
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.runtime import files
from mimarble.scene.edits import resized

dr, mi = mimarble.dr, mimarble.mi
DEFAULTS = {name: getattr(adaptive, name) for name in dir(adaptive) if name.isupper()}


def configure(config: str) -> None:
    """adaptive.py's constants as the code has them, then ``config``'s settings."""
    for name, value in DEFAULTS.items():
        setattr(adaptive, name, value)
    if config == "base":
        return
    for setting in config.split(","):
        name, value = setting.split("=")
        if name not in DEFAULTS:
            raise SystemExit(f"adaptive_rule_sweep: adaptive.py has no constant {name}")
        if name == "JUMP":
            value = None if value == "none" else tuple(float(v) for v in value.split("/"))
        elif isinstance(DEFAULTS[name], bool):
            value = value == "1"
        else:
            value = type(DEFAULTS[name])(float(value))
        setattr(adaptive, name, value)


configs = os.environ.get("CONFIGS", "base").split(";")
target_spp = int(os.environ.get("TARGET", "16"))
table = {config: [] for config in configs}
for path in sys.argv[1:]:
    scene = resized(mimarble.scene.load(path), 256)
    truth = converged(scene, 256, Path(files.cache_folder())).astype(np.float64)
    m = mi.load_dict(to_mitsuba(scene, spp=1))
    rmse = lambda image: float(np.sqrt(np.mean(np.square(np.asarray(image, np.float64) - truth))))
    target = rmse(render_in_passes(m, target_spp))
    for config in configs:
        configure(config)
        runs = []
        for k in range(60):
            run = adaptive.render_adaptive(m, 1, 0.005 * 2.0 ** (-k / 2), 81)
            runs.append({"spp": run.traced / run.samples.size, "rmse": rmse(run.image)})
            if runs[-1]["rmse"] <= target:
                break
        samples = value_at_crossing(runs[-2:], target, "spp")
        levels = {int(k): int(n) for k, n in zip(*np.unique(run.samples, return_counts=True))}
        print(f"{Path(path).stem:16s} {config:40s} {samples if samples is None else round(samples, 2)}"
              f"  (pixels a level at the first threshold past it: {levels})", flush=True)
        table[config].append(samples)
configure("base")
print(f"samples a pixel to plain {target_spp} spp's RMSE, in the scenes' order:")
for config, row in table.items():
    print(f"  {config:40s}", " ".join("never" if v is None else f"{v:.2f}" for v in row))
