"""mimarble — the marble solid texture of Park & Park (2004) for Mitsuba 3.

Importing the package chooses a libLLVM that cannot abort the process (before
Dr.Jit loads one), sets a Mitsuba variant if none is set yet (``cuda_ad_rgb``
with a usable GPU, else ``llvm_ad_rgb``, else ``scalar_rgb``; ``$MIMARBLE_VARIANT``
overrides), and registers the ``marble`` texture for every variant.
"""

import os

from . import environment, llvm_target
from .environment import EnvironmentProblem, use_variant

environment.prepare_llvm()
dr, mi = environment.import_drjit_and_mitsuba()

# The CPU kernels' LLVM target, before any kernel is compiled (mimarble/llvm_target.py).
if environment.llvm_backend_up():
    llvm_target.configure()

# MIMARBLE_JIT_DEBUG=1: Dr.Jit bounds-checks every gather, scatter and symbolic call,
# masks the bad lanes and reports them on stderr (slower; `./go test --jit-debug`).
if os.environ.get(environment.JIT_DEBUG_ENV) == "1":
    environment.enable_bounds_checks()

# A variant problem at import (a bad $MIMARBLE_VARIANT) must not break the
# import: it is kept here, and raised again by whatever needs the variant.
startup_problem = None
if mi.variant() is None:
    try:
        use_variant()
    except EnvironmentProblem as e:
        startup_problem = e

from . import noise  # noqa: E402
from . import marble  # noqa: E402
from . import plugins  # noqa: E402
from . import mitsuba as _mitsuba  # noqa: E402  (declares the material and integrator)
from . import scene  # noqa: E402
from .mitsuba import render, to_mitsuba, write_image  # noqa: E402

plugins.install()

__all__ = ["EnvironmentProblem", "marble", "noise", "render", "scene", "to_mitsuba",
           "use_variant", "write_image"]
__version__ = "0.1.0"
