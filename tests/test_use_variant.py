"""``mimarble.use_variant``: the variant chosen or checked in one sentence, the command
line's ``--variant`` through the same code (mimarble/runtime/environment.py)."""

import os
import subprocess
import sys

import pytest

import mimarble
from mimarble.runtime import environment

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
mi = mimarble.mi


def test_without_a_gpu_cuda_is_one_sentence_naming_what_can_render():
    if environment.variant_problem("cuda_ad_rgb") is None:
        pytest.skip("a CUDA GPU is usable here")
    previous = mi.variant()
    with pytest.raises(mimarble.EnvironmentProblem) as info:
        mimarble.use_variant("cuda_ad_rgb")
    message = str(info.value)
    assert message.startswith("Variant cuda_ad_rgb needs a usable CUDA GPU and driver")
    assert message.endswith(" can render here.") and message.count(".") == 1   # one sentence
    assert all(v in message for v in environment.usable_variants())
    assert "CUDA backend hasn't been initialized" not in message
    assert mi.variant() == previous                       # nothing switched


def test_usable_variants_are_rgb_and_each_passes_its_own_check():
    usable = environment.usable_variants()
    assert "scalar_rgb" in usable
    assert all(v.endswith("_rgb") and environment.variant_problem(v) is None for v in usable)


def test_a_named_usable_variant_is_set_and_returned():
    previous = mi.variant()
    try:
        assert mimarble.use_variant("scalar_rgb") == "scalar_rgb" == mi.variant()
    finally:
        mi.set_variant(previous)


def test_the_command_line_says_the_sentence_python_raises(tmp_path):
    try:
        mimarble.use_variant("nonsense_rgb")
    except mimarble.EnvironmentProblem as e:
        sentence = str(e)
    env = {k: v for k, v in os.environ.items() if k != environment.VARIANT_ENV}
    result = subprocess.run([sys.executable, "-m", "mimarble", "--variant", "nonsense_rgb",
                             "render", "scenes/fig10a.scene", "-o", str(tmp_path / "x.png")],
                            cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 2
    assert result.stderr.strip() == f"mimarble: {sentence}"
    assert "can render here" in sentence
    assert list(tmp_path.iterdir()) == []
