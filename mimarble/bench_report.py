"""``mimarble bench``'s results as text: the table every run and target is printed in.

Reads only the results dict of :func:`mimarble.bench.run_bench` (or its JSON read
back), so a saved benchmark is reported without loading Dr.Jit or Mitsuba. The
targets' modes are the ones the results hold, in the order they were measured.
"""

from __future__ import annotations

import numpy as np

from .machine import machine_line


def _target_modes(targets: dict) -> list[str]:
    """The modes the targets compared (``bench.TARGET_MODES``), in their order."""
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
        lines.append(f"  {mode:15}: {mean}, {worst}   target ≥ 4× (prefilter+edges)")
    return lines


def _process_lines(p, povray) -> list[str]:
    against = (f"   POV-Ray's whole process {povray['process_s']:.2f} s: target faster"
               if povray else "")
    return ["", f"Whole process, `python -m mimarble …` (medians of {p['repeats']}):",
            f"  --help: {p['help_s']:.3f} s   target < 0.15",
            f"  a malformed scene (FILE:LINE:COL): {p['malformed_scene_s']:.3f} s   target < 0.15",
            f"  render fig11a 500², 1 spp, warm caches: {p['render_warm_s']:.2f} s{against}",
            f"  the same, empty kernel and parser caches (a new user): {p['render_cold_s']:.2f} s"]


def _povray_lines(p) -> list[str]:
    return ["", f"Against {p['version']} on the same kind of marble sphere (fig11a, 500², 1 sample):",
            f"  render: POV-Ray trace {p['trace_s'] * 1000:.0f} ms, ours {p['ours_ms']:.1f} ms "
            f"(POV-Ray / ours {p['trace_over_ours']:.1f}×; target ≥ 10)",
            f"  whole process, warm: POV-Ray {p['process_s']:.2f} s, `mimarble render` "
            f"{p['ours_process_s']:.2f} s (POV-Ray / ours {p['process_over_ours']:.2f}×)"]


def calls_lines(calls: dict) -> list[str]:
    """Whole calls against their kernels (mimarble/bench_calls.py), as a table."""
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
    lines.append(f"{'scene':8} {'mode':15} {'spp':>4} {'run ms':>8} {'compile ms':>10} "
                 f"{'new kernels':>11} {'RMSE':>8} {'PSNR dB':>8} {'interior':>8}")
    for r in results["runs"]:
        lines.append(f"{r['scene']:8} {r['mode']:15} {r['spp']:>4} {r['run_ms']:>8.1f} "
                     f"{r['compile_ms']:>10.1f} {r['kernels_compiled']:>11} {r['rmse']:>8.4f} "
                     f"{r['psnr']:>8.1f} {r.get('interior_rmse', float('nan')):>8.4f}")
    lines += _speedup_lines(results.get("speedup_at_plain16_rmse") or {})
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
                         f"({r['t32_ms']:.1f} / {r['t8_ms']:.1f} ms)   target ≤ 1.3")
        r = t.get("tolerance_error_32")
        if r:
            lines.append(f"  at 32 octaves, tolerance {r['tolerance']:.3g}: {r['octaves_evaluated']} "
                         f"octaves evaluated, max colour error against the float64 full sum "
                         f"{r['max_error']:.3g} (allowed: tolerance + float32 "
                         f"{r['float32_bound']:.2g} + octaves past 25 {r['skipped_bound']:.2g})")
        r = t["marble8_over_constant"]
        lines.append(f"  time(marble, 8 octaves)/time(constant colour): {r['ratio']:.2f} "
                     f"({r['marble_ms']:.1f} / {r['constant_ms']:.1f} ms)   target ≤ 3.0, stretch 2.0")
        r = t["octave_evals_per_s_per_core"]
        rate = f"{r['rate'] / 1e6:.0f} M" if r["rate"] else "not measurable (noisy machine)"
        lines.append(f"  octave evaluations per second per core in the render: {rate} "
                     f"(24 octaves vs none: {r['t24_ms']:.1f} - {r['t0_ms']:.1f} ms over "
                     f"{r['hits']:.0f} hits, {r['cores']} cores)   target ≥ 100 M, stretch 200 M")
        r = t["rmse_0.01"]
        for mode in _target_modes(t):
            curve = ", ".join(f"{c['spp']} spp {c['run_ms']:.0f} ms RMSE {c['rmse']:.4f}"
                              for c in r["by_mode"][mode]["curve"])
            lines.append(f"  RMSE ≤ 0.01, {mode:9}: {curve}")
        speedup = r["speedup"]
        lines.append("  band-limited speed-up to RMSE ≤ 0.01: "
                     + (f"{speedup:.2f}×" if speedup else "not reached by both modes")
                     + "   target ≥ 4×")
    if results.get("process"):
        lines += _process_lines(results["process"], results.get("povray"))
    if results.get("povray"):
        lines += _povray_lines(results["povray"])
    if results.get("calls"):
        lines += calls_lines(results["calls"])
    return "\n".join(lines)
