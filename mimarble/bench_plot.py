"""``mimarble bench --plot``: RMSE against render time, drawn with matplotlib.

Each run of :func:`mimarble.bench.run_bench` is a faint point (one scene, mode and
spp); each mode's curve joins its means over the scenes at each spp; the black
staircase is the Pareto front of all runs — for every time, the least error any run
reached in no more time. Both axes are logarithmic: error falls as a power of the
samples, so equal ratios are equal steps.
"""

from __future__ import annotations

import numpy as np


def plot_error_against_time(results: dict, path) -> None:
    """Error against run time, one curve per mode (mean over scenes per spp), Pareto front."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5))
    runs = results["runs"]
    palette = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")
    names = list(dict.fromkeys(r["mode"] for r in runs))
    colours = dict(zip(names, palette * len(names)))
    for mode in names:
        mine = [r for r in runs if r["mode"] == mode]
        ax.scatter([r["run_ms"] for r in mine], [r["rmse"] for r in mine], s=8, alpha=0.3,
                   color=colours[mode])
        spps = sorted({r["spp"] for r in mine})
        xs = [np.mean([r["run_ms"] for r in mine if r["spp"] == s]) for s in spps]
        ys = [np.mean([r["rmse"] for r in mine if r["spp"] == s]) for s in spps]
        ax.plot(xs, ys, "-o", color=colours[mode], label=f"{mode} (mean over scenes)")
        for x, y, s in zip(xs, ys, spps):
            ax.annotate(f"{s} spp", (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
    points = sorted((r["run_ms"], r["rmse"]) for r in runs)
    front, best = [], float("inf")
    for x, y in points:
        if y < best:
            front.append((x, y))
            best = y
    ax.step(*zip(*front), where="post", color="black", lw=1, label="Pareto front (all runs)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("render time per image (ms, median)")
    ax.set_ylabel("RMSE against converged float64 reference")
    ax.set_title(f"mimarble: error against time ({results['size']}², {results['machine']['variant']})")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
