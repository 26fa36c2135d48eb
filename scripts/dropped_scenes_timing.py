"""A recorded pass after other scenes were loaded, rendered and dropped (issue 43): the
sphere tables once held their shapes alive, and every replay walked them.

    ./go python scripts/dropped_scenes_timing.py
"""
import gc, time, statistics, mimarble
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.scene.edits import resized
dr, mi = mimarble.dr, mimarble.mi
def med(m):
    ts = []
    for _ in range(40):
        dr.sync_thread(); t = time.perf_counter(); render_in_passes(m, 1); dr.sync_thread(); ts.append(1000*(time.perf_counter()-t))
    return statistics.median(ts)
a = mi.load_dict(to_mitsuba(resized(mimarble.scene.load("scenes/fig11a.scene"), 16)))
render_in_passes(a, 1)
before = med(a)
for name in ("fig09d", "fig10a", "fig07b"):
    b = mi.load_dict(to_mitsuba(resized(mimarble.scene.load(f"scenes/{name}.scene"), 16)))
    render_in_passes(b, 1); del b
gc.collect()
render_in_passes(a, 1)
print(f"16² 1-spp render: {before:.3f} ms alone, {med(a):.3f} ms after three scenes loaded, rendered and dropped")
