"""mimarble.bench.peers: the table, our row, and peers that are missing. No timing limits:
machines are noisy, so only the shape and the bookkeeping of the rows are checked."""

import sys

import numpy as np
import pytest

import mimarble
from mimarble.bench import peers as bench_peers

dr, mi = mimarble.dr, mimarble.mi

TINY = 4096


def test_peers_table_renders_one_row_per_input_row_and_marks_skipped_ones():
    rows = [
        {"name": "alpha", "m_octave_evals_per_s": 12.345, "points": 100, "threads": 1,
         "note": "first"},
        {"name": "beta", "m_octave_evals_per_s": None, "points": 50, "threads": 1,
         "note": bench_peers.NOT_INSTALLED},
        {"name": "gamma", "m_octave_evals_per_s": 0.5, "points": 7, "threads": 1,
         "note": "a | b"},
    ]
    table = bench_peers.peers_table(rows, machine="Test CPU, 2 cores")
    lines = table.splitlines()
    assert lines[0] == "Machine: Test CPU, 2 cores"
    body = [line for line in lines if line.startswith("|")][2:]   # past header and rule
    assert len(body) == len(rows)
    for line, row in zip(body, rows):
        cells = [c.strip() for c in line.strip("|").split(" | ")]
        assert cells[0] == row["name"] and cells[2] == str(row["points"]) and cells[3] == "1"
    assert body[0].split(" | ")[1] == "12.3"
    assert body[1].split(" | ")[1] == "skipped" and bench_peers.NOT_INSTALLED in body[1]
    assert "skipped" not in body[0] and "skipped" not in body[2]
    assert "a \\| b" in body[2]                      # a pipe in a note cannot split the row
    assert not bench_peers.peers_table(rows).startswith("Machine")


def test_sample_points_are_seeded_float32_in_the_cube():
    a, b = bench_peers.sample_points(1000, seed=3), bench_peers.sample_points(1000, seed=3)
    assert a.shape == (1000, 3) and a.dtype == np.float32
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, bench_peers.sample_points(1000, seed=4))
    assert np.all(np.abs(a) <= bench_peers.EXTENT)


def test_peer_rates_gives_our_row_on_one_thread_and_restores_the_thread_count(llvm):
    threads_before = dr.thread_count()
    rows = bench_peers.peer_rates(points=TINY, octaves=3, repeats=1, seed=1)
    assert dr.thread_count() == threads_before
    assert mi.variant() == llvm
    assert [r["name"] for r in rows] == [bench_peers.OURS, bench_peers.FASTNOISELITE,
                                         bench_peers.NOISE]
    ours = rows[0]
    assert ours["threads"] == 1 and ours["points"] == TINY
    assert isinstance(ours["m_octave_evals_per_s"], float) and ours["m_octave_evals_per_s"] > 0
    for row in rows:
        assert set(row) == {"name", "m_octave_evals_per_s", "points", "threads", "note"}
        assert row["threads"] == 1
        rate = row["m_octave_evals_per_s"]
        assert rate is None or rate > 0
    assert rows[2]["points"] == min(TINY, bench_peers.SCALAR_POINTS)


def test_our_noise_runs_with_one_thread_in_the_llvm_variant(llvm, monkeypatch):
    from mimarble.texture import noise
    seen = []
    real = noise.fractal3

    def recording(p, octaves, turbulence=False):
        seen.append((dr.thread_count(), mi.variant(), dr.width(p), octaves))
        return real(p, octaves, turbulence)

    monkeypatch.setattr(noise, "fractal3", recording)
    bench_peers.measure_ours(bench_peers.sample_points(300), octaves=4, repeats=3)
    assert seen == [(1, "llvm_ad_rgb", 300, 4)] * 4          # one warm-up, three timed


def test_peer_rates_restores_a_scalar_variant(llvm):
    mi.set_variant("scalar_rgb")
    try:
        rows = bench_peers.peer_rates(points=256, octaves=2, repeats=1)
        assert mi.variant() == "scalar_rgb"
        assert rows[0]["m_octave_evals_per_s"] > 0
    finally:
        mi.set_variant(llvm)


def test_missing_peers_are_reported_as_skipped(llvm, monkeypatch):
    # A None entry in sys.modules makes `import name` raise ImportError, as when absent.
    for module in ("noise", "pyfastnoiselite", "pyfastnoiselite.pyfastnoiselite"):
        monkeypatch.setitem(sys.modules, module, None)
    rows = bench_peers.peer_rates(points=TINY, octaves=2, repeats=1)
    ours, fastnoise, scalar = rows
    assert ours["m_octave_evals_per_s"] > 0
    for row in (fastnoise, scalar):
        assert row["m_octave_evals_per_s"] is None
        assert row["note"] == bench_peers.NOT_INSTALLED == "not installed (pip install mimarble[peers])"
    table = bench_peers.peers_table(rows).splitlines()
    assert sum("skipped" in line for line in table) == 2


@pytest.mark.parametrize("module, measure", [
    ("pyfastnoiselite", bench_peers.measure_fastnoiselite),
    ("noise", bench_peers.measure_noise),
])
def test_installed_peers_are_measured(module, measure):
    pytest.importorskip(module)
    row = measure(bench_peers.sample_points(512), octaves=8, repeats=1)
    assert row["m_octave_evals_per_s"] > 0 and row["threads"] == 1 and row["points"] == 512


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError):
        bench_peers.peer_rates(points=0)
    with pytest.raises(ValueError):
        bench_peers.peer_rates(points=16, octaves=0)
