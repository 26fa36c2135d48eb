import os
import sys

import pytest

import mimarble
from mimarble import environment

sys.path.insert(0, os.path.dirname(__file__))   # perlin64, the tests' own reference

mi = mimarble.mi
VARIANTS = ("scalar_rgb", "llvm_ad_rgb", "cuda_ad_rgb")
JIT_VARIANTS = ("llvm_ad_rgb", "cuda_ad_rgb")


def _use(variant):
    problem = environment.variant_problem(variant)
    if problem:
        pytest.skip(problem)
    previous = mi.variant()
    mi.set_variant(variant)
    return previous


@pytest.fixture(params=VARIANTS)
def variant(request):
    """Each RGB variant usable here (CUDA skipped cleanly without a GPU)."""
    previous = _use(request.param)
    yield request.param
    mi.set_variant(previous)


@pytest.fixture(params=JIT_VARIANTS)
def jit_variant(request):
    previous = _use(request.param)
    yield request.param
    mi.set_variant(previous)


@pytest.fixture
def llvm():
    previous = _use("llvm_ad_rgb")
    yield "llvm_ad_rgb"
    mi.set_variant(previous)
