"""``mimarble bench --plot``: RMSE against render time, drawn with matplotlib.

Each run of :func:`mimarble.bench.run.run_bench` on a paper scene is a faint point (one
scene, mode and spp, or an adaptive mode's threshold); each mode's curve joins its
means over the paper scenes at each setting (over every scene when the benchmark had
no paper scene); the dashed lines are plain 16 and 64 spp's mean RMSE, the levels
each mode's time is measured to (:func:`mimarble.bench.curves.times_to_plain_rmse`, scene by
scene); the black staircase is the Pareto front of the drawn runs — for every time, the
least error any run reached in no more time. Both axes are logarithmic: error falls
as a power of the samples, so equal ratios are equal steps.
"""

from __future__ import annotations

import numpy as np

from mimarble.bench.report import paper_runs, setting
from mimarble.runtime.extras import require_extra


def _short(run: dict) -> str:
    """A point's label: ``16 spp``, or an adaptive run's threshold and samples taken."""
    if run.get("threshold") is None:
        return f"{run['spp']} spp"
    return f"{run['threshold']:g}"


def plot_error_against_time(results: dict, path) -> None:
    """Error against run time, one curve per mode (mean over the paper scenes per spp or
    threshold), plain 16 and 64 spp's RMSE levels, Pareto front."""
    require_extra("bench --plot")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 6))
    runs = paper_runs(results["runs"])
    scenes = len({r["scene"] for r in runs})
    palette = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
               "tab:pink", "tab:olive")
    names = list(dict.fromkeys(r["mode"] for r in runs))
    colours = dict(zip(names, palette * len(names)))
    for mode in names:
        mine = [r for r in runs if r["mode"] == mode]
        adaptive = any(r.get("threshold") is not None for r in mine)
        ax.scatter([r["run_ms"] for r in mine], [r["rmse"] for r in mine], s=8, alpha=0.3,
                   color=colours[mode], marker="^" if adaptive else "o")
        keys = sorted({setting(r) for r in mine})
        at = [[r for r in mine if setting(r) == k] for k in keys]
        xs = [np.mean([r["run_ms"] for r in group]) for group in at]
        ys = [np.mean([r["rmse"] for r in group]) for group in at]
        label = f"{mode} (mean over {scenes} scene{'s' * (scenes != 1)}" + (
            "; labels: threshold, samples per pixel)" if adaptive else ")")
        ax.plot(xs, ys, "--^" if adaptive else "-o", color=colours[mode], label=label)
        for x, y, group in zip(xs, ys, at):
            text = _short(group[0])
            if adaptive and all(r.get("mean_spp") is not None for r in group):
                text += f", {np.mean([r['mean_spp'] for r in group]):.1f}"
            ax.annotate(text, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7,
                        color=colours[mode] if adaptive else "black")
    for spp, style in ((16, (0, (4, 3))), (64, (0, (1, 2)))):
        level = [r["rmse"] for r in runs if r["mode"] == "plain" and r["spp"] == spp
                 and r.get("threshold") is None]
        if level:
            ax.axhline(np.mean(level), color="grey", lw=1, ls=style,
                       label=f"plain {spp} spp's RMSE (mean {np.mean(level):.4f})")
    points = sorted((r["run_ms"], r["rmse"]) for r in runs)
    front, best = [], float("inf")
    for x, y in points:
        if y < best:
            front.append((x, y))
            best = y
    ax.step(*zip(*front), where="post", color="black", lw=1, label="Pareto front (drawn runs)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("render time per image (ms, median)")
    ax.set_ylabel(f"RMSE against converged float64 reference ({results['converged_spp']} spp)")
    which = "paper scene" if any(r["scene"].startswith("fig") for r in runs) else "scene"
    ax.set_title(f"mimarble: error against time, {scenes} {which}{'s' * (scenes != 1)} "
                 f"({results['size']}², {results['machine']['variant']})")
    ax.legend(fontsize=7, loc="upper right", framealpha=0.85)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
