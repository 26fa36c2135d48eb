import os
import sys

import pytest

import mimarble
from mimarble.runtime import environment

sys.path.insert(0, os.path.dirname(__file__))   # perlin64, the tests' own reference

from jit_reports import stderr_reports  # noqa: E402

dr, mi = mimarble.dr, mimarble.mi
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


# ---------------------------------------------------------------------------
# Dr.Jit's bounds checks (tests/jit_reports.py)

def pytest_addoption(parser):
    parser.addoption("--jit-debug", action="store_true",
                     help="run with Dr.Jit's JitFlag.Debug: every gather, scatter and symbolic "
                          "call is bounds-checked, and a test during which Dr.Jit reports an "
                          "out-of-bounds access fails (also: MIMARBLE_JIT_DEBUG=1)")


def pytest_configure(config):
    if config.getoption("--jit-debug"):
        os.environ[environment.JIT_DEBUG_ENV] = "1"   # child processes (CLI tests) check too
        environment.enable_bounds_checks()


def pytest_report_header(config):
    return f"Dr.Jit bounds checks (JitFlag.Debug): {'on' if dr.flag(dr.JitFlag.Debug) else 'off'}"


@pytest.hookimpl(wrapper=True, trylast=True)   # inside pytest's own capture
def pytest_runtest_call(item):
    """Fail the test if Dr.Jit reported an invalid access while it ran."""
    with stderr_reports(dr) as captured:
        result = yield
    reports = captured.reports()
    if reports:
        pytest.fail("Dr.Jit reported invalid memory accesses during this test:\n  "
                    + "\n  ".join(reports), pytrace=False)
    return result
