"""The machine a measurement belongs to: its CPU, cores, and what LLVM compiles for.

Every timing mimarble prints or writes (``mimarble bench``, ``mimarble stress``, the
scripts under ``scripts/``) names the machine it was taken on, because the same
render is several times faster on one CPU than another (docs/benchmarks.md). The
facts are gathered here once, so every table names the machine the same way.

Dr.Jit and Mitsuba are imported by :func:`machine_facts` only: naming the machine
of a saved result (:func:`machine_line`) loads neither.
"""

from __future__ import annotations

import os
import platform

#: The CPU features that decide the noise's speed (docs/benchmarks.md): AVX2 or
#: AVX-512 vectors, LLVM's fast-gather cost model, fused multiply-add.
FEATURES_OF_NOTE = ("avx2", "avx512f", "fast-gather", "fma")


def machine_facts() -> dict:
    """The machine every figure belongs to: CPU, cores, versions, the Mitsuba variant,
    and for LLVM variants the target Dr.Jit compiles for (mimarble/runtime/llvm_target.py)."""
    from . import environment, llvm_target
    dr, mi = environment.import_drjit_and_mitsuba()
    facts = {"variant": mi.variant(), "cores": os.cpu_count(), "python": platform.python_version(),
             "mitsuba": mi.__version__, "drjit": dr.__version__, "machine": platform.machine(),
             "processor": _cpu_name()}
    if mi.variant().startswith("llvm_"):
        outcome = llvm_target.configure()
        target = outcome.target
        facts["llvm_target"] = None if target is None else {
            "cpu": target.cpu, "vector_width": target.vector_width, "how": outcome.how,
            "features": [f for f in target.features.split(",")
                         if f.lstrip("+-") in FEATURES_OF_NOTE]}
    return facts


def machine_line(facts: dict) -> str:
    """One line naming the machine of :func:`machine_facts`, for every printed table."""
    line = f"{facts.get('processor', 'unknown CPU')}, {facts['cores']} cores, {facts['variant']}"
    target = facts.get("llvm_target")
    if target:
        line += (f"; LLVM target {target['cpu']}, vector width {target['vector_width']}, "
                 f"{' '.join(target['features'])}")
    return line


def _cpu_name() -> str:
    """The CPU's model name from ``/proc/cpuinfo`` (Linux), else ``unknown``."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"
