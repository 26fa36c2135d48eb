"""Adaptive and plain 16 spp renders under several of Dr.Jit's LLVM block sizes, interleaved.

    SIZES=16384,8192,4096,2048 T=1.5e-3 ./go python scripts/llvm_block_timing.py SCENE …

Each scene at 256², point-sampled: an adaptive render (first pass 1 spp, at most 81,
threshold T) and a plain 16 spp render, under each block size in turn (set through
drjit-core's ``jit_llvm_set_block_size``, mimarble/runtime/llvm_blocks.py), nine rounds;
prints the medians (ms) and the load (docs/benchmarks.md, "Dr.Jit's blocks").
"""
import os, statistics, sys, time
import mimarble
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering import adaptive
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.scene.edits import resized
dr, mi = mimarble.dr, mimarble.mi
from mimarble.runtime import llvm_blocks
setbs = llvm_blocks.set_block_size
T = float(os.environ.get("T", "1.5e-3"))
SIZES = tuple(int(x) for x in os.environ.get("SIZES","16384,8192,4096,2048").split(","))
for path in sys.argv[1:]:
    m = mi.load_dict(to_mitsuba(resized(mimarble.scene.load(path), 256), spp=1))
    f = lambda: adaptive.render_adaptive(m, 1, T, 81)
    for _ in range(2): r = f(); render_in_passes(m, 16)
    res = {}
    for rep in range(9):
        for bs in SIZES:
            setbs(bs); dr.sync_thread()
            s = time.perf_counter(); f(); dr.sync_thread(); a = time.perf_counter() - s
            s = time.perf_counter(); render_in_passes(m, 16); dr.sync_thread(); p = time.perf_counter() - s
            res.setdefault(bs, []).append((1000 * a, 1000 * p))
    setbs(llvm_blocks.configure().block_size)
    print(os.path.basename(path), f"{r.traced/65536:.2f} spp", {bs: (round(statistics.median(a for a, _ in v), 2), round(statistics.median(b for _, b in v), 2)) for bs, v in res.items()}, "adaptive ms, plain16 ms", os.getloadavg()[0], flush=True)
