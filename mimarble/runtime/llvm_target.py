"""The LLVM target Dr.Jit compiles CPU kernels for: told where gathers are cheap.

The noise is gathers (5 per octave: mimarble/texture/noise.py, ``corner_hashes``).
LLVM's cost model for AMD Zen says vector gathers are slow and lowers each one
to scalar loads, 8 per AVX2 vector; on Intel AVX-512 CPUs it emits
``vpgatherdd``. Telling LLVM that gathers are fast (``+fast-gather``) makes the noise and
the marble scenes markedly faster on the AMD EPYC, the same values bit for bit
(docs/benchmarks.md, "AMD EPYC (AVX2): the other machine kind"). On Intel CPUs from Skylake
on, LLVM already assumes fast gathers, so the feature changes nothing there. Hence the rule:

* automatic (``MIMARBLE_LLVM_TARGET`` unset): on x86 with AVX2, add
  ``+fast-gather`` to the features Dr.Jit detected;
* ``MIMARBLE_LLVM_TARGET=default``: leave Dr.Jit's detection alone;
* ``MIMARBLE_LLVM_TARGET="CPU|FEATURES|WIDTH"``: a target CPU name (e.g.
  ``znver3``, to make one machine generate the other's code — only for a CPU
  whose instructions this one has), features to append (``+fast-gather``,
  ``-fast-gather``), a vector width; an empty part keeps what was detected.

drjit-core exports the calls as C++ symbols of ``libdrjit-core.so``
(``jit_llvm_set_target`` and the three getters, opened by mimarble/runtime/drjit_core.py);
when they are missing (another Dr.Jit version) the default stays and
:func:`configure`'s outcome says so. The setting must be made once Dr.Jit is
imported and before the first kernel is compiled, for it to apply everywhere:
``mimarble.runtime.environment.import_drjit_and_mitsuba`` calls :func:`configure` then.
Dr.Jit's kernel cache keys on it, so kernels compiled either way never mix.
Images are bit-identical with and without ``+fast-gather``; another vector width
leaves the noise exact and moves shaded colours by float32 rounding (≤ 1.1e-5
measured on fig11a), see tests/test_llvm_target.py.
"""

from __future__ import annotations

import ctypes
import dataclasses
import os
import platform
import sys

from . import drjit_core

TARGET_ENV = "MIMARBLE_LLVM_TARGET"
FAST_GATHER = "+fast-gather"

# drjit-core 1.5's C++ symbols (Itanium mangling of the declarations in drjit-core/jit.h).
_SET_TARGET = "_Z19jit_llvm_set_targetPKcS0_j"
_TARGET_CPU = "_Z19jit_llvm_target_cpuv"
_TARGET_FEATURES = "_Z24jit_llvm_target_featuresv"
_VECTOR_WIDTH = "_Z21jit_llvm_vector_widthv"


@dataclasses.dataclass(frozen=True)
class Target:
    cpu: str
    features: str          # LLVM's comma-separated +feat/-feat list
    vector_width: int

    def has(self, feature: str) -> bool:
        return feature in self.features.split(",")

    def summary(self) -> str:
        shown = [f for f in ("+avx512f", "+avx2", FAST_GATHER) if self.has(f)]
        return f"{self.cpu}, vector width {self.vector_width}, {' '.join(shown) or 'no AVX2'}"


@dataclasses.dataclass(frozen=True)
class Outcome:
    target: Target | None   # what kernels are compiled for (None: could not be read)
    how: str                # one phrase: what was decided and why


class _Core:
    """drjit-core's target calls through ctypes; raises OSError/AttributeError when absent."""

    def __init__(self):
        lib = drjit_core.library()
        self._set = getattr(lib, _SET_TARGET)
        self._set.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint32]
        self._set.restype = None
        self._cpu, self._features, self._width = (getattr(lib, name) for name in
                                                 (_TARGET_CPU, _TARGET_FEATURES, _VECTOR_WIDTH))
        self._cpu.restype = self._features.restype = ctypes.c_char_p
        self._width.restype = ctypes.c_uint32

    def read(self) -> Target:
        return Target((self._cpu() or b"").decode(), (self._features() or b"").decode(),
                      int(self._width()))

    def write(self, target: Target) -> None:
        self._set(target.cpu.encode(), target.features.encode(), target.vector_width)


def parse(value: str, detected: Target) -> Target | None:
    """The target ``MIMARBLE_LLVM_TARGET`` asks for (None: Dr.Jit's default). Raises ValueError."""
    value = value.strip()
    if value == "default":
        return None
    parts = value.split("|")
    if len(parts) > 3:
        raise ValueError(f"{TARGET_ENV}={value!r}: expected 'default' or 'CPU|FEATURES|WIDTH'")
    cpu, features, width = (parts + ["", "", ""])[:3]
    extra = [f.strip() for f in features.split(",") if f.strip()]
    if any(f[0] not in "+-" for f in extra):
        raise ValueError(f"{TARGET_ENV}={value!r}: features are '+name' or '-name', "
                         f"comma-separated")
    if width.strip() and (not width.strip().isdigit() or int(width) not in (1, 4, 8, 16)):
        raise ValueError(f"{TARGET_ENV}={value!r}: the vector width must be 1, 4, 8 or 16")
    return Target(cpu.strip() or detected.cpu,
                  ",".join(filter(None, [detected.features, *extra])),
                  int(width) if width.strip() else detected.vector_width)


def automatic(detected: Target) -> Target | None:
    """The rule of the module docstring: +fast-gather on x86 with AVX2, where absent."""
    x86 = platform.machine().lower() in ("x86_64", "amd64")
    if x86 and detected.has("+avx2") and not detected.has(FAST_GATHER):
        return dataclasses.replace(detected, features=f"{detected.features},{FAST_GATHER}")
    return None


_outcome: Outcome | None = None


def configure() -> Outcome:
    """Decide and set the target once, before kernels are compiled; later calls report it.

    Before Dr.Jit is imported there is no target to read yet: the outcome then
    says so and nothing is decided, so that the call the import makes
    (``mimarble.runtime.environment.import_drjit_and_mitsuba``) decides.
    """
    global _outcome
    if _outcome is not None:
        return _outcome
    if "drjit" not in sys.modules:
        return Outcome(None, "not decided yet: Dr.Jit is not imported")
    try:
        core = _Core()
        detected = core.read()
    except (OSError, AttributeError) as e:
        _outcome = Outcome(None, f"Dr.Jit's default (drjit-core's target calls are not "
                                 f"available: {e})")
        return _outcome
    requested = os.environ.get(TARGET_ENV)
    try:
        if requested is not None:
            wanted, how = parse(requested, detected), f"from {TARGET_ENV}={requested!r}"
        else:
            wanted = automatic(detected)
            how = (f"{FAST_GATHER} added by mimarble: vector gathers for the noise"
                   if wanted else "Dr.Jit's detection")
    except ValueError as e:
        import warnings
        warnings.warn(f"mimarble: {e}; keeping Dr.Jit's detected target", stacklevel=2)
        wanted, how = None, f"Dr.Jit's detection; {TARGET_ENV} was not understood"
    if wanted is not None and wanted != detected:
        core.write(wanted)
        detected = core.read()
    if wanted is None and requested is not None:
        how = f"Dr.Jit's detection, as {TARGET_ENV}={requested!r} asks"
    _outcome = Outcome(detected, how)
    return _outcome
