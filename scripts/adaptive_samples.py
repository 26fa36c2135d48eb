"""Samples a pixel for plain 16 and 64 spp's RMSE: adaptive sampling and the oracle (issue 43).

    ./go python scripts/adaptive_samples.py SCENE …        # FILT=prefilter for prefiltered marble

Samples do not depend on the machine's load. 256², against the float64 reference at 256 spp
(cached); adaptive at thresholds 0.005·2^−2k, k < 12, first pass 1 spp, at most 81; the
oracle over the ladder's levels (mimarble/bench/oracle.py). The estimate's weights and the
bar's power can be tried from the environment: SW, DW, CW (SPREAD_, DOUBT_, CONTRAST_WEIGHT),
BAR (BAR_POWER), KW (CURVATURE_WEIGHT), DS (DEVIATION_SHARE), JUMP (lo,hi or none: adaptive.JUMP); DK=1 traces the first pass's doubt kernel
(DK=0, the default: ``traces_doubts`` decides — the image's second difference unless a
marble is prefiltered); ORACLE=0 leaves the oracle out.
"""
import sys, os
from pathlib import Path
import numpy as np, mimarble
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering import adaptive
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.scene.edits import resized, with_marbles
from mimarble.bench.timing import converged
from mimarble.bench.curves import value_at_crossing
from mimarble.bench.oracle import oracle_samples, level_images
from mimarble.bench.modes import ADAPTIVE_THRESHOLDS
from mimarble.runtime import files
dr, mi = mimarble.dr, mimarble.mi
filt = os.environ.get("FILT", "none")
for k, name in (("SW", "SPREAD_WEIGHT"), ("DW", "DOUBT_WEIGHT"), ("CW", "CONTRAST_WEIGHT"), ("BAR", "BAR_POWER"), ("KW", "CURVATURE_WEIGHT"), ("DS", "DEVIATION_SHARE")):
    if k in os.environ: setattr(adaptive, name, float(os.environ[k]))
if "JUMP" in os.environ:     # JUMP=lo,hi the first round's band of E / bar sent to 16; JUMP=none: no jump
    adaptive.JUMP = None if os.environ["JUMP"] == "none" else tuple(map(float, os.environ["JUMP"].split(",")))
if "DK" in os.environ: adaptive.DOUBT_KERNEL = os.environ["DK"] == "1"
ORACLE = os.environ.get("ORACLE", "1") == "1"
for path in sys.argv[1:]:
    scene = resized(mimarble.scene.load(path), 256)
    truth = converged(scene, 256, Path(files.cache_folder()))
    v = with_marbles(scene, filter=filt)
    m = mi.load_dict(to_mitsuba(v, spp=1))
    rm = lambda im: float(np.sqrt(np.mean(np.square(np.asarray(im, np.float64) - truth))))
    plain = {s: render_in_passes(m, s) for s in (16, 64)}
    t16, t64 = rm(plain[16]), rm(plain[64])
    runs = []
    for t in [0.005 * 2.0 ** -k for k in range(0, 24, 2)]:
        r = adaptive.render_adaptive(m, 1, t, 81)
        runs.append({"mean_spp": r.traced / 65536, "rmse": rm(r.image)})
    if ORACLE: images, costs = level_images(m, 1, 81)
    o16 = o64 = None
    if ORACLE: o16 = oracle_samples(images, truth, costs, t16)
    if ORACLE: o64 = oracle_samples(images, truth, costs, t64)
    a16, a64 = value_at_crossing(runs, t16, "mean_spp"), value_at_crossing(runs, t64, "mean_spp")
    f = lambda x: "—" if x is None else f"{x:.1f}"
    print(f"{Path(path).stem} {filt} SW={adaptive.SPREAD_WEIGHT} DW={adaptive.DOUBT_WEIGHT} CW={adaptive.CONTRAST_WEIGHT} BAR={adaptive.BAR_POWER} DK={int(adaptive.DOUBT_KERNEL)} JUMP={adaptive.JUMP} KW={adaptive.CURVATURE_WEIGHT} DS={adaptive.DEVIATION_SHARE}: to plain16 ({t16:.5f}) adaptive {f(a16)} oracle {f(o16)}; to plain64 ({t64:.5f}) adaptive {f(a64)} oracle {f(o64)}; last {runs[-1]['mean_spp']:.1f} spp {runs[-1]['rmse']:.5f}")
