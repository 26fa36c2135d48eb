"""Which fine-vein pixels could stay at one sample, and what knowing more would buy (issue 43).

    ./go python scripts/adaptive_signal_table.py SCENE …

256², point-sampled, against the float64 reference at 256 spp (cached); the level images
and their costs as the oracle has them (mimarble/bench/oracle.py: 1, 9, 17 = the jump to
16, 81, 98 = the jump then 81). Prints, for each scene:

1. The oracle at the price per sample that reaches plain 16 spp's RMSE; among the pixels
   our rule refines (at the first threshold 0.005·2^(−k/2) past that RMSE, as
   scripts/adaptive_vs_oracle.py finds it), the oracle's 1s against its others: each
   candidate signal of the first (1-spp) image, its quartiles on both sets and the area
   under the ROC curve (the chance that one of the oracle's 1s has the lower value: 0.5
   separates nothing, 1 all).
2. A rule that reads one signal (or a pair) of the first image and nothing after: pixels
   binned by it (48 quantiles; a pair 12 × 12), each bin's mean squared error at each
   level, the level of least error + price·samples per bin, the price bisected to plain 16's
   RMSE. Calibrated on the truth: the best a rule on that signal alone can do, not a rule.
3. Rules that know more (dynamic programming from the deepest level, each choice on the
   expectation of what follows given what is known, binned as in 2): the first image's
   doubt at one sample and a signal at 9 and 17 (from the level images, or the pixel's own
   samples' range, read as the second round reads it); and the pixel's *true* error at each
   level it reaches (but not at the levels it has not traced) — the bound of any estimate
   of a pixel's present error on this ladder, and the same with a level of 4 samples
   (the 2×2 grid, 5 traced) and on to 36 (the 6×6 grid, which holds the 2×2 one's
   centres, 37 traced) added.
Samples do not depend on the machine's load.
"""
import sys
from pathlib import Path

import numpy as np

import mimarble
from mimarble.bench.oracle import oracle_choice, oracle_scene, price_for, squared_errors
from mimarble.mitsuba.rendering import adaptive
from mimarble.mitsuba.rendering.render import render_in_passes

dr, mi = mimarble.dr, mimarble.mi


def shifted(image, dy, dx):
    """``image`` moved by (dy, dx), clipped at the border (as adaptive._neighbours)."""
    h, w = image.shape[:2]
    rows = np.clip(np.arange(h) + dy, 0, h - 1)
    columns = np.clip(np.arange(w) + dx, 0, w - 1)
    return image[rows][:, columns]


def window(image, radius):
    return [shifted(image, dy, dx) for dy in range(-radius, radius + 1)
            for dx in range(-radius, radius + 1)]


def signals(first):
    """Candidate signals per pixel (H, W) from the 1-spp image (H, W, 3)."""
    big = lambda a: np.max(np.abs(a), axis=-1)
    around = window(first, 1)
    total = sum(around)
    second = 0.125 * big(total - 9 * first)
    deviation = np.max([big(a - first) for a in around], axis=0)
    range3 = big(np.max(around, axis=0) - np.min(around, axis=0))
    wide = window(first, 2)
    range5 = big(np.max(wide, axis=0) - np.min(wide, axis=0))
    std5 = np.max(np.std(wide, axis=0), axis=-1)
    std3 = np.max(np.std(around, axis=0), axis=-1)
    mean3 = total / 9
    value = np.max(first, axis=-1)
    # The pixel against the neighbourhood's spread: how far it is from its neighbours'
    # mean in units of their spread.
    z = big(first - mean3) / np.maximum(std3, 1e-6)
    current = np.maximum(second, adaptive.DEVIATION_SHARE * deviation)
    # Deviation from the 3x3 median (robust centre).
    median = np.median(around, axis=0)
    med_dev = big(first - median)
    return {"second": second, "deviation": deviation, "current doubt": current,
            "range3": range3, "range5": range5, "std3": std3, "std5": std5,
            "value": value, "z (|x-mean3|/std3)": z, "|x-median3|": med_dev,
            "current / range5": current / np.maximum(range5, 1e-6),
            "min step": np.sort([big(a - first) for a in around], axis=0)[1]}


def auc(low, high):
    """P(a value of ``low`` < a value of ``high``) (ties half)."""
    values = np.concatenate([low, high])
    ranks = np.argsort(np.argsort(values, kind="stable"), kind="stable") + 1.0
    return (ranks[len(low):].sum() - len(high) * (len(high) + 1) / 2) / (len(low) * len(high))


for path in sys.argv[1:]:
    measured = oracle_scene(path)
    m, truth, rmse = measured.mitsuba, measured.truth, measured.rmse
    images, costs, errors = measured.images, measured.costs, measured.errors
    target = rmse(render_in_passes(m, 16))
    pixels = errors.shape[1]
    cost = np.asarray(costs, np.float64)[:, None]
    chosen = oracle_choice(errors, costs, target)
    oracle = cost[chosen, 0]
    for k in range(40):
        run = adaptive.render_adaptive(m, 1, 0.005 * 2.0 ** (-k / 2), 81)
        if rmse(run.image) <= target:
            break
    refined = run.samples.ravel() > 1
    first = images[costs.index(1)]
    ones = refined & (oracle == 1)
    others = refined & (oracle > 1)
    print(f"{Path(path).stem}: oracle {oracle.mean():.2f} samples a pixel, ours "
          f"{run.traced / pixels:.2f}; we refine {refined.sum()} pixels, the oracle leaves "
          f"{ones.sum()} of them at 1; their e1² share of the image's "
          f"{errors[0][ones].sum() / errors[0].sum():.3f}")
    print(f"  {'signal':24s} {'oracle 1s: quartiles':34s} {'oracle >1: quartiles':34s} AUC")
    for name, signal in signals(first).items():
        signal = signal.ravel()
        q = lambda s: " ".join(f"{v:.4g}" for v in np.percentile(s, [25, 50, 75]))
        print(f"  {name:24s} {q(signal[ones]):34s} {q(signal[others]):34s} "
              f"{auc(signal[ones], signal[others]):.3f}")
    # Each signal as the only knowledge: pixels binned by it (quantiles), each bin's mean
    # squared error at each level, the Lagrangian choice per bin: the samples a pixel a
    # rule reading this signal alone could reach plain 16's RMSE with (calibrated on the
    # truth: a bound for rules on this signal, not a rule).
    table = signals(first)
    table["(true e1², the bound)"] = errors[costs.index(1)].reshape(first.shape[:2])
    pairs = {"second × value": ("second", "value"), "current × value": ("current doubt", "value"),
             "second × std5": ("second", "std5"), "current × z": ("current doubt", "z (|x-mean3|/std3)")}
    def binned(values, bins):
        edges = np.unique(np.percentile(values, np.linspace(0, 100, bins + 1)[1:-1]))
        return np.searchsorted(edges, values)
    keys = {name: binned(v.ravel(), 48) for name, v in table.items()}
    for pair, (a, b) in pairs.items():
        keys[pair] = binned(table[a].ravel(), 12) * 16 + binned(table[b].ravel(), 12)
    print(f"  a rule on one signal at its best (bins calibrated on the truth), samples a pixel:")
    for name, key in keys.items():
        _, key = np.unique(key, return_inverse=True)
        sizes = np.bincount(key)
        means = np.stack([np.bincount(key, weights=e) / sizes for e in errors])  # (levels, bins)
        choose = lambda price: np.argmin(means + price * cost, axis=0)[key]
        pick = choose(price_for(lambda price: np.sqrt(
            np.mean(errors[choose(price), np.arange(pixels)]) / 3), target, steps=80))
        print(f"    {name:24s} {cost[pick, 0].mean():.2f}  levels {dict(zip(*[a.tolist() for a in np.unique(cost[pick, 0].astype(int), return_counts=True)]))}")
    # A rule that knows, at each level it reaches, the pixel's true error there (but not
    # the error at the levels it has not traced), and expects the next level's from the
    # present one (binned, calibrated on the truth): the best any estimate of a pixel's
    # present error can do on this ladder. Dynamic programming, from the deepest level.
    at = {c: errors[costs.index(c)] for c in costs}
    def expected(values, given, bins=48):
        key = binned(given, bins)
        _, key = np.unique(key, return_inverse=True)
        return (np.bincount(key, weights=values) / np.bincount(key))[key]
    def stopping(price, s1, s9, s17):
        """The DP with knowledge s1, s9, s17 at each level (binned, calibrated)."""
        stay9 = expected(at[9], s9) <= expected(at[81], s9) + price * 72
        stay17 = expected(at[17], s17) <= expected(at[98], s17) + price * 81
        final9, cost9 = np.where(stay9, at[9], at[81]), np.where(stay9, 9, 81)
        final17, cost17 = np.where(stay17, at[17], at[98]), np.where(stay17, 17, 98)
        options = [expected(at[1], s1), expected(final9, s1) + price * 8,
                   expected(final17, s1) + price * 16]
        choice = np.argmin(options, axis=0)
        final = np.choose(choice, [at[1], final9, final17])
        spent = np.choose(choice, [np.ones_like(cost9), cost9, cost17])
        return np.sqrt(np.mean(final) / 3), spent
    image = {c: images[costs.index(c)] for c in costs}
    big = lambda a: np.max(np.abs(a), axis=-1).ravel()
    second_of = lambda c: signals(image[c])["second"].ravel()
    current = table["current doubt"].ravel()
    window_range = lambda c: signals(image[c])["range3"].ravel()

    def sample_range(jump):
        """Each pixel's own samples' range (largest colour) at the first round's level, 9
        (``jump`` "never") or 16 ("always"): read where the second round's estimate reads it."""
        seen = []
        plain = adaptive.refine
        def reading(state, packed, pixels, axis, *args, **kwargs):
            if axis > 1 and not seen:
                seen.append(np.max(np.asarray(state.high) - np.asarray(state.low), axis=0))
            return plain(state, packed, pixels, axis, *args, **kwargs)
        adaptive.refine = reading
        try:
            adaptive.render_adaptive(m, 1, -1.0, 81, rounds=2, jump=jump)
        finally:
            adaptive.refine = plain
        return seen[0]
    knowledge = {
        "current; own range at 9, 16": (current, sample_range("never"), sample_range("always")),
        "current; range3 of means at 9, 17": (current, window_range(9), window_range(17)),
        "true e1 (binned); true at 9, 17": (at[1], at[9], at[17]),
        "current doubt; true at 9, 17": (current, at[9], at[17]),
        "true e1; second at 9, 17": (at[1], second_of(9), second_of(17)),
        "current doubt; second at 9, 17": (current, second_of(9), second_of(17)),
        "current; |m9-m1|, |m17-m1|": (current, big(image[9] - image[1]), big(image[17] - image[1])),
        "current; doubt at 9,17 (1/n²)": (current, current, current),
    }
    for name, (s1, s9, s17) in knowledge.items():
        price = price_for(lambda price: stopping(price, s1, s9, s17)[0], target, steps=80)
        spent = stopping(price, s1, s9, s17)[1]
        print(f"    DP: {name:34s} {spent.mean():.2f}  levels "
              f"{dict(zip(*[a.tolist() for a in np.unique(spent, return_counts=True)]))}")
    # The same bound with a level of 4 samples added (the 2×2 grid, replacing the first
    # sample: 5 traced) and on from it to the 6×6 grid (which holds the 2×2 one's centres:
    # 37 traced): would a ladder through 4 leave more pixels low?
    for c, spp in ((5, 4), (37, 36)):
        at[c] = squared_errors([render_in_passes(m, spp)], truth)[0]
    def tree(price, ladder):
        """Best cost-plus-error from each level down, knowing each reached level's error."""
        def value(c):
            # (what the choice expects, the error it ends with, the samples it traces)
            options = [(at[c], at[c], np.full(pixels, float(c)))]
            for nxt in ladder.get(c, ()):
                final, spent = value(nxt)
                options.append((expected(final + price * (spent - c), at[c]), final, spent))
            best = np.argmin([o[0] for o in options], axis=0)
            return (np.choose(best, [o[1] for o in options]),
                    np.choose(best, [o[2] for o in options]))
        return value(1)
    for name, ladder in (("1 9 17 81 98", {1: (9, 17), 9: (81,), 17: (98,)}),
                         ("+ 4, 36", {1: (5, 9, 17), 5: (37,), 9: (81,), 17: (98,)})):
        price = price_for(lambda price: np.sqrt(np.mean(tree(price, ladder)[0]) / 3), target,
                          steps=80)
        final, spent = tree(price, ladder)
        print(f"    DP, true errors, ladder {name:14s} {spent.mean():.2f}  levels "
              f"{dict(zip(*[a.tolist() for a in np.unique(spent.astype(int), return_counts=True)]))}")
    e1 = np.sqrt(errors[0]).ravel()
    print(f"  {'(true |e1|)':24s} {np.percentile(e1[ones], [25, 50, 75]).round(4)} "
          f"{np.percentile(e1[others], [25, 50, 75]).round(4)} {auc(e1[ones], e1[others]):.3f}")
