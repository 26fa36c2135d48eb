"""How Dr.Jit's LLVM back end cuts a kernel's lanes into work for its threads.

drjit-core launches a CPU kernel as blocks that its threads take in turn: up to
2 · threads · B lanes it makes 2 · threads blocks, above that blocks of B lanes
(``jit_llvm_block_size``, 16 384 by default). With two threads, the machines this project
runs on, a kernel of 65 536 lanes — a 256² first pass of adaptive sampling, most of its
rounds — is then four blocks, and one of 80 000 lanes five: where lanes cost unequally
(a sphere's against the background's, the sphere in the middle rows) one thread finishes
late while the other waits. Blocks of :data:`BLOCK_SIZE` lanes (16 to 20 there) balance
them; kernels of a million lanes (a plain 256² render at 16 spp: 64 blocks either way)
and small ones (fewer than four blocks' worth) are cut as before. Which lane runs where
changes no value: images are the same bit for bit (tests/test_llvm_blocks.py). Measured
in docs/benchmarks.md, "Dr.Jit's blocks".

* automatic (``MIMARBLE_LLVM_BLOCK_SIZE`` unset): :data:`BLOCK_SIZE`;
* ``MIMARBLE_LLVM_BLOCK_SIZE=default``: Dr.Jit's own;
* ``MIMARBLE_LLVM_BLOCK_SIZE=N``: N lanes, a power of two of at least the vector width
  (drjit-core's own rule: it raises a C++ exception otherwise, which through ctypes would
  end the process, so the value is checked here first).

Set once, after the LLVM target (the vector width is the target's), by
``mimarble.runtime.environment.import_drjit_and_mitsuba``; it is read at every launch, so
it applies from then on. drjit-core exports the calls as C++ symbols of
``libdrjit-core.so`` (opened by mimarble/runtime/drjit_core.py); when they are missing
(another Dr.Jit version) Dr.Jit's own stays and :func:`configure`'s outcome says so.
"""

from __future__ import annotations

import ctypes
import dataclasses
import os
import sys

from . import drjit_core
from .llvm_target import _VECTOR_WIDTH

BLOCK_SIZE_ENV = "MIMARBLE_LLVM_BLOCK_SIZE"
#: Lanes a block: enough blocks to balance two threads over kernels of 65 536 lanes, few
#: enough that taking a block (a few microseconds) stays small beside its ~0.1 ms of work.
BLOCK_SIZE = 4096

# drjit-core 1.5's C++ symbols (Itanium mangling of the declarations in drjit-core/jit.h).
_SET_BLOCK_SIZE = "_Z23jit_llvm_set_block_sizej"
_BLOCK_SIZE = "_Z19jit_llvm_block_sizev"


@dataclasses.dataclass(frozen=True)
class Outcome:
    block_size: int | None  # lanes a block (None: could not be read)
    how: str                # one phrase: what was decided and why


def parse(value: str, vector_width: int) -> int | None:
    """The block size ``MIMARBLE_LLVM_BLOCK_SIZE`` asks for (None: Dr.Jit's own). Raises
    ValueError for anything drjit-core would refuse."""
    value = value.strip()
    if value == "default":
        return None
    if not value.isdigit():
        raise ValueError(f"{BLOCK_SIZE_ENV}={value!r}: expected 'default' or a number of lanes")
    size = int(value)
    if size < vector_width or size & (size - 1) or size >= 1 << 31:
        raise ValueError(f"{BLOCK_SIZE_ENV}={value!r}: the block size must be a power of two "
                         f"from the vector width ({vector_width}) up to 2**30")
    return size


class _Core:
    """drjit-core's block size calls through ctypes; raises OSError/AttributeError when absent."""

    def __init__(self):
        lib = drjit_core.library()
        self._set, self._get, self._width = (getattr(lib, name) for name in
                                             (_SET_BLOCK_SIZE, _BLOCK_SIZE, _VECTOR_WIDTH))
        self._set.argtypes, self._set.restype = [ctypes.c_uint32], None
        self._get.restype = self._width.restype = ctypes.c_uint32

    def vector_width(self) -> int:
        return int(self._width())

    def read(self) -> int:
        return int(self._get())

    def write(self, size: int) -> None:
        """Set ``size`` lanes a block, checked first (drjit-core's refusal would end the
        process). Raises ValueError."""
        parse(str(size), self.vector_width())
        self._set(size)


def set_block_size(size: int) -> None:
    """Set the block size now (a benchmark's comparison of sizes); raises ValueError for one
    drjit-core would refuse, OSError/AttributeError where its calls are missing."""
    _Core().write(size)


_outcome: Outcome | None = None


def configure() -> Outcome:
    """Decide and set the block size once; later calls report it. Before Dr.Jit is imported
    nothing is decided (the outcome says so), as for the LLVM target."""
    global _outcome
    if _outcome is not None:
        return _outcome
    if "drjit" not in sys.modules:
        return Outcome(None, "not decided yet: Dr.Jit is not imported")
    try:
        core = _Core()
    except (OSError, AttributeError) as e:
        _outcome = Outcome(None, f"Dr.Jit's own (drjit-core's block size calls are not "
                                 f"available: {e})")
        return _outcome
    requested = os.environ.get(BLOCK_SIZE_ENV)
    try:
        if requested is None:
            wanted, how = BLOCK_SIZE, "set by mimarble: blocks balanced over the threads"
        else:
            wanted = parse(requested, core.vector_width())
            how = (f"Dr.Jit's own, as {BLOCK_SIZE_ENV}={requested!r} asks" if wanted is None
                   else f"from {BLOCK_SIZE_ENV}={requested!r}")
        if wanted is not None:
            core.write(wanted)
    except ValueError as e:
        import warnings
        warnings.warn(f"mimarble: {e}; keeping Dr.Jit's block size", stacklevel=2)
        how = f"Dr.Jit's own; {BLOCK_SIZE_ENV} was not understood" if requested is not None \
            else f"Dr.Jit's own ({e})"
    _outcome = Outcome(core.read(), how)
    return _outcome
