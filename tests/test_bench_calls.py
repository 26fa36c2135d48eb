"""The benchmark's whole-call rows measure what they say (no timing is asserted: machines
are shared; the figures belong in docs/benchmarks.md)."""

import mimarble
from mimarble import scene as scene_language

mi, dr = mimarble.mi, mimarble.dr

from mimarble.bench import adam as bench_adam, calls as bench_calls  # noqa: E402
from mimarble.bench.report import calls_lines  # noqa: E402
from mimarble.scene.edits import resized  # noqa: E402

SCENE = "scenes/fig11a.scene"


def test_a_call_is_timed_with_the_kernels_it_launches(llvm):
    small = resized(scene_language.load(SCENE), 16)

    def render():
        return mimarble.render(small, spp=1)

    once = bench_calls.time_call(render, repeats=2)
    assert once["whole_ms"] > 0 and once["kernels_ms"] > 0 and once["launches"] >= 1
    twice = bench_calls.time_call(lambda: (render(), render()), repeats=2)
    # Every launch of the call is counted: the second render's too (it may launch fewer
    # than the first, whose results a render kept can share: under --jit-debug it does).
    assert once["launches"] < twice["launches"] <= 2 * once["launches"]
    idle = bench_calls.time_call(lambda: None, repeats=2)     # no kernel: no ratio to give
    assert idle["launches"] == 0 and idle["kernels_ms"] == 0 and idle["ratio"] is None


def test_replay_is_switched_for_the_block_only(llvm, monkeypatch):
    monkeypatch.setenv("MIMARBLE_FREEZE", "1")
    with bench_calls.replay(False):
        assert not mimarble.mitsuba.rendering.replay.enabled()
    assert mimarble.mitsuba.rendering.replay.enabled()


def test_the_sweep_row_counts_every_frames_kernels(llvm):
    row = bench_calls.sweep_row(SCENE, frames=2, size=16, spp=1)
    assert row["frames"] == 2 and row["kernels_s"] > 0 and row["whole_s"] > row["kernels_s"]


def test_the_adam_step_is_the_same_frozen_and_traced_on_one_thread(llvm):
    threads = dr.thread_count()
    dr.set_thread_count(1)
    try:
        rows = bench_adam.step_rows(steps=bench_adam.WARM + 2)
    finally:
        dr.set_thread_count(threads)
    assert rows["loss_difference"] == 0 and rows["parameter_difference"] == 0
    assert rows["frozen"]["kernels_ms"] > 0 and rows["traced"]["launches"] >= 1


def test_the_report_prints_every_row():
    render = {"call": "mimarble.render: x", "replay": True, "whole_ms": 2.0, "kernels_ms": 1.0,
              "ratio": 2.0, "launches": 3}
    step = {"whole_ms": 4.0, "kernels_ms": 2.0, "launches": 5}
    calls = {"renders": [render, {**render, "replay": False}],
             "sweep": {"call": "sweep: 2 frames", "whole_s": 1.0, "kernels_s": 0.5,
                       "compile_s": 0.1, "ratio": 1.67},
             "adam_step": {"traced": step, "frozen": {**step, "whole_ms": 2.0},
                           "loss_difference": 0.0, "parameter_difference": 0.0},
             "povray": {"version": "POV-Ray 3.7", "trace_s": 0.08, "ours_ms": 8.0,
                        "trace_over_ours": 10.0},
             "peers": [{"name": "ours", "m_octave_evals_per_s": 100.0, "points": 8,
                        "note": "n"}, {"name": "absent", "m_octave_evals_per_s": None,
                                       "points": 8, "note": "not installed"}]}
    text = "\n".join(calls_lines(calls))
    for shown in ("| mimarble.render: x | on | 2.00 ms | 1.00 ms | 2.00× | 3 |",
                  "| mimarble.render: x | off |", "sweep: 2 frames", "frozen against traced: 2.00×",
                  "POV-Ray / ours 10.0×", "ours: 100.0", "absent: —"):
        assert shown in text, shown
