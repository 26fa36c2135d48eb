"""Issue 42 item 4's costs: what recording where values stand adds to parsing, what the key
registry adds to ``with_value`` and a sweep's frames, and what a save's ``rewrite`` takes.

    ./go python scripts/keys_timing.py            # prints the figures; ~1 minute

To compare with the tree before the registry, run it with that tree first on PYTHONPATH
(``git archive main | tar -x -C /tmp/base``, then ``PYTHONPATH=/tmp/base``): the parts it
lacks (``rewrite``) are left out. Every figure is a median; the machine is shared, so the
two trees are best run alternately, as docs/benchmarks.md's were.
"""

import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCENES = ("scenes/fig11a.scene", "scenes/fig05.scene", "scenes/beyond-spheres/pawns.scene")


def median_of(run, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    import mimarble
    from mimarble.scene import parse
    from mimarble.scene.edits import with_value
    from mimarble.sweeps.frames import frames
    from mimarble.sweeps.settings import settings_from
    print(f"mimarble from {Path(mimarble.__file__).parent}")
    for name in SCENES:
        path = str(ROOT / name)
        text = (ROOT / name).read_text()
        parse(text, source=path)
        print(f"parse {name}: {median_of(lambda: parse(text, source=path), 200) * 1e3:.3f} ms")
    scene = parse((ROOT / SCENES[0]).read_text())
    for key in ("marble.period", "camera.fov"):
        t = median_of(lambda: with_value(scene, key, 2.0), 2000)
        print(f"with_value {key}: {t * 1e6:.0f} µs")
    settings = settings_from({"marble.period": list(range(100)),
                              "marble.distortion": list(range(100))})
    print(f"frames of a 100 × 100 sweep: {median_of(lambda: frames(scene, settings), 3):.2f} s")
    try:
        from mimarble.scene.rewrite import rewrite
    except ImportError:
        return
    for name, key, value in ((SCENES[0], "marble.period", 2.0),
                             (SCENES[2], "onyx.ramp.1", "#ffffff")):
        path = str(ROOT / name)
        text = (ROOT / name).read_text()
        t = median_of(lambda: rewrite(text, {key: value}, source=path), 50)
        print(f"rewrite {name} {key}: {t * 1e3:.1f} ms")


if __name__ == "__main__":
    sys.exit(main())
