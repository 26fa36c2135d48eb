"""The benchmark's adaptive modes and each mode's time to plain 16 and 64 spp's RMSE
(mimarble/bench/run.py, reported by bench_report.py and bench_page.py, drawn by bench_plot.py).
No timing is asserted: machines are shared."""

import math

import pytest

from mimarble.bench import (run as bench, page as bench_page, plot as bench_plot,
    report as bench_report)
from mimarble.bench.curves import (adaptive_columns, speedups_at_equal_error, time_to_rmse,
                                   times_to_plain_rmse)
from mimarble.bench import modes as bench_modes

MACHINE = {"processor": "AMD EPYC", "cores": 2, "variant": "llvm_ad_rgb"}


# ---------------------------------------------------------------------------
# time_to_rmse: a curve of (run_ms, rmse) points, interpolated in log-log

def test_the_crossing_is_interpolated_in_log_time_against_log_rmse():
    curve = [(1.0, 0.1), (100.0, 0.001)]
    assert time_to_rmse(curve, 0.01) == pytest.approx(10.0)          # halfway in log-log
    assert time_to_rmse(curve, 0.1 * 10 ** -0.5) == pytest.approx(10 ** 0.5)
    assert time_to_rmse(curve, 0.001) == pytest.approx(100.0)         # the last point itself


def test_the_bracketing_neighbours_are_taken_in_the_curves_own_order():
    # the target 0.004 lies between the 4 and 16 ms points, in log-log halfway
    curve = [(1.0, 0.016), (4.0, 0.008), (16.0, 0.002), (64.0, 0.001)]
    expected = math.exp(math.log(4) + 0.5 * (math.log(16) - math.log(4)))
    assert time_to_rmse(curve, 0.004) == pytest.approx(expected)
    # a noisy time does not reorder the settings: the crossing is still between the
    # second and third settings, whose times are 30 and 16 ms
    noisy = [(1.0, 0.016), (30.0, 0.008), (16.0, 0.002), (64.0, 0.001)]
    assert time_to_rmse(noisy, 0.004) == pytest.approx(math.sqrt(30 * 16))


def test_a_curve_that_never_reaches_the_target_has_no_time():
    assert time_to_rmse([(1.0, 0.1), (4.0, 0.05), (16.0, 0.02)], 0.01) is None
    assert time_to_rmse([], 0.01) is None


def test_a_curve_whose_cheapest_point_reaches_it_takes_that_time():
    assert time_to_rmse([(3.0, 0.005), (9.0, 0.001)], 0.01) == 3.0


def test_a_curve_that_goes_back_up_is_crossed_the_first_time():
    curve = [(1.0, 0.1), (2.0, 0.01), (4.0, 0.05), (8.0, 0.001)]
    assert time_to_rmse(curve, 0.01) == pytest.approx(2.0)


# ---------------------------------------------------------------------------
# times_to_plain_rmse, the report, the page and the plot on synthetic runs

def _run(scene, mode, run_ms, rmse, spp=1, threshold=None, mean_spp=None):
    run = {"scene": scene, "mode": mode, "spp": spp, "edge_spp": None, "run_ms": run_ms,
           "compile_ms": 1.0, "kernels_compiled": 0, "rmse": rmse, "psnr": -20 * math.log10(rmse),
           "interior_rmse": rmse / 2, "mean_spp": float(spp if mean_spp is None else mean_spp)}
    if threshold is not None:
        run.update(threshold=threshold, max_spp=64)
    return run


def synthetic_runs():
    """Plain: time ∝ spp, RMSE ∝ 1/√spp. Adaptive: RMSE halves per threshold at 1.5× the
    time; on the fine-vein scene it stops short of plain 64 spp's RMSE."""
    runs = []
    for scene, floor in (("fig01a", None), ("fig11a", None), ("veins-p4-d4-s2", 0.003)):
        for spp in (1, 4, 16, 64):
            runs.append(_run(scene, "plain", 2.0 * spp, 0.016 / math.sqrt(spp), spp=spp))
        for i, threshold in enumerate((0.01, 0.005, 0.0025, 0.00125)):
            rmse = max(0.016 / 2 ** (i + 1), floor or 0)
            runs.append(_run(scene, "adaptive", 3.0 * 1.5 ** i, rmse, threshold=threshold,
                             mean_spp=1.2 * 2 ** i))
    return runs


def synthetic_results():
    runs = synthetic_runs()
    return {"machine": MACHINE, "date": "2026-12-02", "size": 32, "converged_spp": 256,
            "repeats": 1, "tolerance": None, "runs": runs, "paper": [], "targets": {},
            "modes": [{"name": "plain"}, {"name": "adaptive", "adaptive": True}],
            "adaptive": {"thresholds": [0.01, 0.005, 0.0025, 0.00125], "first_spp": 1,
                         "max_spp": 64},
            "speedup_at_plain16_rmse": speedups_at_equal_error(runs),
            "time_to_rmse": times_to_plain_rmse(runs)}


def test_time_to_plain_rmse_per_scene_with_means_and_missed_scenes():
    ttr = times_to_plain_rmse(synthetic_runs())
    assert ttr["targets"] == [16, 64]
    fig = ttr["by_scene"]["fig01a"]
    # plain reaches its own RMSE at its own time
    assert fig["16"]["by_mode"]["plain"]["speedup"] == pytest.approx(1.0)
    assert fig["64"]["by_mode"]["plain"]["ms"] == pytest.approx(128.0)
    # plain 16 spp: RMSE 0.004, adaptive's second point (0.004 at 4.5 ms, 2.4 spp) exactly
    assert fig["16"]["rmse"] == pytest.approx(0.004)
    assert fig["16"]["by_mode"]["adaptive"]["ms"] == pytest.approx(4.5)
    assert fig["16"]["by_mode"]["adaptive"]["speedup"] == pytest.approx(32 / 4.5)
    assert fig["16"]["by_mode"]["adaptive"]["mean_spp"] == pytest.approx(2.4)
    # plain 64: 0.002, adaptive's third point (6.75 ms)
    assert fig["64"]["by_mode"]["adaptive"]["ms"] == pytest.approx(6.75)
    # between two points: plain 16 spp's RMSE sits halfway (log-log) from 1 to 4 spp's
    # adaptive points of a curve made for it
    half = [_run("fig01a", "plain", 32.0, 0.004, spp=16),
            _run("fig01a", "adaptive", 2.0, 0.008, threshold=0.01, mean_spp=1.0),
            _run("fig01a", "adaptive", 8.0, 0.002, threshold=0.001, mean_spp=4.0)]
    crossing = times_to_plain_rmse(half)["by_scene"]["fig01a"]["16"]["by_mode"]["adaptive"]
    assert crossing["ms"] == pytest.approx(4.0) and crossing["mean_spp"] == pytest.approx(2.0)
    assert crossing["speedup"] == pytest.approx(8.0)
    veins = ttr["by_scene"]["veins-p4-d4-s2"]
    assert veins["64"]["by_mode"]["adaptive"] is None              # stops at 0.003
    paper = ttr["groups"]["paper"]
    assert paper["scenes"] == ["fig01a", "fig11a"]
    assert paper["16"]["adaptive"]["mean_speedup"] == pytest.approx(32 / 4.5)
    assert paper["16"]["adaptive"]["reached"] == 2 and paper["16"]["adaptive"]["missed"] == []
    alone = ttr["groups"]["veins-p4-d4-s2"]
    assert alone["scenes"] == ["veins-p4-d4-s2"]
    assert alone["64"]["adaptive"] == {"reached": 0, "of": 1, "missed": ["veins-p4-d4-s2"],
                                       "mean_speedup": None, "worst_speedup": None,
                                       "mean_ms": None, "mean_spp": None}


def test_the_adaptive_columns_per_traced_sample_oracle_and_soonest_mode():
    """Issue 43's columns, by hand: fig01a's plain 16 spp takes 32 ms for 16 · 32² samples
    (1953 ns each); adaptive crosses it at 4.5 ms and 2.4 spp (1831 ns: 0.94×)."""
    results = synthetic_results()
    results["oracle"] = {"fig01a": {"adaptive": {"16": 1.5, "64": 3.0}}}
    columns = adaptive_columns(results)
    fig = columns["fig01a"]
    plain_ns = 1e6 * 32.0 / (16 * 32 ** 2)
    assert fig["plain_ns"] == pytest.approx(plain_ns)
    adaptive = fig["modes"]["adaptive"]
    assert adaptive["ns"] == pytest.approx(1e6 * 4.5 / (2.4 * 32 ** 2))
    assert adaptive["ratio"] == pytest.approx(adaptive["ns"] / plain_ns)
    assert adaptive["spp"]["16"] == pytest.approx(2.4)
    assert adaptive["oracle_spp"] == {"16": 1.5, "64": 3.0}
    assert fig["best"] == {"16": "adaptive", "64": "adaptive"}
    lines = "\n".join(bench_report.adaptive_column_lines(columns))
    assert "fig01a" in lines and "1.5" in lines


def test_the_oracle_refines_the_pixels_whose_error_it_knows():
    """Four pixels, one wrong by 0.3 in each colour at the first level (cost 1), all right
    at the second (cost 3): RMSE √(0.27 / 12) = 0.15 for 1 sample a pixel; the oracle
    reaches RMSE 0 by refining only the wrong pixel, (1 + 1 + 1 + 3) / 4 = 1.5 samples."""
    import numpy as np
    from mimarble.bench.oracle import oracle_curve, oracle_samples
    truth = np.zeros((1, 4, 3))
    first = truth.copy()
    first[0, 3] = 0.3
    curve = oracle_curve([first, truth], truth, [1, 3])
    assert curve[0] == {"mean_spp": 1.0, "rmse": pytest.approx(0.15)}
    assert curve[-1] == {"mean_spp": 1.5, "rmse": 0.0}
    assert oracle_samples([first, truth], truth, [1, 3], 0.1) == pytest.approx(1.5)
    assert oracle_samples([first, first], truth, [1, 3], 0.1) is None     # never reached


def test_the_oracle_choice_at_an_rmse_refines_the_worst_pixels_first():
    """Three pixels wrong at the first level (cost 1) by squared errors 0.03, 0.12, 0.27
    (summed over the colours), right at the second (cost 3). Refining the worst leaves
    RMSE √(0.15 / 9) ≈ 0.129, the worst two √(0.03 / 9) ≈ 0.0577, all three 0: at a
    target of 0.1 the oracle refines the pixels of 0.27 and 0.12 and keeps 0.03. And
    the price bisection finds where a rule's RMSE (here the price itself) crosses a
    target."""
    import numpy as np
    from mimarble.bench.oracle import oracle_choice, price_for
    errors = np.array([[0.03, 0.12, 0.27], [0.0, 0.0, 0.0]])
    assert oracle_choice(errors, [1, 3], 0.1).tolist() == [0, 1, 1]
    assert oracle_choice(errors, [1, 3], 0.13).tolist() == [0, 0, 1]
    assert oracle_choice(errors, [1, 3], 0.0).tolist() == [1, 1, 1]
    assert price_for(lambda price: price, 0.25) == pytest.approx(0.25)


def test_a_scene_without_plain_64_has_only_the_16_spp_target():
    runs = [r for r in synthetic_runs() if not (r["mode"] == "plain" and r["spp"] == 64)]
    ttr = times_to_plain_rmse(runs)
    assert set(ttr["by_scene"]["fig01a"]) == {"16"}
    assert "64" not in ttr["groups"]["paper"]


def test_the_report_prints_the_time_to_rmse_tables_and_adaptive_runs():
    text = bench_report.format_report(synthetic_results())
    assert "Time to plain 16 spp's RMSE" in text and "Time to plain 64 spp's RMSE" in text
    assert "paper scenes (mean of 2):" in text
    assert "7.11× (worst 7.11×), 4.5 ms, 2.4 spp   target ≥ 4×" in text
    assert "missed on all 1   target ≥ 6×" in text         # the fine veins at plain 64's
    assert "threshold" in text and "mean spp" in text
    row = next(line for line in text.splitlines()
               if line.startswith("veins-p4-d4-s2") and "adaptive" in line and "0.0025" in line)
    assert "4.80" in row                                    # its mean spp


def test_the_page_has_the_time_to_rmse_table_and_paper_means(tmp_path):
    text = bench_page.section(synthetic_results())
    assert "**Time to plain 16 and 64 spp's RMSE**" in text
    assert "| plain 16 spp | paper scenes (mean of 2) | 1.00× (worst 1.00×), 32.0 ms, 16.0 spp |" \
        in text
    assert "| plain 64 spp | veins-p4-d4-s2 | 1.00×, 128.0 ms, 64.0 spp | missed on all 1 |" in text
    assert "means over 2 scenes" in text and "**veins-p4-d4-s2** (32²)" in text
    assert "| adaptive | threshold 0.005 | 4.5 ms |" in text
    assert "| plain | 16 | 32.0 ms | 0.0040 |" in text


def test_the_plot_draws_adaptive_curves_and_plain_levels(tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "plot.png"
    bench_plot.plot_error_against_time(synthetic_results(), out)
    assert out.stat().st_size > 10_000


def test_the_default_modes_add_adaptive_sampling_of_plain_and_prefiltered_marble():
    names = [m.name for m in bench_modes.modes()]
    assert names == ["plain", "bandlimit", "prefilter", "prefilter+edges", "adaptive",
                     "adaptive+prefilter"]
    assert [m.name for m in bench_modes.modes(adaptive=False)] == names[:4]
    assert [(m.name, m.filter, m.adaptive) for m in bench_modes.modes("prefilter")] == [
        ("prefilter", "prefilter", False), ("adaptive+prefilter", "prefilter", True)]
    assert bench_modes.DEFAULT_SPPS[-1] == 64 < bench_modes.DEFAULT_CONVERGED_SPP


# ---------------------------------------------------------------------------
# One small benchmark, end to end

def test_a_small_bench_with_the_adaptive_mode(llvm, tmp_path):
    pytest.importorskip("mimarble.mitsuba.rendering.adaptive")
    modes = (bench_modes.Mode("plain"), bench_modes.Mode("adaptive", adaptive=True))
    results = bench.run_bench(["scenes/fine-veins/veins-p4-d4-s2.scene"], size=32,
                              spps=(1, 4, 16, 64), converged_spp=16, repeats=1, paper=False,
                              cache_dir=tmp_path, progress=False, modes=modes,
                              thresholds=(0.01, 0.001), max_spp=16)
    adaptive = [r for r in results["runs"] if r["mode"] == "adaptive"]
    assert [r["threshold"] for r in adaptive] == [0.01, 0.001]
    for r in adaptive:        # levels 1, 9 kept, then 16 replacing them: 9 + 16 at most
        assert 1 <= r["final_spp"] <= r["max_spp"] == 16
        assert r["final_spp"] <= r["mean_spp"] <= 9 + 16
        assert r["rmse"] >= 0 and r["rounds"] >= 0
    assert all(r["mean_spp"] == r["spp"] for r in results["runs"] if r["mode"] == "plain")
    assert results["adaptive"] == {"thresholds": [0.01, 0.001], "first_spp": 1, "max_spp": 16}
    ttr = results["time_to_rmse"]
    assert set(ttr["by_scene"]["veins-p4-d4-s2"]) == {"16", "64"}
    assert set(ttr["groups"]) == {"veins-p4-d4-s2"}
    assert "Time to plain 16 spp's RMSE" in bench_report.format_report(results)
    # The oracle beside the mode (its figures checked against the mode's runs in
    # test_the_oracle_needs_no_more_samples_than_adaptive_renders: here, with a converged
    # image of 16 spp, plain 16 spp's RMSE is ~0 and the mode reaches neither target).
    oracle = results["oracle"]["veins-p4-d4-s2"]["adaptive"]
    assert set(oracle) == {"16", "64"}
    assert results["adaptive_columns"]["veins-p4-d4-s2"]["modes"]["adaptive"]["oracle_spp"] \
        == oracle
    assert "soonest" in bench_report.format_report(results)


def test_the_oracle_needs_no_more_samples_than_adaptive_renders(llvm):
    """The oracle chooses among the same levels knowing each pixel's error (against the
    float64 reference), so at the RMSE an adaptive render reaches it needs at most that
    render's samples a pixel (5 % for the interpolation between its runs)."""
    import numpy as np
    import mimarble
    from mimarble import reference
    from mimarble.bench.oracle import level_images, oracle_samples
    from mimarble.mitsuba import to_mitsuba
    from mimarble.mitsuba.rendering.adaptive import render_adaptive
    from mimarble.scene.edits import resized
    scene = resized(mimarble.scene.load("scenes/fine-veins/veins-p4-d4-s2.scene"), 24)
    truth = reference.render(scene, spp=64)
    loaded = mimarble.mi.load_dict(to_mitsuba(scene, spp=1))
    images, costs = level_images(loaded, 1, 16)
    # Kept samples not traced again; 16 replaces (after 1: the first round's jump, or 9).
    assert costs == [1, 9, 1 + 16, 9 + 16]
    for threshold in (0.01, 0.001):
        run = render_adaptive(loaded, 1, threshold, 16)
        rmse = float(np.sqrt(np.mean(np.square(run.image.astype(np.float64) - truth))))
        ours = run.traced / (24 * 24)
        theirs = oracle_samples(images, truth, costs, rmse)
        assert theirs is not None and 1.0 <= theirs <= 1.05 * ours, (threshold, theirs, ours)


@pytest.mark.parametrize("args, message", [
    (["--max-spp", "8"], "--max-spp 8"),
    (["--adaptive", "0.01", "0"], "--adaptive 0.0"),
    (["--adaptive", "nan"], "finite number > 0"),
])
def test_bench_refuses_bad_adaptive_settings_before_measuring(args, message, capsys):
    from mimarble.cli.main import main
    assert main(["bench", *args]) == 2
    assert message in capsys.readouterr().err
