"""Time to plain 16 and 64 spp's RMSE, adaptive against plain, interleaved, in one process.

    ./go python scripts/adaptive_time_to_rmse.py SCENE …    # MAXSPP=64 for issue 24's code; DK=1 doubt kernel; JUMP=none no jump to 16; DS=0 no neighbour's step
    FILTER=prefilter ./go python scripts/adaptive_time_to_rmse.py SCENE …   # the adaptive renders' marbles prefiltered (plain stays point-sampled, as the truth)

For each target: the thresholds 0.005·2^−k until a render reaches plain N spp's RMSE, then
plain N spp and the two bracketing thresholds timed in turn (medians of 7, each after a
sync), the crossing interpolated log-log as the benchmark does (mimarble/bench/curves.py).
Prints plain's time over adaptive's (above 1: adaptive sooner), and the load.
"""
import sys, time, statistics, os
from pathlib import Path
import numpy as np, mimarble
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering import adaptive
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.scene.edits import resized, with_marbles
from mimarble.bench.timing import converged
from mimarble.bench.curves import time_to_rmse
from mimarble.runtime import files
dr, mi = mimarble.dr, mimarble.mi
maxspp = int(os.environ.get("MAXSPP", "81"))
if "DK" in os.environ:      # DK=1: the first pass traces the doubt kernel (issue 43's first code)
    adaptive.DOUBT_KERNEL = os.environ["DK"] == "1"
if "BAR" in os.environ:
    adaptive.BAR_POWER = float(os.environ["BAR"])
if "JUMP" in os.environ:    # JUMP=lo,hi: the first round's band (adaptive.JUMP); none: no jump
    adaptive.JUMP = None if os.environ["JUMP"] == "none" else tuple(map(float, os.environ["JUMP"].split(",")))
if "DS" in os.environ:      # DS=0: the image's doubt from the second difference alone
    adaptive.DEVIATION_SHARE = float(os.environ["DS"])
if "THIRDS" in os.environ:
    adaptive.THIRDS = os.environ["THIRDS"] == "1"
for path in sys.argv[1:]:
    scene = resized(mimarble.scene.load(path), 256)
    truth = converged(scene, 256, Path(files.cache_folder()))
    m = mi.load_dict(to_mitsuba(scene, spp=1))
    # FILTER: the adaptive renders' marbles filtered so (plain 16 and 64 and the truth are
    # point-sampled either way: the targets do not move).
    a = m if "FILTER" not in os.environ else \
        mi.load_dict(to_mitsuba(with_marbles(scene, filter=os.environ["FILTER"]), spp=1))
    rm = lambda im: float(np.sqrt(np.mean(np.square(np.asarray(im, np.float64) - truth))))
    out = []
    for target_spp in (16, 64):
        target = rm(render_in_passes(m, target_spp))
        ts = [0.005 * 2.0 ** -k for k in range(0, 26)]
        runs = []
        for t in ts:
            r = adaptive.render_adaptive(a, 1, t, maxspp)
            runs.append((t, rm(r.image), r.traced / 65536))
            if runs[-1][1] <= target: break
        if runs[-1][1] > target:
            out.append(f"{target_spp}: never"); continue
        pick = runs[-2:] if len(runs) > 1 else runs
        renders = [("plain", lambda: render_in_passes(m, target_spp))] + [(t, (lambda t=t: adaptive.render_adaptive(a, 1, t, maxspp))) for t, _, _ in pick]
        for _, f in renders: f()
        times = {k: [] for k, _ in renders}
        for _ in range(7):
            for k, f in renders:
                dr.sync_thread(); s = time.perf_counter(); f(); dr.sync_thread(); times[k].append(1000 * (time.perf_counter() - s))
        med = {k: statistics.median(v) for k, v in times.items()}
        ms = time_to_rmse([(med[t], e) for t, e, _ in pick], target)
        out.append(f"{target_spp}: plain {med['plain']:.1f} ms, adaptive {ms:.1f} ms ({pick[-1][2]:.1f} spp at the finer point) → {med['plain']/ms:.2f}×")
    print(Path(path).stem, "; ".join(out), "load", os.getloadavg()[0], flush=True)
