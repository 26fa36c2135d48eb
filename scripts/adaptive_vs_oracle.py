"""Which pixels adaptive sampling refines against those the oracle refines, at one RMSE (issue 43).

    ./go python scripts/adaptive_vs_oracle.py SCENE …

256², point-sampled, against the float64 reference at 256 spp (cached). Adaptive sampling at
thresholds 0.005·2^(−k/2) until its RMSE is at most plain 16 spp's; the oracle
(mimarble/bench/oracle.py, every level of both ladders, the jump to 16 included) at the
price per sample that gives the same RMSE (bisected). Prints the samples a pixel of each,
how many pixels end at each level, and — per level we end a pixel at — the oracle's choice
for those pixels and their share of our final squared error. Samples do not depend on the
machine's load.
"""
import sys
from pathlib import Path

import numpy as np

import mimarble
from mimarble.bench.oracle import oracle_scene, oracle_choice
from mimarble.mitsuba.rendering import adaptive
from mimarble.mitsuba.rendering.render import render_in_passes

dr, mi = mimarble.dr, mimarble.mi


def counts(values) -> dict:
    return {int(k): int(n) for k, n in zip(*np.unique(values, return_counts=True))}


for path in sys.argv[1:]:
    measured = oracle_scene(path)
    m, truth, rmse = measured.mitsuba, measured.truth, measured.rmse
    images, costs, errors = measured.images, measured.costs, measured.errors
    target = rmse(render_in_passes(m, 16))
    for k in range(40):
        run = adaptive.render_adaptive(m, 1, 0.005 * 2.0 ** (-k / 2), 81)
        if rmse(run.image) <= target:
            break
    ours_rmse, pixels = rmse(run.image), errors.shape[1]
    # The oracle's levels at the same RMSE (its price bisected, oracle.price_for).
    cost = np.asarray(costs, np.float64)[:, None]
    chosen = oracle_choice(errors, costs, ours_rmse)
    oracle_cost = cost[chosen, 0]
    # Our pixels' level (its index in the oracle's list, by the samples it ended with; a
    # pixel at 81 counted at the ladder's 81, whose image is the same).
    index = {c: i for i, c in reversed(list(enumerate(costs)))}
    level_of = {1: index[1], 9: index[9], 16: index[17], 81: index[81]}
    ours = run.samples.ravel()
    final = errors[[level_of[int(s)] for s in ours], np.arange(pixels)]
    print(f"{Path(path).stem}: plain 16's RMSE {target:.5f}; ours {ours_rmse:.5f} at "
          f"{run.traced / pixels:.2f} samples a pixel (threshold {0.005 * 2.0 ** (-k / 2):.3g}), "
          f"the oracle {oracle_cost.mean():.2f}; levels (cost: pixels) ours {counts(ours)}, "
          f"the oracle's {counts(oracle_cost.astype(int))}")
    for samples in (1, 9, 16, 81):
        at = ours == samples
        if at.any():
            print(f"  ours at {samples}: {int(at.sum())} pixels, {final[at].sum() / final.sum():.3f} "
                  f"of our squared error; the oracle's cost for them {counts(oracle_cost[at].astype(int))}")
