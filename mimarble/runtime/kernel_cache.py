"""Dr.Jit's kernel cache: where it is, how big, and filling it before a first render.

Dr.Jit compiles each distinct kernel with LLVM (CPU) or the CUDA driver and keeps
the machine code on disk, keyed by the kernel's code and the LLVM target: in
``$DRJIT_CACHE_DIR``, else ``~/.drjit`` (drjit-core's ``jitc_cache_init``). It
prunes the folder to ``$DRJIT_CACHE_MAXSIZE`` bytes (suffixes k, M, G; default
1 GiB) at most once an hour; deleting the folder clears it, harmlessly.

Compiling costs more than rendering: fig11a's kernel takes an order of magnitude longer
to compile than its 500² 1-spp render takes (docs/benchmarks.md, "Start-up: the whole
process", and the AMD EPYC's tables). A scene compiles one kernel per
structure (number of octaves, marble function, lights, …) and image size;
every spp and every opaque parameter (period, distortion, colours, positions)
reuses it. ``render_in_passes`` (mimarble/mitsuba/rendering/passes.py, pixel_tracer.py) passes the spp
and the pass offsets as opaque values, so no spp is in the kernel; it passes
width and height as opaque values too, yet a new image size still compiles a
new kernel (measured, Dr.Jit 1.5 and Mitsuba 3.9: fig11a at 16², 24² and 33²
compiled three render kernels, 16² again found its own in memory).
``mimarble doctor --warm`` (mimarble/cli/doctor.py) renders scenes once so that
those kernels are on disk before the first real render.

drjit-core's C++ call for the folder is reached through mimarble/runtime/drjit_core.py,
once Dr.Jit is imported the safe way (mimarble/runtime/environment.py).
"""

from __future__ import annotations

import ctypes
import os
from pathlib import Path

from . import drjit_core, environment

_CACHE_DIR = "_Z13jit_cache_dirv"     # drjit-core: const char *jit_cache_dir()


def folder() -> Path | None:
    """The folder Dr.Jit keeps compiled kernels in (None: it keeps none)."""
    try:
        environment.import_drjit_and_mitsuba()     # drjit-core is asked once Dr.Jit is set up
        get = getattr(drjit_core.library(), _CACHE_DIR)
        get.restype = ctypes.c_char_p
        path = get()
        if path:
            return Path(path.decode())
    except (OSError, AttributeError):
        pass
    # Not initialised yet, or another drjit-core: its rule.
    if os.environ.get("DRJIT_CACHE_DIR"):
        return Path(os.environ["DRJIT_CACHE_DIR"])
    home = os.environ.get("HOME")
    return Path(home) / ".drjit" if home else None


def usage(path: Path | None = None) -> tuple[int, int]:
    """(kernels, bytes) in the cache folder."""
    path = folder() if path is None else path
    kernels = size = 0
    if path is not None and path.is_dir():
        for entry in os.scandir(path):
            if entry.name.endswith(".bin") and entry.is_file():
                kernels += 1
                size += entry.stat().st_size
    return kernels, size


def describe() -> str:
    """One line for ``mimarble doctor``."""
    path = folder()
    if path is None:
        return "none (no HOME and no DRJIT_CACHE_DIR): every process compiles its kernels"
    kernels, size = usage(path)
    limit = os.environ.get("DRJIT_CACHE_MAXSIZE") or "1G"
    return (f"{path}: {kernels} kernels, {size / 2**20:.1f} MiB (pruned to "
            f"DRJIT_CACHE_MAXSIZE={limit}; delete the folder to clear it)")


def compiled(history) -> int:
    """How many kernels of a ``dr.kernel_history()`` were compiled (found in no cache)."""
    import drjit as dr
    return sum(1 for k in history if k["type"] == dr.KernelType.JIT and not k["cache_hit"])
