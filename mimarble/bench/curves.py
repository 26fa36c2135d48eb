"""Error against time: when a mode's curve (its runs, coarse to fine) reaches an RMSE,
each mode's time to plain 16 and 64 spp's RMSE and its speed-ups, per scene and over the
paper's scenes. Reads only the runs' dicts (NumPy, no renderer)."""

from __future__ import annotations

import numpy as np

from mimarble.bench.modes import TARGET_SPPS, is_paper_scene
from mimarble.bench.report import setting



def _crossing(rmses, target: float):
    """Where a curve's RMSEs (coarse to fine) reach ``target``: ``(i, f)``, the crossing at
    fraction ``f`` in log(RMSE) from point ``i`` to point ``i + 1`` (``(0, 0.0)``: the
    first point already reaches it); None when no point does."""
    rmses = [float(e) for e in rmses]
    if not rmses:
        return None
    if rmses[0] <= target:
        return 0, 0.0
    for i, (e0, e1) in enumerate(zip(rmses, rmses[1:])):
        if e0 > target >= e1:
            if e1 <= 0 or target <= 0:        # no logarithm: the later point
                return i, 1.0
            return i, float((np.log(e0) - np.log(target)) / (np.log(e0) - np.log(e1)))
    return None


def _log_between(a: float, b: float, f: float) -> float:
    """Linear in the logarithm from ``a`` (f = 0) to ``b`` (f = 1)."""
    if f == 0.0:
        return float(a)
    if f == 1.0 or a <= 0 or b <= 0:
        return float(b)
    return float(np.exp(np.log(a) + f * (np.log(b) - np.log(a))))


def time_to_rmse(curve, target: float) -> float | None:
    """When a mode's curve on one scene, its ``(run_ms, rmse)`` points in the order of the
    mode's settings (coarse to fine: spp up, an adaptive threshold down), reaches RMSE
    ``target``: between the first two neighbouring points that bracket it (the coarser
    above, the finer at or below), linearly in log(time) against log(RMSE); the coarsest
    (cheapest) point's time when it already reaches it; None when no point does (no
    extrapolation beyond the measured points). The settings' order, not the times', so
    that a noisy timing cannot reorder the curve (on a quiet machine they agree)."""
    curve = [(float(t), float(e)) for t, e in curve]
    at = _crossing([e for _, e in curve], target)
    if at is None:
        return None
    i, f = at
    return _log_between(curve[i][0], curve[min(i + 1, len(curve) - 1)][0], f)


def value_at_crossing(curve, target: float, key: str) -> float | None:
    """``key`` of a curve's runs (dicts, coarse to fine) where :func:`time_to_rmse` puts
    the crossing, interpolated as the time is (its logarithm linear in log RMSE)."""
    at = _crossing([r["rmse"] for r in curve], target)
    if at is None:
        return None
    i, f = at
    return _log_between(curve[i][key], curve[min(i + 1, len(curve) - 1)][key], f)


def times_to_plain_rmse(runs, target_spps=TARGET_SPPS) -> dict:
    """Each mode's time to plain ``spp``'s RMSE for every spp of ``target_spps``
    (:func:`time_to_rmse` on the mode's curve), per scene, and the speed-ups (plain's
    own time at that spp over the mode's), with means over the paper scenes and each
    other scene (fine veins, …) on its own.

    ``{"targets": [16, 64], "by_scene": {scene: {"16": {"rmse", "plain_ms", "by_mode":
    {mode: {"ms", "speedup", "mean_spp"} or None (never reached)}}}}, "groups": {"paper"
    or scene: {"scenes": [...], "16": {mode: {"mean_speedup", "worst_speedup",
    "mean_ms", "mean_spp", "reached", "missed": [scenes]}}}}}`` — a mode that never
    reaches the target on a scene counts as missed there: the mean is over the scenes
    it reached, and ``missed`` names the others. ``mean_spp``: the samples traced per
    pixel at the crossing (interpolated as the time)."""
    by_scene = {}
    for scene in sorted({r["scene"] for r in runs}):
        mine = [r for r in runs if r["scene"] == scene]
        modes = list(dict.fromkeys(r["mode"] for r in mine))
        out = {}
        for spp in target_spps:
            plain = next((r for r in mine if r["mode"] == "plain" and r["spp"] == spp), None)
            if plain is None:
                continue
            by_mode = {}
            for mode in modes:
                curve = sorted((r for r in mine if r["mode"] == mode), key=setting)
                ms = time_to_rmse([(r["run_ms"], r["rmse"]) for r in curve], plain["rmse"])
                by_mode[mode] = None if ms is None else {
                    "ms": ms, "speedup": plain["run_ms"] / ms,
                    "mean_spp": value_at_crossing(curve, plain["rmse"], "mean_spp")
                    if all("mean_spp" in r for r in curve) else None}
            out[str(spp)] = {"rmse": plain["rmse"], "plain_ms": plain["run_ms"],
                             "by_mode": by_mode}
        if out:
            by_scene[scene] = out
    groups = {}
    paper = [s for s in by_scene if is_paper_scene(s)]
    for group, members in ([("paper", paper)] if paper else []) + [
            (s, [s]) for s in by_scene if not is_paper_scene(s)]:
        summary = {"scenes": members}
        for spp in map(str, target_spps):
            at = [by_scene[s][spp] for s in members if spp in by_scene[s]]
            if not at:
                continue
            modes = list(dict.fromkeys(m for a in at for m in a["by_mode"]))
            summary[spp] = {}
            for mode in modes:
                reached = {s: by_scene[s][spp]["by_mode"].get(mode) for s in members
                           if spp in by_scene[s]}
                got = [v for v in reached.values() if v]
                spps = [v["mean_spp"] for v in got if v["mean_spp"] is not None]
                summary[spp][mode] = {
                    "reached": len(got), "of": len(reached),
                    "missed": [s for s, v in reached.items() if not v],
                    "mean_speedup": float(np.mean([v["speedup"] for v in got])) if got else None,
                    "worst_speedup": float(min(v["speedup"] for v in got)) if got else None,
                    "mean_ms": float(np.mean([v["ms"] for v in got])) if got else None,
                    "mean_spp": float(np.mean(spps)) if spps else None}
        groups[group] = summary
    return {"targets": list(target_spps), "by_scene": by_scene, "groups": groups}


def adaptive_columns(results: dict) -> dict:
    """Per scene, what issue 43 adds beside the time to plain 16 and 64 spp's RMSE: plain 16
    spp's time per traced sample, each adaptive mode's at its crossing of plain 16 spp's
    RMSE (its time there over its samples there) and their ratio; the oracle's samples a
    pixel for each target beside the mode's (``results["oracle"]``,
    mimarble/bench/oracle.py); and the best mode, the one that reaches each target
    soonest. ``{scene: {"plain_ns": …, "modes": {mode: {"ns", "ratio", "spp": {"16", "64"},
    "oracle_spp": {…}}}, "best": {"16": mode or None, "64": …}}}``."""
    pixels = results["size"] ** 2
    by_scene = results.get("time_to_rmse", {}).get("by_scene", {})
    oracle = results.get("oracle", {})
    out = {}
    for scene, at in by_scene.items():
        if "16" not in at:
            continue
        plain_ns = 1e6 * at["16"]["plain_ms"] / (16 * pixels)
        modes = {}
        for mode in at["16"]["by_mode"]:
            if not mode.startswith("adaptive"):
                continue
            crossing = at["16"]["by_mode"][mode]
            ns = (1e6 * crossing["ms"] / (crossing["mean_spp"] * pixels)
                  if crossing and crossing.get("mean_spp") else None)
            modes[mode] = {"ns": ns, "ratio": None if ns is None else ns / plain_ns,
                           "spp": {t: (at[t]["by_mode"].get(mode) or {}).get("mean_spp")
                                   for t in at},
                           "oracle_spp": oracle.get(scene, {}).get(mode, {})}
        best = {}
        for target in at:
            reached = {m: v["ms"] for m, v in at[target]["by_mode"].items() if v}
            best[target] = min(reached, key=reached.get) if reached else None
        out[scene] = {"plain_ns": plain_ns, "modes": modes, "best": best}
    return out


def speedups_at_equal_error(runs) -> dict:
    """Per scene and mode: the fastest run of the mode whose RMSE is at most plain 16 spp's,
    and plain 16 spp's time over its time (None: no run of the mode got there)."""
    out = {}
    for scene in sorted({r["scene"] for r in runs}):
        mine = [r for r in runs if r["scene"] == scene]
        plain16 = next((r for r in mine if r["mode"] == "plain" and r["spp"] == 16), None)
        if plain16 is None:
            continue
        out[scene] = {}
        for mode in sorted({r["mode"] for r in mine} - {"plain"}):
            good = [r for r in mine if r["mode"] == mode and r["rmse"] <= plain16["rmse"]]
            best = min(good, key=lambda r: r["run_ms"]) if good else None
            out[scene][mode] = None if best is None else {
                "spp": best["spp"], "edge_spp": best.get("edge_spp"),
                "threshold": best.get("threshold"), "run_ms": best["run_ms"],
                "rmse": best["rmse"], "plain16_ms": plain16["run_ms"],
                "plain16_rmse": plain16["rmse"], "speedup": plain16["run_ms"] / best["run_ms"]}
    return out
