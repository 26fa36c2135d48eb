"""What a replay's walk of its inputs costs on the host: a frozen function that adds 1 to 16
lanes, called with nothing more, then with a loaded scene or one of its parts as an extra
argument (which Dr.Jit walks at every call). Medians and minima of 200 calls, in ms.

    ./go python scripts/frozen_walk_cost.py [SCENE]        # default scenes/fig09d.scene

A pass of adaptive sampling's rounds takes the scene as an input (mimarble/mitsuba/rendering/
passes.py), so this is a floor on each pass's host time (issue 43).
"""
import statistics
import sys
import time

import mimarble
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.plugins.material import CHANNELS
from mimarble.scene.edits import resized

dr, mi = mimarble.dr, mimarble.mi

path = sys.argv[1] if len(sys.argv) > 1 else "scenes/fig09d.scene"
scene = mi.load_dict(to_mitsuba(resized(mimarble.scene.load(path), 256), spp=1))
x = dr.arange(mi.Float, 16)


def timed(call, repeats=200):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(1e3 * (time.perf_counter() - start))
    return f"median {statistics.median(times):.3f}, least {min(times):.3f}"


@dr.freeze
def alone(x):
    return x + 1


bsdf = scene.shapes()[0].bsdf()
parts = [("the scene", scene), ("its shapes", scene.shapes()), ("the first shape's BSDF", bsdf),
         ("the sensor", scene.sensors()[0]), ("the emitters", scene.emitters()),
         ("the integrator", scene.integrator())]
parts += [(f"the BSDF's {name} ({type(getattr(bsdf, name)).__name__})", getattr(bsdf, name))
          for name in CHANNELS if getattr(bsdf, name, None) is not None]
for _ in range(3):
    alone(x)
print(f"{path}: nothing more: {timed(lambda: alone(x))} ms")
for name, value in parts:
    with_input = dr.freeze(lambda extra, x: x + 1)       # one per input: one recording each
    for _ in range(3):
        with_input(value, x)
    print(f"  {name}: {timed(lambda: with_input(value, x))} ms")
print("  the BSDF's ambient and diffuse are one object:", bsdf.ambient is bsdf.diffuse
      if hasattr(bsdf, "ambient") and hasattr(bsdf, "diffuse") else "—")
