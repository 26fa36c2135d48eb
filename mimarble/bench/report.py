"""``mimarble bench``'s results as text: the table every run and target is printed in.

Reads only the results dict of :func:`mimarble.bench.run.run_bench` (or its JSON read
back), so a saved benchmark is reported without loading Dr.Jit or Mitsuba. The
targets' modes are the ones the results hold, in the order they were measured.

A run is one scene in one mode at one *setting*: its spp, or an adaptive mode's
threshold (:func:`setting`); the helpers here name settings for the page and the plot too.
"""

from __future__ import annotations

import numpy as np

from mimarble.bench.goals import (ADAPTIVE_TARGETS, MARBLE_OVER_CONSTANT, OCTAVE_RATE, OCTAVES_32_OVER_8,
                                  POVRAY_OVER_OURS, PROCESS_SECONDS, RMSE_SPEEDUP)
from mimarble.runtime.machine import machine_line


def setting(run: dict):
    """What a run varies along its mode's curve: ``("threshold", T)`` for an adaptive
    run, else ``("spp", spp)``; sorts coarse to fine within a mode."""
    if run.get("threshold") is not None:
        return ("threshold", -run["threshold"])
    return ("spp", run["spp"])


def setting_label(run: dict) -> str:
    """A run's setting in words: ``16 spp`` or ``threshold 0.005``."""
    if run.get("threshold") is not None:
        return f"threshold {run['threshold']:g}"
    return f"{run['spp']} spp"


def paper_runs(runs: list) -> list:
    """The runs of the paper's scenes (``fig…``), the ones means are taken over; all of
    them when there are none (a benchmark of other scenes only)."""
    mine = [r for r in runs if r["scene"].startswith("fig")]
    return mine or list(runs)


def _target_modes(targets: dict) -> list[str]:
    """The modes the targets compared (``mimarble.bench.modes.TARGET_MODES``), in their order."""
    return list(targets["rmse_0.01"]["by_mode"])


def _speedup_lines(speedups: dict) -> list[str]:
    """Each mode's speed-up over plain 16 spp at no more RMSE: per scene, mean, worst."""
    modes = sorted({m for by_mode in speedups.values() for m in by_mode})
    if not modes:
        return []
    lines = ["", "Speed-up over plain 16 spp at equal or lower RMSE (fastest run that gets there):"]
    for mode in modes:
        values = [by_mode.get(mode) for by_mode in speedups.values()]
        reached = [v["speedup"] for v in values if v]
        worst = "not reached on every scene" if len(reached) < len(values) else \
            f"worst {min(reached):.2f}×"
        mean = f"mean {np.mean(reached):.2f}× over {len(reached)} of {len(values)} scenes" \
            if reached else "reached on no scene"
        goal = f"   {RMSE_SPEEDUP.in_report()}" if mode == "prefilter+edges" else ""
        lines.append(f"  {mode:18}: {mean}, {worst}{goal}")
    return lines


def _cell(v: dict | None) -> str:
    """One scene's crossing: speed-up, time, samples per pixel; — where never reached."""
    if not v:
        return "—"
    spp = f" {v['mean_spp']:.1f} spp" if v.get("mean_spp") is not None else ""
    return f"{v['speedup']:.2f}× {v['ms']:.1f} ms{spp}"


def group_cell(g: dict | None) -> str:
    """A group's crossing: mean speed-up (worst), mean time and samples, and the scenes
    where the mode never got there."""
    if not g:
        return "—"
    if not g["reached"]:
        return f"missed on all {g['of']}"
    spp = f", {g['mean_spp']:.1f} spp" if g.get("mean_spp") is not None else ""
    text = (f"{g['mean_speedup']:.2f}×" + (f" (worst {g['worst_speedup']:.2f}×)" if g["of"] > 1
                                           else "") + f", {g['mean_ms']:.1f} ms{spp}")
    if g["missed"]:
        text += f"; missed on {len(g['missed'])} of {g['of']}: {', '.join(g['missed'])}"
    return text


def group_name(name: str, group: dict) -> str:
    return (f"paper scenes (mean of {len(group['scenes'])})" if name == "paper" else name)


def time_to_rmse_lines(ttr: dict) -> list[str]:
    """Each mode's time to plain N spp's RMSE: every scene, then the means (paper scenes;
    every other scene on its own), with the adaptive targets."""
    lines = []
    for spp in map(str, ttr["targets"]):
        scenes = {s: by[spp] for s, by in ttr["by_scene"].items() if spp in by}
        if not scenes:
            continue
        modes = list(dict.fromkeys(m for at in scenes.values() for m in at["by_mode"]))
        width = 24
        lines += ["", f"Time to plain {spp} spp's RMSE (each mode's curve, log-log between the "
                      f"runs around it): speed-up over plain {spp} spp's time, time, samples "
                      f"per pixel; — never reached",
                  f"{'scene':15} {'RMSE':>8} {'plain ms':>8}  "
                  + " ".join(f"{m:{width}}" for m in modes)]
        for scene, at in scenes.items():
            lines.append(f"{scene:15} {at['rmse']:>8.4f} {at['plain_ms']:>8.1f}  "
                         + " ".join(f"{_cell(at['by_mode'].get(m)):{width}}" for m in modes))
        target = ADAPTIVE_TARGETS.get(spp)
        for name, group in ttr["groups"].items():
            if spp not in group:
                continue
            lines.append(f"  {group_name(name, group)}:")
            for mode, g in group[spp].items():
                goal = (f"   target ≥ {target:g}×" if target and mode.startswith("adaptive")
                        else "")
                lines.append(f"    {mode:18} {group_cell(g)}{goal}")
    return lines


def adaptive_column_lines(columns: dict) -> list[str]:
    """Issue 43's columns: time per traced sample (plain 16 spp's, the adaptive mode's at
    plain 16 spp's RMSE, their ratio), samples a pixel to plain 16 and 64 spp's RMSE
    against the oracle's, and the mode that reaches each soonest."""
    def number(v, form):
        return "—" if v is None else format(v, form)
    lines = ["", "Adaptive sampling against plain and the oracle: ns per traced sample (plain "
                 "16 spp; the mode at plain 16 spp's RMSE) and their ratio; samples a pixel "
                 "to plain 16 / 64 spp's RMSE, ours and the oracle's; the soonest mode",
             f"{'scene':15} {'mode':18} {'plain ns':>8} {'ns':>7} {'ratio':>6} "
             f"{'16: ours':>8} {'oracle':>6} {'64: ours':>8} {'oracle':>6}  soonest to 16 / 64"]
    for scene, c in columns.items():
        best = f"{c['best'].get('16') or '—'} / {c['best'].get('64') or '—'}"
        for mode, m in c["modes"].items():
            lines.append(
                f"{scene:15} {mode:18} {c['plain_ns']:>8.1f} {number(m['ns'], '7.1f'):>7} "
                f"{number(m['ratio'], '6.2f'):>6} {number(m['spp'].get('16'), '8.1f'):>8} "
                f"{number(m['oracle_spp'].get('16'), '6.1f'):>6} "
                f"{number(m['spp'].get('64'), '8.1f'):>8} "
                f"{number(m['oracle_spp'].get('64'), '6.1f'):>6}  {best}")
    return lines


def best_of_words(p) -> str:
    """" (best of 5)" after the malformed scene's time, when it was the least of its runs
    (results of before issue 39 have its median)."""
    runs = p.get("malformed_scene_runs")
    return f" (best of {runs})" if runs else ""


def _process_lines(p, povray) -> list[str]:
    against = (f"   POV-Ray's whole process {povray['process_s']:.2f} s: target faster"
               if povray else "")
    return ["", f"Whole process, `python -m mimarble …` (medians of {p['repeats']}):",
            f"  --help: {p['help_s']:.3f} s   {PROCESS_SECONDS.in_report()}",
            f"  a malformed scene (FILE:LINE:COL): {p['malformed_scene_s']:.3f} s"
            f"{best_of_words(p)}   {PROCESS_SECONDS.in_report()}",
            f"  render fig11a 500², 1 spp, warm caches: {p['render_warm_s']:.2f} s{against}",
            f"  the same, empty kernel and parser caches (a new user): {p['render_cold_s']:.2f} s"]


def _povray_lines(p) -> list[str]:
    return ["", f"Against {p['version']} on the same kind of marble sphere (fig11a, 500², 1 sample):",
            f"  render: POV-Ray trace {p['trace_s'] * 1000:.0f} ms, ours {p['ours_ms']:.1f} ms "
            f"(POV-Ray / ours {p['trace_over_ours']:.1f}×; {POVRAY_OVER_OURS.in_report()})",
            f"  whole process, warm: POV-Ray {p['process_s']:.2f} s, `mimarble render` "
            f"{p['ours_process_s']:.2f} s (POV-Ray / ours {p['process_over_ours']:.2f}×)"]


def calls_lines(calls: dict) -> list[str]:
    """Whole calls against their kernels (mimarble/bench/calls.py), as a table."""
    lines = ["", "Whole call against its kernels (warm; kernels: Dr.Jit's kernel history):",
             "| call | replay | whole call | its kernels | ratio | launches |",
             "|---|---|---|---|---|---|"]
    for r in calls["renders"]:
        lines.append(f"| {r['call']} | {'on' if r['replay'] else 'off'} | "
                     f"{r['whole_ms']:.2f} ms | {r['kernels_ms']:.2f} ms | "
                     f"{r['ratio']:.2f}× | {r['launches']} |")
    s = calls["sweep"]
    lines.append(f"| {s['call']} | on | {s['whole_s']:.2f} s | {s['kernels_s']:.2f} s "
                 f"+ compile {s['compile_s']:.2f} s | {s['ratio']:.2f}× | |")
    adam = calls.get("adam_step")
    if adam:
        for name in ("traced", "frozen"):
            r = adam[name]
            lines.append(f"| one Adam step of notebook 02 (64², 16 spp prb), {name} | "
                         f"{'on' if name == 'frozen' else 'off'} | {r['whole_ms']:.1f} ms | "
                         f"{r['kernels_ms']:.1f} ms | {r['whole_ms'] / r['kernels_ms']:.2f}× | "
                         f"{r['launches']:g} |")
        lines.append(f"Adam step frozen against traced: "
                     f"{adam['traced']['whole_ms'] / adam['frozen']['whole_ms']:.2f}×; largest "
                     f"difference of losses {adam['loss_difference']:.3g}, of parameters "
                     f"{adam['parameter_difference']:.3g}")
    p = calls.get("povray")
    if p:
        lines.append(f"POV-Ray ({p['version']}) trace of the 8-octave sphere, 500², 1 sample: "
                     f"{p['trace_s'] * 1000:.1f} ms; warm mimarble.render {p['ours_ms']:.2f} ms: "
                     f"POV-Ray / ours {p['trace_over_ours']:.1f}×")
    if calls.get("peers"):
        lines += ["", "The noise alone, one thread (M octave-evals/s):"]
        lines += [f"  {r['name']}: " + (f"{r['m_octave_evals_per_s']:.1f}" if
                                        r["m_octave_evals_per_s"] is not None else "—")
                  + f" ({r['points']} points; {r['note']})" for r in calls["peers"]]
    return lines


def format_report(results: dict) -> str:
    """The whole report: every run, the speed-ups, the paper comparison, the targets, the
    whole-process times and POV-Ray, each section where the results have it."""
    lines = [f"mimarble bench — {machine_line(results['machine'])}",
             f"{results['size']}², error against the float64 reference at "
             f"{results['converged_spp']} spp; times are medians of {results['repeats']} warm runs", ""]
    adaptive = results.get("adaptive")
    if adaptive:
        lines.insert(-1, f"adaptive modes: first pass {adaptive['first_spp']} spp, more samples "
                         f"where a pixel's estimated error is above the threshold, at most "
                         f"{adaptive['max_spp']} spp")
    lines.append(f"{'scene':15} {'mode':18} {'spp':>4} {'threshold':>9} {'mean spp':>8} "
                 f"{'run ms':>8} {'compile ms':>10} {'new kernels':>11} {'RMSE':>8} "
                 f"{'PSNR dB':>8} {'interior':>8}")
    for r in results["runs"]:
        threshold = f"{r['threshold']:>9g}" if r.get("threshold") is not None else f"{'':9}"
        taken = f"{r['mean_spp']:>8.2f}" if r.get("mean_spp") is not None else f"{'':8}"
        lines.append(f"{r['scene']:15} {r['mode']:18} {r['spp']:>4} {threshold} {taken} "
                     f"{r['run_ms']:>8.1f} {r['compile_ms']:>10.1f} {r['kernels_compiled']:>11} "
                     f"{r['rmse']:>8.4f} {r['psnr']:>8.1f} "
                     f"{r.get('interior_rmse', float('nan')):>8.4f}")
    lines += _speedup_lines(results.get("speedup_at_plain16_rmse") or {})
    if results.get("time_to_rmse"):
        lines += time_to_rmse_lines(results["time_to_rmse"])
    if results.get("adaptive_columns"):
        lines += adaptive_column_lines(results["adaptive_columns"])
    if results["paper"]:
        lines += ["", "Against the paper's render column (500×500, the scene's own spp):",
                  f"{'scene':8} {'spp':>4} {'ours s':>8} {'paper s':>8} {'ours/paper':>10} "
                  f"{'reference s':>11}"]
        for r in results["paper"]:
            lines.append(f"{r['scene']:8} {r['spp']:>4} {r['ours_s']:>8.3f} {r['paper_s']:>8.1f} "
                         f"{r['ratio']:>10.4f} {r['reference_s']:>11.2f}")
    t = results.get("targets")
    if t:
        lines += ["", "Targets (fig11a, 500×500, sphere filling the view, 1 spp):"]
        for mode in _target_modes(t):
            r = t[f"octaves32_over_8_{mode}"]
            lines.append(f"  time(octaves 32)/time(octaves 8), {mode:9}: {r['ratio']:.2f} "
                         f"({r['t32_ms']:.1f} / {r['t8_ms']:.1f} ms)   {OCTAVES_32_OVER_8.in_report()}")
        r = t.get("tolerance_error_32")
        if r:
            lines.append(f"  at 32 octaves, tolerance {r['tolerance']:.3g}: {r['octaves_evaluated']} "
                         f"octaves evaluated, max colour error against the float64 full sum "
                         f"{r['max_error']:.3g} (allowed: tolerance + float32 "
                         f"{r['float32_bound']:.2g} + octaves past 25 {r['skipped_bound']:.2g})")
        r = t["marble8_over_constant"]
        lines.append(f"  time(marble, 8 octaves)/time(constant colour): {r['ratio']:.2f} "
                     f"({r['marble_ms']:.1f} / {r['constant_ms']:.1f} ms)   {MARBLE_OVER_CONSTANT.in_report()}")
        r = t["octave_evals_per_s_per_core"]
        rate = f"{r['rate'] / 1e6:.0f} M" if r["rate"] else "not measurable (noisy machine)"
        lines.append(f"  octave evaluations per second per core in the render: {rate} "
                     f"(24 octaves vs none: {r['t24_ms']:.1f} - {r['t0_ms']:.1f} ms over "
                     f"{r['hits']:.0f} hits, {r['cores']} cores)   {OCTAVE_RATE.in_report()}")
        r = t["rmse_0.01"]
        for mode in _target_modes(t):
            curve = ", ".join(f"{c['spp']} spp {c['run_ms']:.0f} ms RMSE {c['rmse']:.4f}"
                              for c in r["by_mode"][mode]["curve"])
            lines.append(f"  RMSE ≤ 0.01, {mode:9}: {curve}")
        speedup = r["speedup"]
        lines.append("  band-limited speed-up to RMSE ≤ 0.01: "
                     + (f"{speedup:.2f}×" if speedup else "not reached by both modes")
                     + f"   {RMSE_SPEEDUP.in_report()}")
    if results.get("process"):
        lines += _process_lines(results["process"], results.get("povray"))
    if results.get("povray"):
        lines += _povray_lines(results["povray"])
    if results.get("calls"):
        lines += calls_lines(results["calls"])
    return "\n".join(lines)
