"""The benchmarks page keeps one section per machine kind (mimarble/bench/page.py)."""

import copy
import json
from pathlib import Path

import pytest

from mimarble.bench import page as bench_page

ROOT = Path(__file__).resolve().parent.parent
XEON = json.loads((ROOT / "docs" / "bench" / "bench.json").read_text())
ZEN4 = {"processor": "AMD EPYC", "cores": 2, "variant": "llvm_ad_rgb",
        "llvm_target": {"cpu": "znver4", "vector_width": 16, "how": "x",
                        "features": ["+avx2", "+avx512f", "+fma", "+fast-gather"]}}
ZEN3 = {"processor": "AMD EPYC", "cores": 2, "variant": "llvm_ad_rgb",
        "llvm_target": {"cpu": "znver3", "vector_width": 8, "how": "x",
                        "features": ["+avx2", "+fma", "-avx512f"]}}


def on(machine, render_ms=1.0):
    results = copy.deepcopy(XEON)
    results["machine"] = machine
    for run in results["runs"]:
        run["run_ms"] = render_ms
    return results


def test_labels_name_the_amd_generation_and_vector_width():
    assert bench_page.machine_label(ZEN4) == "AMD EPYC (Zen 4, AVX-512, LLVM target znver4), 2 cores"
    assert bench_page.machine_label(ZEN3) == "AMD EPYC (Zen 3, AVX2, LLVM target znver3), 2 cores"
    assert bench_page.machine_label(XEON["machine"]) == "Intel Xeon, 2 cores"
    assert len({bench_page.machine_slug(m) for m in (ZEN4, ZEN3, XEON["machine"])}) == 3


def test_a_machine_section_replaces_its_own_and_keeps_the_others(tmp_path):
    page = tmp_path / "benchmarks.md"
    page.write_text("# Benchmarks\n\nintro\n\n" + bench_page.SECTIONS_START + "\n"
                    + bench_page.SECTIONS_END + "\n\n## Other measurements\n\nkept text\n")
    bench_page.write_section(page, on(XEON["machine"], 7.0))
    bench_page.write_section(page, on(ZEN4, 3.0))
    bench_page.write_section(page, on(ZEN4, 5.0))     # a rerun on the same machine kind
    text = page.read_text()
    assert text.count("## Intel Xeon, 2 cores") == 1 and text.count("(Zen 4, AVX-512") == 1
    assert "| plain | 1 | 7.0 ms |" in text and "| plain | 1 | 5.0 ms |" in text
    assert "| plain | 1 | 3.0 ms |" not in text
    assert text.index("Intel Xeon") < text.index("Zen 4") < text.index("kept text")
    assert text.startswith("# Benchmarks\n\nintro\n")


def test_a_page_without_sections_gets_them_at_its_end(tmp_path):
    page = tmp_path / "b.md"
    page.write_text("# Mine\n\nhand-written\n")
    slug = bench_page.write_section(page, on(ZEN3))
    text = page.read_text()
    assert slug == "amd-epyc-znver3"
    assert text.startswith("# Mine\n\nhand-written\n")
    assert text.index(bench_page.SECTIONS_START) < text.index("Zen 3") \
        < text.index(bench_page.SECTIONS_END)


def test_the_section_names_its_command_date_and_plot(tmp_path):
    results = on(ZEN4)
    results["date"], results["command"] = "2026-12-01", "mimarble bench --page x.md"
    text = bench_page.section(results, plot="bench/plot.png")
    assert "Measured 2026-12-01 by `mimarble bench --page x.md`" in text
    assert "(bench/plot.png)" in text
    assert bench_page.plot_relative_to(tmp_path / "docs" / "b.md",
                                       tmp_path / "docs" / "bench" / "p.png") == "bench/p.png"


def test_bench_refuses_a_page_that_is_not_markdown(tmp_path, capsys):
    from mimarble.cli.main import main
    assert main(["bench", "--page", str(tmp_path / "page.txt")]) == 2
    assert "page" in capsys.readouterr().err


def test_text_between_the_sections_is_kept(tmp_path):
    page = tmp_path / "b.md"
    bench_page.write_section(page, on(ZEN3))
    page.write_text(page.read_text().replace(bench_page.SECTIONS_END,
                                             "a note of hand\n\n" + bench_page.SECTIONS_END))
    bench_page.write_section(page, on(ZEN3, 2.0))
    bench_page.write_section(page, on(ZEN4))
    text = page.read_text()
    assert "a note of hand" in text and text.count("(Zen 3,") == 1
    assert text.index("Zen 3") < text.index("a note of hand") < text.index("Zen 4")
