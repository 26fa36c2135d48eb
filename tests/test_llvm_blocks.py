"""Dr.Jit's LLVM blocks (mimarble/runtime/llvm_blocks.py): parsed, applied, shown — and
images unchanged by how a kernel's lanes are cut across the threads."""

import os
import subprocess
import sys

import numpy as np
import pytest

from mimarble.runtime import environment, llvm_blocks
from mimarble.runtime.llvm_blocks import BLOCK_SIZE_ENV, parse

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_parse_takes_powers_of_two_from_the_vector_width():
    assert parse("default", 16) is None
    assert parse(" 4096 ", 16) == 4096
    assert parse("16", 16) == 16 and parse("8", 8) == 8


@pytest.mark.parametrize("bad", ["", "x", "-4096", "3000", "8", "0", str(1 << 31), "4096.0"])
def test_parse_refuses_what_drjit_core_would_raise_on(bad):
    """drjit-core raises a C++ exception for these, which through ctypes ends the process."""
    with pytest.raises(ValueError, match=BLOCK_SIZE_ENV):
        parse(bad, 16)


def test_configure_decides_nothing_before_drjit_is_imported(monkeypatch):
    monkeypatch.setattr(llvm_blocks, "_outcome", None)
    monkeypatch.delitem(sys.modules, "drjit")
    outcome = llvm_blocks.configure()
    assert outcome.block_size is None and "not imported" in outcome.how
    assert llvm_blocks._outcome is None


def test_doctor_names_the_block_size():
    if not environment.llvm_backend_up():
        pytest.skip("no LLVM backend here")
    rows = dict(environment.doctor()[0])
    outcome = llvm_blocks.configure()
    assert rows["llvm blocks"].startswith(f"{outcome.block_size} lanes")


_RENDER = """
import sys, numpy as np, mimarble
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering.adaptive import render_adaptive
from mimarble.runtime import llvm_blocks
from mimarble.scene.edits import resized
scene = resized(mimarble.scene.load(sys.argv[2]), 128)
loaded = mimarble.mi.load_dict(to_mitsuba(scene, spp=1))
adaptive = render_adaptive(loaded, 1, 2e-3, 81)
np.savez(sys.argv[1], plain=mimarble.render(scene, spp=4), adaptive=adaptive.image,
         samples=adaptive.samples, size=llvm_blocks.configure().block_size)
"""


def _render(tmp_path, setting):
    out = tmp_path / f"{setting}.npz"
    env = dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb", **{BLOCK_SIZE_ENV: setting})
    run = subprocess.run([sys.executable, "-c", _RENDER, str(out),
                          os.path.join(ROOT, "scenes", "fig11a.scene")],
                         env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    return np.load(out), run.stderr


def test_images_are_bit_identical_whatever_the_block_size(tmp_path):
    """128² at 4 spp (65 536 lanes: Dr.Jit's own cuts it in four blocks, 4096 in sixteen,
    16 in 4096) and an adaptive render (its first pass and rounds): the same bits."""
    if not environment.llvm_backend_up():
        pytest.skip("no LLVM backend here")
    results = {s: _render(tmp_path, s)[0] for s in ("default", "4096", "16")}
    assert int(results["default"]["size"]) == 16384      # drjit-core 1.5's own
    assert int(results["4096"]["size"]) == 4096 and int(results["16"]["size"]) == 16
    for setting in ("4096", "16"):
        for name in ("plain", "adaptive", "samples"):
            assert np.array_equal(results[setting][name], results["default"][name]), (setting, name)


def test_a_block_size_drjit_core_would_refuse_is_warned_of_not_fatal(tmp_path):
    if not environment.llvm_backend_up():
        pytest.skip("no LLVM backend here")
    result, stderr = _render(tmp_path, "3000")
    assert int(result["size"]) == 16384
    assert f"{BLOCK_SIZE_ENV}='3000'" in stderr and "power of two" in stderr
