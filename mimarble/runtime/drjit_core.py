"""drjit-core's shared library through ctypes, for the calls Dr.Jit's Python API lacks.

``libdrjit-core.so`` lies beside Dr.Jit's Python package and exports a few C++
functions that Python cannot reach: the LLVM target (mimarble/runtime/llvm_target.py)
and the kernel cache's folder (mimarble/runtime/kernel_cache.py). This module only
opens that library, for the Dr.Jit this process has already imported.

It imports no other module of mimarble and never imports Dr.Jit itself: Dr.Jit
must be imported the safe way, through
``mimarble.runtime.environment.import_drjit_and_mitsuba`` (which chooses the libLLVM
before Dr.Jit loads one, then sets the LLVM target through this library), so
data flows one way: environment → llvm_target → drjit_core.
"""

from __future__ import annotations

import ctypes
import os
import sys


def library() -> ctypes.CDLL:
    """The ``libdrjit-core.so`` of the imported Dr.Jit.

    Raises OSError when Dr.Jit is not imported yet, or the library cannot be
    loaded (another Dr.Jit's layout).
    """
    dr = sys.modules.get("drjit")
    if dr is None:
        raise OSError("Dr.Jit is not imported yet "
                      "(mimarble.runtime.environment.import_drjit_and_mitsuba imports it)")
    return ctypes.CDLL(os.path.join(os.path.dirname(dr.__file__), "libdrjit-core.so"))
