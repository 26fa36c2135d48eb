"""Write a saved benchmark's machine section into docs/benchmarks.md, and the README's
benchmark section from it (every figure there from that one run), without measuring again.

    ./go python scripts/bench_report.py docs/bench/bench-amd-epyc-znver4.json \
        [--plot docs/bench/error-vs-time-amd-epyc-znver4.png] [--readme]

``mimarble bench --page docs/benchmarks.md`` writes the section itself when it runs; this
script re-renders one from its JSON (after the page's layout changed, say). ``--readme``
also rewrites the README's "## Benchmark" section from that JSON, naming its machine.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mimarble.bench.page import machine_label, plot_relative_to, write_section  # noqa: E402
from mimarble.bench.report import paper_runs  # noqa: E402

PAGE = ROOT / "docs" / "benchmarks.md"


def readme_section(b: dict, json_path: Path) -> str:
    """The README's short version of one machine's run, saying where its figures come from."""
    runs = paper_runs(b["runs"])              # the fine-vein scenes are reported on their own
    spps = sorted({r["spp"] for r in runs if r["mode"] == "plain"})
    scenes = len({r["scene"] for r in runs})

    def mean(spp, key):
        return np.mean([r[key] for r in runs if r["mode"] == "plain" and r["spp"] == spp])
    paper = {r["scene"]: r for r in b["paper"]}
    rows = "\n".join(
        f"| {name} ({label}) | {paper[name]['ours_s'] * 1000:.0f} ms | {paper[name]['paper_s']:.1f} s | "
        f"{paper[name]['reference_s']:.2f} s |"
        for name, label in (("fig10a", "1 octave"), ("fig10d", "8 octaves"),
                            ("fig11a", "12 octaves"), ("fig11b", "32 octaves")) if name in paper)
    relative = json_path.resolve().relative_to(ROOT).as_posix()
    lines = []
    calls = b.get("calls") or {}
    model = next((r for r in calls.get("renders", []) if r["replay"]
                  and r["call"].startswith("mimarble.render: 8-octave")), None)
    if model:
        pov = calls.get("povray")
        against = (f", against {pov['version'].split(' ')[0]} {pov['version'].split(' ')[1][:3]}'s "
                   f"{pov['trace_s'] * 1000:.0f} ms trace of the same sphere" if pov else "")
        lines.append(f"A warm `mimarble.render` of fig11a's sphere (500², 1 spp, 8-octave marbles) "
                     f"takes {model['whole_ms']:.1f} ms, {model['ratio']:.2f}× its kernels' own "
                     f"{model['kernels_ms']:.1f} ms{against} (scenes load once, passes replay "
                     f"their recorded kernels).")
    modes = {r["mode"] for r in runs}
    if "prefilter+edges" in modes and 16 in spps:
        def mode_mean(mode, spp, key):
            return np.mean([r[key] for r in runs if r["mode"] == mode and r["spp"] == spp])
        edge_spp = next(r["edge_spp"] for r in runs if r["mode"] == "prefilter+edges")
        lines.append(f"Prefiltered marble with edge samples (`--filter prefilter --edge-spp "
                     f"{edge_spp}`, 4 spp): RMSE {mode_mean('prefilter+edges', 4, 'rmse'):.4f} in "
                     f"{mode_mean('prefilter+edges', 4, 'run_ms'):.1f} ms against plain 16 spp's "
                     f"{mean(16, 'rmse'):.4f} in {mean(16, 'run_ms'):.1f} ms ({b['size']}², mean "
                     f"of {scenes}).")
    paper_group = (b.get("time_to_rmse") or {}).get("groups", {}).get("paper", {})

    def reached(spp, mode):
        v = paper_group.get(spp, {}).get(mode)
        if not v or not v["reached"]:
            return f"never (on none of {v['of'] if v else scenes} scenes)"
        sooner = f"{v['mean_speedup']:.2f}× sooner than plain {spp} spp"
        where = "" if v["reached"] == v["of"] else f" on the {v['reached']} of {v['of']} it reaches"
        return f"{sooner} ({v['mean_spp']:.1f} samples a pixel{where})"
    if paper_group.get("16", {}).get("adaptive"):
        lines.append(f"Adaptive sampling (`--adaptive T`, a first pass of 1 spp, at most "
                     f"{b['adaptive']['max_spp']} spp): plain 16 spp's RMSE "
                     f"{reached('16', 'adaptive')}, with `--filter prefilter` "
                     f"{reached('16', 'adaptive+prefilter')}; plain 64 spp's RMSE "
                     f"{reached('64', 'adaptive')}, with the prefilter "
                     f"{reached('64', 'adaptive+prefilter')} (mean of {scenes}; the targets "
                     f"were 4× and 6×: docs/benchmarks.md).")
    extra = "\n\n".join(lines)
    return f"""## Benchmark

Measured {b.get('date', '')} on an **{machine_label(b['machine'])}** ({b['machine']['variant']};
medians of {b['repeats']} warm runs after a sync; error = RMSE against the float64 reference tracer
at {b['converged_spp']} spp) by `{b.get('command', './go bench')}` (results: `{relative}`).
Timings depend on the CPU: [docs/benchmarks.md](docs/benchmarks.md) has a section for each
machine kind the project has run on, and `./go bench --page docs/benchmarks.md` adds yours.

| every paper scene, {b['size']}², mean of {scenes} | {' | '.join(f'{s} spp' for s in spps)} |
|---|{'---|' * len(spps)}
| render time | {' | '.join(f'{mean(s, "run_ms"):.1f} ms' for s in spps)} |
| RMSE against converged | {' | '.join(f'{mean(s, "rmse"):.4f}' for s in spps)} |

| 500×500, the scenes' 4 spp | ours | paper (P4, 2004) | reference tracer (NumPy) |
|---|---|---|---|
{rows}

{extra}

Whitted renders agree with the reference on every paper scene above 116 dB PSNR, no pixel off by
1/255 (`./go compare SCENE`; [docs/rendering-model.md](docs/rendering-model.md)).

"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("json", type=Path, help="a `mimarble bench --json` file")
    parser.add_argument("--plot", help="its error-against-time plot, linked from the section")
    parser.add_argument("--readme", action="store_true",
                        help="also write the README's benchmark section from it")
    args = parser.parse_args()
    b = json.loads(args.json.read_text())
    slug = write_section(PAGE, b, plot_relative_to(PAGE, args.plot))
    print(f"wrote the section {slug} into {PAGE}")
    if args.readme:
        readme = (ROOT / "README.md").read_text()
        start = readme.index("## Benchmark")
        end = readme.index("\n## ", start) + 1
        (ROOT / "README.md").write_text(readme[:start] + readme_section(b, args.json)
                                        + readme[end:])
        print("updated README.md")


if __name__ == "__main__":
    main()
