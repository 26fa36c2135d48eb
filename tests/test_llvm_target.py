"""The LLVM target (mimarble/runtime/llvm_target.py): parsed, applied, shown — and images unchanged."""

import os
import subprocess
import sys

import numpy as np
import pytest

import mimarble
from mimarble.runtime import environment, llvm_target
from mimarble.runtime.llvm_target import Target, automatic, parse

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ZEN = Target("znver3", "+avx,+avx2,-avx512f", 8)


def test_parse_keeps_what_is_left_empty_and_appends_features():
    assert parse("default", ZEN) is None
    assert parse("", ZEN) == ZEN
    assert parse("|+fast-gather", ZEN) == Target("znver3", "+avx,+avx2,-avx512f,+fast-gather", 8)
    assert parse("skylake||4", ZEN) == Target("skylake", ZEN.features, 4)


@pytest.mark.parametrize("bad", ["a|b|c|d", "|fast-gather", "||3", "||x"])
def test_parse_refuses_what_it_cannot_mean(bad):
    with pytest.raises(ValueError, match="MIMARBLE_LLVM_TARGET"):
        parse(bad, ZEN)


def test_automatic_adds_fast_gather_only_where_avx2_lacks_it(monkeypatch):
    monkeypatch.setattr(llvm_target.platform, "machine", lambda: "x86_64")
    assert automatic(ZEN).has("+fast-gather")
    assert automatic(Target("skylake-avx512", "+avx2,+fast-gather", 16)) is None
    assert automatic(Target("x86-64", "+sse2,-avx2", 4)) is None
    monkeypatch.setattr(llvm_target.platform, "machine", lambda: "aarch64")
    assert automatic(ZEN) is None


def test_configure_decides_nothing_before_drjit_is_imported(monkeypatch):
    """Without Dr.Jit there is no target to read: the outcome says so and is not kept, so
    the call that environment.import_drjit_and_mitsuba makes after the import decides."""
    monkeypatch.setattr(llvm_target, "_outcome", None)
    monkeypatch.delitem(sys.modules, "drjit")
    outcome = llvm_target.configure()
    assert outcome.target is None and "not imported" in outcome.how
    assert llvm_target._outcome is None


def test_doctor_names_the_target():
    if not environment.llvm_backend_up():
        pytest.skip("no LLVM backend here")
    rows = dict(environment.doctor()[0])
    outcome = llvm_target.configure()
    assert outcome.target is not None
    assert rows["llvm target"].startswith(outcome.target.cpu)
    assert f"vector width {outcome.target.vector_width}" in rows["llvm target"]


_RENDER = """
import sys, numpy as np, mimarble
from mimarble.runtime import llvm_target
from mimarble.scene.edits import resized
scene = resized(mimarble.scene.load(sys.argv[2]), 48)
points = np.random.default_rng(5).uniform(-300, 300, (4096, 3))
np.savez(sys.argv[1], image=mimarble.render(scene, spp=4),
         noise=mimarble.texture.noise.fractal(points, 12), target=llvm_target.configure().target.summary())
"""


def test_images_are_bit_identical_whatever_the_target(tmp_path):
    if not environment.llvm_backend_up():
        pytest.skip("no LLVM backend here")
    results = {}
    for setting in ("default", "|+fast-gather", "|-fast-gather|4"):
        out = tmp_path / f"{len(results)}.npz"
        env = dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb", MIMARBLE_LLVM_TARGET=setting)
        run = subprocess.run([sys.executable, "-c", _RENDER, str(out),
                              os.path.join(ROOT, "scenes", "fig11a.scene")],
                             env=env, capture_output=True, text=True, timeout=300)
        sys.stderr.write(run.stderr)
        assert run.returncode == 0, run.stderr
        results[setting] = np.load(out)
    first, fast, narrow = (results[k] for k in ("default", "|+fast-gather", "|-fast-gather|4"))
    # The choice mimarble makes changes nothing but speed: bit for bit.
    assert np.array_equal(fast["image"], first["image"])
    assert np.array_equal(fast["noise"], first["noise"])
    # Another vector width (a user's override) keeps the noise exact; the shading's
    # float32 rounding may differ (measured: ≤ 1.1e-5).
    assert "vector width 4" in str(narrow["target"])
    assert np.array_equal(narrow["noise"], first["noise"])
    assert np.abs(narrow["image"] - first["image"]).max() <= 1e-4


def test_benchmark_figures_name_the_machine_and_target(llvm):
    from mimarble.runtime.machine import machine_facts, machine_line
    facts = machine_facts()
    line = machine_line(facts)
    assert facts["processor"] in line and f"{facts['cores']} cores" in line
    outcome = llvm_target.configure()
    if outcome.target is not None:
        assert facts["llvm_target"]["cpu"] == outcome.target.cpu
        assert f"LLVM target {outcome.target.cpu}, vector width {outcome.target.vector_width}" in line
