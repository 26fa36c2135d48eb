"""Host reads (synchronisations) of one Adam step of notebook 02, by who issues them.

    ./go python scripts/count_syncs.py [--steps N] [--timing N]

The step is notebook 02's (part 3), as ``mimarble/bench/adam.py`` writes it: the
optimiser's period, distortion and vein colour into the scene through ``mi.traverse``,
``params.update()``, ``mi.render`` (``prb``, 64×64, 16 spp), the L2 loss,
``dr.backward``, ``opt.step()``, the colour clipped to [0, 1] — traced every step (not
frozen: a replay of ``dr.freeze`` runs no Python at all, so no Python read can happen in
it; the traced step is the one that shows them).

A host read is any call that waits for the device and copies a value to Python: an
array's ``numpy()``, ``__array__``, ``tolist()``, ``array``, ``__float__``/``__int__``/
``__index__``/``__bool__``, ``__repr__``/``__str__``, one lane read by ``x[i]`` (but not a
literal's, which the host already holds: Dr.Jit copies it without waiting), and
``dr.sync_thread()``. Dr.Jit offers no counter of its own synchronisations (its
``JitFlag.ForbidSynchronization`` raises at the first explicit one and does not see
single-lane reads on LLVM), so the script wraps those entry points of every Dr.Jit and
Mitsuba array type and attributes each read to the innermost Python frame that called it:
mimarble's own code (``mimarble/``), Mitsuba's Python code, Dr.Jit's, or this script.
Reads made inside C++ (Mitsuba's own plugins) are not seen; none is mimarble's.

Printed: reads per step by source and by mimarble's file:line, the kernels launched per
step (Dr.Jit's kernel history, JIT kernels and the rest), and with ``--timing N`` the
medians over N further steps of the wall time and of the process's CPU time (every
thread; steadier than the wall time on a machine others share), a sync before each
clock read.
"""

from __future__ import annotations

import argparse
import collections
import os
import statistics
import sys
import time
from pathlib import Path

import mimarble

mimarble.start()

from mimarble.bench.adam import START, TRUE, adam_step, marble_scene, optimiser_at_start

dr, mi = mimarble.dr, mimarble.mi

PACKAGE = Path(mimarble.__file__).resolve().parent
#: The methods that copy an array's value to the host (see the module docstring).
READING_METHODS = ("numpy", "__array__", "tolist", "__float__", "__int__", "__index__",
                   "__bool__", "__repr__", "__str__")


class HostReads:
    """Counts host reads, by the innermost Python frame that issued them."""

    def __init__(self):
        self.by_site = collections.Counter()
        self.counting = False
        self._originals = []

    def source(self, site: str) -> str:
        if site.startswith(str(PACKAGE)):
            return "mimarble"
        if os.sep + "mitsuba" + os.sep in site:
            return "mitsuba (Python)"
        if os.sep + "drjit" + os.sep in site:
            return "drjit (Python)"
        return "this script"

    def _record(self):
        if not self.counting:
            return
        frame = sys._getframe(2)
        self.by_site[f"{frame.f_code.co_filename}:{frame.f_lineno}"] += 1

    def _wrap_method(self, cls, name):
        original = cls.__dict__[name]
        counter = self

        def reading(self_, *args, **kwargs):
            if dr.is_jit_v(type(self_)):          # a scalar array is on the host already
                counter._record()
            return original(self_, *args, **kwargs)
        setattr(cls, name, reading)
        self._originals.append((cls, name, original))

    def _wrap_getitem(self, cls):
        # The class's own slot takes integers only; anything else (a mask, a slice) goes
        # to the base's, as Dr.Jit's own lookup would.
        lane, general = cls.__dict__["__getitem__"], dr.ArrayBase.__dict__["__getitem__"]
        counter = self

        def getitem(self_, index):
            value = (lane if type(index) is int else general)(self_, index)
            # One lane of a JIT array read into a Python number (a component of a nested
            # array is an array: no read); a literal is copied without waiting.
            if isinstance(value, (bool, int, float)) and dr.is_jit_v(type(self_)) \
                    and self_.state != dr.VarState.Literal:
                counter._record()
            return value
        setattr(cls, "__getitem__", getitem)
        self._originals.append((cls, "__getitem__", lane))

    def install(self):
        classes = {dr.ArrayBase}
        for module in (dr.llvm, dr.llvm.ad, mi):
            classes.update(c for c in vars(module).values()
                           if isinstance(c, type) and issubclass(c, dr.ArrayBase))
        for cls in classes:
            for name in READING_METHODS:
                if name in cls.__dict__:
                    self._wrap_method(cls, name)
            if "__getitem__" in cls.__dict__ and cls is not dr.ArrayBase \
                    and dr.depth_v(cls) == 1:
                self._wrap_getitem(cls)
        sync = dr.sync_thread
        counter = self

        def sync_thread():
            counter._record()
            return sync()
        dr.sync_thread = sync_thread
        self._originals.append((dr, "sync_thread", sync))

    def uninstall(self):
        for owner, name, original in reversed(self._originals):
            setattr(owner, name, original)
        self._originals.clear()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=3, help="counted steps (after one warm)")
    parser.add_argument("--timing", type=int, default=0,
                        help="further steps whose median wall time is printed")
    args = parser.parse_args()
    target = mi.render(marble_scene(**TRUE), spp=32, seed=1)
    scene = marble_scene(**START)
    marble, opt = optimiser_at_start(scene)
    reads = HostReads()
    reads.install()
    launches = collections.Counter()
    try:
        for it in range(1 + args.steps):
            dr.eval(opt["period"], opt["distortion"], opt["vein"])
            reads.counting = it > 0            # the first step traces and compiles: warm
            with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
                dr.kernel_history()
                loss = adam_step(scene, marble, opt, target, mi.UInt32(it))
                dr.eval(loss, opt["period"], opt["distortion"], opt["vein"])
                reads.counting = False
                history = dr.kernel_history()
            if it > 0:
                launches.update(str(k["type"]).split(".")[-1] for k in history)
        wall, cpu = [], []
        for it in range(args.timing):
            dr.sync_thread()
            start, start_cpu = time.perf_counter(), time.process_time()
            loss = adam_step(scene, marble, opt, target, mi.UInt32(100 + it))
            dr.eval(loss, opt["period"], opt["distortion"], opt["vein"])
            dr.sync_thread()
            wall.append((time.perf_counter() - start) * 1e3)
            cpu.append((time.process_time() - start_cpu) * 1e3)
    finally:
        reads.uninstall()
    steps = args.steps
    by_source = collections.Counter()
    for site, n in reads.by_site.items():
        by_source[reads.source(site)] += n
    print(f"host reads per traced Adam step ({mi.variant()}, {steps} steps counted):")
    for source in ("mimarble", "mitsuba (Python)", "drjit (Python)", "this script"):
        print(f"  {source:18s} {by_source[source] / steps:g}")
    mine = sorted((site, n) for site, n in reads.by_site.items()
                  if reads.source(site) == "mimarble")
    for site, n in mine:
        print(f"    {os.path.relpath(site, PACKAGE.parent)}  {n / steps:g}")
    print("kernels per step: " + ", ".join(f"{kind} {n / steps:g}"
                                           for kind, n in sorted(launches.items())))
    if wall:
        print(f"step time: median {statistics.median(wall):.1f} ms wall, "
              f"{statistics.median(cpu):.1f} ms CPU (every thread) of {len(wall)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
