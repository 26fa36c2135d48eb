"""docs/benchmarks.md's sections per machine: ``mimarble bench --page`` writes its own.

The same render takes other times on another CPU (the project has run on an Intel Xeon,
AMD EPYC Zen 2/3 and Zen 4), so a benchmark page holds one section per machine kind,
each made from one run's results and labelled with the machine, the date and the command.
:func:`write_section` replaces the section of the machine the results were measured on
and keeps every other machine's, so a newcomer finds the table for the CPU in front of
them beside the ones already there.

Reads only the results dict of :func:`mimarble.bench.run.run_bench` (or its JSON read back):
no Dr.Jit, no Mitsuba.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from mimarble.bench.goals import ADAPTIVE_TARGETS, MARBLE_OVER_CONSTANT, OCTAVE_RATE, OCTAVES_32_OVER_8, RMSE_SPEEDUP
from mimarble.bench.report import (group_cell, group_name, paper_runs, setting,
    setting_label, best_of_words)
from mimarble.runtime.files import write_atomically

#: What LLVM's AMD targets are called in AMD's own words.
ZEN = {"znver1": "Zen", "znver2": "Zen 2", "znver3": "Zen 3", "znver4": "Zen 4",
       "znver5": "Zen 5"}

#: Where the machine sections begin and end on the page; everything else is kept.
SECTIONS_START = "<!-- machine sections: `mimarble bench --page` writes its machine's, keeps the others -->"
SECTIONS_END = "<!-- end of machine sections -->"


def machine_label(facts: dict) -> str:
    """A machine kind in words: the CPU, its AMD generation or vector ISA where the
    results know it (LLVM's target, recorded since the AMD runs), its cores."""
    name = re.sub(r"\((R|TM)\)", "", facts.get("processor", "unknown CPU"))
    name = re.sub(r"\s+Processor\b", "", name).strip()
    target = facts.get("llvm_target") or {}
    details = []
    if target.get("cpu") in ZEN:
        details.append(ZEN[target["cpu"]])
    features = target.get("features") or []
    if "+avx512f" in features:
        details.append("AVX-512")
    elif "+avx2" in features:
        details.append("AVX2")
    if target.get("cpu"):
        details.append(f"LLVM target {target['cpu']}")
    kind = f"{name} ({', '.join(details)})" if details else name
    return f"{kind}, {facts.get('cores', '?')} cores"


def machine_slug(facts: dict) -> str:
    """The machine kind as a file-name and anchor word: ``amd-epyc-znver4``."""
    name = re.sub(r"\((R|TM)\)|\bProcessor\b|\bCPU\b", "", facts.get("processor", "unknown"))
    cpu = (facts.get("llvm_target") or {}).get("cpu") or ""
    return re.sub(r"[^a-z0-9]+", "-", f"{name} {cpu}".lower()).strip("-") or "unknown"


def _mean(runs, key):
    return float(np.mean([r[key] for r in runs]))


def _rows(runs) -> list[str]:
    """One row per mode and setting (spp, or an adaptive threshold): means over ``runs``."""
    lines = ["| mode | spp | render time | RMSE | PSNR | samples per pixel |",
             "|---|---|---|---|---|---|"]
    for mode in dict.fromkeys(r["mode"] for r in runs):
        mine = [r for r in runs if r["mode"] == mode]
        for key in sorted({setting(r) for r in mine}):
            at = [r for r in mine if setting(r) == key]
            label = at[0]["spp"] if key[0] == "spp" else setting_label(at[0])
            taken = (f"{_mean(at, 'mean_spp'):.2f}" if all(r.get("mean_spp") is not None
                                                          for r in at) else "")
            lines.append(f"| {mode} | {label} | {_mean(at, 'run_ms'):.1f} ms | "
                         f"{_mean(at, 'rmse'):.4f} | {_mean(at, 'psnr'):.1f} dB | {taken} |")
    return lines


def _error_table(results: dict) -> list[str]:
    runs = results["runs"]
    paper = paper_runs(runs)
    chosen = {id(r) for r in paper}
    others = [r for r in runs if id(r) not in chosen]
    scenes = len({r["scene"] for r in paper})
    which = "every paper scene" if others else "every scene"
    lines = [f"**Run time against error**, {which} at {results['size']}², means over "
             f"{scenes} scenes:", ""] + _rows(paper)
    adaptive = results.get("adaptive")
    if adaptive:
        lines += ["", f"Adaptive modes: a first pass of {adaptive['first_spp']} spp, then more "
                      f"samples where a pixel's estimated error is above the threshold, at most "
                      f"{adaptive['max_spp']} spp; samples per pixel counts every one traced."]
    for scene in dict.fromkeys(r["scene"] for r in others):
        lines += ["", f"**{scene}** ({results['size']}²):", ""]
        lines += _rows([r for r in others if r["scene"] == scene])
    speedups = results.get("speedup_at_plain16_rmse") or {}
    for mode in sorted({m for by_mode in speedups.values() for m in by_mode}):
        reached = [v["speedup"] for v in (b.get(mode) for b in speedups.values()) if v]
        if reached:
            lines += ["", f"Speed-up of {mode} over plain 16 spp at equal or lower RMSE: mean "
                          f"{np.mean(reached):.2f}× over {len(reached)} of {len(speedups)} scenes."]
    return lines


def _time_to_rmse_table(results: dict) -> list[str]:
    """Each mode's time to plain 16 and 64 spp's RMSE, as means over the paper scenes and
    on each other scene: speed-up over plain's time (worst scene), time, samples."""
    ttr = results.get("time_to_rmse")
    if not ttr or not ttr.get("groups"):
        return []
    modes = list(dict.fromkeys(m for g in ttr["groups"].values() for spp in map(str, ttr["targets"])
                               for m in g.get(spp, {})))
    lines = ["", "**Time to plain 16 and 64 spp's RMSE**, each scene's own, interpolated on "
                 "each mode's curve (log time against log RMSE between the runs around it; "
                 "never beyond them): the speed-up over plain's time at that spp, the time and "
                 "the samples per pixel taken; means over the scenes a mode reached, the others "
                 "named. Targets: the adaptive modes "
                 + " and ".join(f"≥ {v:g}× to plain {k}'s" for k, v in ADAPTIVE_TARGETS.items())
                 + ".", "",
             "| RMSE of | scenes | " + " | ".join(modes) + " |",
             "|---|---|" + "---|" * len(modes)]
    for spp in map(str, ttr["targets"]):
        for name, group in ttr["groups"].items():
            if spp in group:
                lines.append(f"| plain {spp} spp | {group_name(name, group)} | "
                             + " | ".join(group_cell(group[spp].get(m)) for m in modes) + " |")
    return lines


def _paper_table(results: dict) -> list[str]:
    if not results.get("paper"):
        return []
    lines = ["", "**Against the paper's render column** (500×500, the scenes' own spp; the "
                 "paper's times are a 2 GHz Pentium 4 in 2004):", "",
             "| scene | ours | paper | ours / paper | reference tracer (NumPy) |",
             "|---|---|---|---|---|"]
    lines += [f"| {r['scene']} | {r['ours_s'] * 1000:.0f} ms | {r['paper_s']:.1f} s | "
              f"{r['ratio']:.4f} | {r['reference_s']:.2f} s |" for r in results["paper"]]
    return lines


def _targets_table(results: dict) -> list[str]:
    t = results.get("targets")
    if not t:
        return []
    lines = ["", "**Targets** (fig11a, 500×500, sphere filling the view, 1 spp):", "",
             "| target | measured |", "|---|---|"]
    modes = list(t["rmse_0.01"]["by_mode"])
    ratios = "; ".join(f"{mode} {t[f'octaves32_over_8_{mode}']['ratio']:.2f} "
                       f"({t[f'octaves32_over_8_{mode}']['t32_ms']:.1f} / "
                       f"{t[f'octaves32_over_8_{mode}']['t8_ms']:.1f} ms)" for mode in modes)
    lines.append(f"| time(octaves 32) / time(octaves 8) {OCTAVES_32_OVER_8.bound} | {ratios} |")
    r = t["marble8_over_constant"]
    lines.append(f"| time(marble, 8 octaves) / time(constant colour) {MARBLE_OVER_CONSTANT.bound}"
                 f"{MARBLE_OVER_CONSTANT.stretched()} | "
                 f"{r['ratio']:.2f} ({r['marble_ms']:.1f} / {r['constant_ms']:.1f} ms) |")
    r = t["octave_evals_per_s_per_core"]
    rate = f"{r['rate'] / 1e6:.0f} M" if r["rate"] else "not measurable (noisy machine)"
    lines.append(f"| {OCTAVE_RATE.bound} octave evaluations / s / core in the render{OCTAVE_RATE.stretched()} | "
                 f"{rate} (24 octaves {r['t24_ms']:.1f} ms − none {r['t0_ms']:.1f} ms over "
                 f"{r['hits']:.0f} hits) |")
    r = t["rmse_0.01"]
    to = ", ".join(f"{mode} {r['by_mode'][mode]['ms_to_rmse_0.01']:.0f} ms"
                   for mode in modes if r["by_mode"][mode].get("ms_to_rmse_0.01"))
    speedup = f"{r['speedup']:.2f}×" if r.get("speedup") else "not reached by both modes"
    lines.append(f"| band-limited reaches RMSE ≤ 0.01 {RMSE_SPEEDUP.bound} sooner | {speedup} ({to}) |")
    return lines


def _process_table(results: dict) -> list[str]:
    p, pov = results.get("process"), results.get("povray")
    lines = []
    if p:
        lines += ["", f"**Whole process**, `python -m mimarble …` (medians of {p['repeats']}): "
                      f"`--help` {p['help_s']:.3f} s; a malformed scene {p['malformed_scene_s']:.3f} s"
                      f"{best_of_words(p)}; "
                      f"render fig11a 500², 1 spp, warm caches {p['render_warm_s']:.2f} s, "
                      f"empty caches {p['render_cold_s']:.2f} s."]
    if pov:
        lines += ["", f"**Against {pov['version']}** (fig11a's sphere, 500², 1 sample): POV-Ray's "
                      f"trace {pov['trace_s'] * 1000:.0f} ms, ours {pov['ours_ms']:.1f} ms "
                      f"({pov['trace_over_ours']:.1f}×); whole process, warm: POV-Ray "
                      f"{pov['process_s']:.2f} s, `mimarble render` {pov['ours_process_s']:.2f} s."]
    return lines


def section(results: dict, plot: str | None = None) -> str:
    """The machine's section of the page: label, provenance, the tables its results hold.
    ``plot``: the error-against-time image, relative to the page."""
    facts = results["machine"]
    slug = machine_slug(facts)
    when = results.get("date", "(date not recorded)")
    command = results.get("command")
    versions = ", ".join(f"{name} {facts[key]}" for name, key in
                         (("Mitsuba", "mitsuba"), ("Dr.Jit", "drjit"), ("Python", "python"))
                         if facts.get(key))
    lines = [f"<!-- machine {slug} -->", f"## {machine_label(facts)}", "",
             f"Measured {when}" + (f" by `{command}`" if command else "")
             + f"; `{facts.get('variant', '?')}`, {versions}. Times are medians of "
             f"{results['repeats']} warm runs after a sync (compile time apart, from Dr.Jit's "
             f"kernel history); RMSE is against the float64 reference tracer at "
             f"{results['converged_spp']} spp.", ""]
    lines += _error_table(results)
    lines += _time_to_rmse_table(results)
    if plot:
        lines += ["", f"![error against time on {machine_label(facts)}]({plot})"]
    lines += _paper_table(results) + _targets_table(results) + _process_table(results)
    lines += [f"<!-- /machine {slug} -->"]
    return "\n".join(lines) + "\n"


def write_section(page, results: dict, plot: str | None = None) -> str:
    """Put the results' machine section into ``page``: in place of that machine's earlier
    section, else last among the sections; everything else on the page, other machines'
    sections and any text between them, is kept as it is. A page without the section
    markers gets them at its end. Written atomically. Returns the machine's slug."""
    page = Path(page)
    text = page.read_text() if page.exists() else "# Benchmarks\n"
    if SECTIONS_START not in text:
        text = text.rstrip("\n") + f"\n\n{SECTIONS_START}\n{SECTIONS_END}\n"
    slug = machine_slug(results["machine"])
    new = section(results, plot)
    head, rest = text.split(SECTIONS_START, 1)
    body, tail = rest.split(SECTIONS_END, 1)
    earlier = re.search(rf"<!-- machine {re.escape(slug)} -->\n.*?<!-- /machine "
                        rf"{re.escape(slug)} -->\n", body, re.S)
    if earlier:
        body = body[:earlier.start()] + new + body[earlier.end():]
    else:
        body = body.rstrip("\n") + "\n\n" + new + "\n"
    text = head + SECTIONS_START + body + SECTIONS_END + tail
    write_atomically(page, lambda tmp: Path(tmp).write_text(text))
    return slug


def plot_relative_to(page, plot) -> str | None:
    """The plot's path as the page links it (relative to the page's folder)."""
    if plot is None:
        return None
    return Path(os.path.relpath(Path(plot).resolve(), Path(page).resolve().parent)).as_posix()
