"""The noise alone against Python-callable peers: one thread each, the same points.

What is timed, per row, is an 8-octave fractional Brownian motion (gain 0.5,
lacunarity 2) of a gradient noise at the same random points (seeded, uniform in
[−16, 16]³), on one CPU thread, warm, the median of several repeats, reported as
M octave-evals/s = points · octaves / seconds / 10⁶:

* **mimarble** — :func:`mimarble.texture.noise.fractal3`, Ken Perlin's improved noise
  (2002) summed as Σ_{i<K} N(2^i p)/2^i, one Dr.Jit LLVM kernel over all points
  (a symbolic octave loop), with ``dr.set_thread_count(1)``: Dr.Jit then runs the
  kernel on the calling thread alone. Each repeat traces the expression again and
  finds the kernel in Dr.Jit's cache, as any caller would; the first (compiling)
  call is left out.
* **FastNoise Lite** (``pyfastnoiselite``) — its Perlin noise with the FBm fractal
  type, frequency 1 (so its lattice cells are the same unit cubes as ours).
  ``gen_from_coords`` is a plain Cython loop over the points calling the C++
  ``GetNoise`` per point: single-threaded, it has no thread option (no OpenMP, no
  thread pool).
* **noise** (the ``noise`` package, Casey Duncan's C extension) — ``pnoise3``,
  Perlin's improved noise with fBm, one point per call, so it is timed on fewer
  points (:data:`SCALAR_POINTS`) in a Python loop, and its rate includes Python's
  per-call overhead. One thread.

Comparable, not identical. All three are 8-octave fBm of a Perlin-style gradient
noise evaluated in float32 on one core, so the rates measure the same kind of work;
but they are different noises. mimarble and ``noise`` both follow Perlin's improved
noise (his permutation table, 12 edge gradients, quintic fade), yet ``noise`` wraps
the lattice at a period of 1024 and divides the sum by the total amplitude;
FastNoise Lite's Perlin hashes the lattice with prime multiplications, has its own
gradient set, changes the seed per octave and scales the sum by its "fractal
bounding". Their values therefore differ and only the speeds are compared. Numbers
also depend on the machine (mimarble/runtime/machine.py names it in every table) and on
the LLVM target Dr.Jit compiles for (mimarble/runtime/llvm_target.py).

Both peers are optional (``pip install mimarble[peers]``): a peer that cannot be
imported gets a row without a rate and with the reason.

    python -m mimarble.bench.peers [points]
"""

from __future__ import annotations

import importlib
import statistics
import sys
import time

import numpy as np

#: Why a peer's row has no rate when its package cannot be imported.
NOT_INSTALLED = "not installed (pip install mimarble[peers])"
#: Points for the peers called once per point from Python (the ``noise`` package).
SCALAR_POINTS = 1 << 16
#: The points: uniform in [−EXTENT, EXTENT]³.
EXTENT = 16.0

OURS = "mimarble fractal3 (Dr.Jit LLVM)"
FASTNOISELITE = "FastNoise Lite Perlin FBm (pyfastnoiselite)"
NOISE = "noise.pnoise3 (noise, Python loop)"


def sample_points(points: int, seed: int = 0) -> np.ndarray:
    """``points`` random points, (points, 3) float32, uniform in [−16, 16]³, seeded."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-EXTENT, EXTENT, (points, 3)).astype(np.float32)


def _import_peer(module: str):
    """The peer's module, or None when it cannot be imported."""
    try:
        return importlib.import_module(module)
    except ImportError:
        return None


def _median_seconds(run, repeats: int) -> float:
    """Run once to warm (compile, caches), then the median of ``repeats`` timed runs."""
    run()
    times = []
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _row(name: str, points: int, octaves: int, seconds: float | None, note: str) -> dict:
    rate = None if seconds is None else points * octaves / seconds / 1e6
    return {"name": name, "m_octave_evals_per_s": rate, "points": points, "threads": 1,
            "note": note}


def _skipped(name: str, points: int, note: str = NOT_INSTALLED) -> dict:
    return {"name": name, "m_octave_evals_per_s": None, "points": points, "threads": 1,
            "note": note}


def measure_ours(xyz: np.ndarray, octaves: int, repeats: int) -> dict:
    """mimarble's ``fractal3`` over ``xyz`` in the ``llvm_ad_rgb`` variant, one thread."""
    import mimarble
    mimarble.start()
    mi, dr = mimarble.mi, mimarble.dr
    from mimarble.runtime import environment
    from mimarble.texture import noise

    problem = environment.variant_problem("llvm_ad_rgb")
    if problem:
        return _skipped(OURS, len(xyz), f"LLVM variant unusable: {problem}")
    previous_variant, previous_threads = mi.variant(), dr.thread_count()
    try:
        if previous_variant != "llvm_ad_rgb":
            mi.set_variant("llvm_ad_rgb")
        dr.set_thread_count(1)
        p = mi.Point3f(*(np.ascontiguousarray(xyz[:, k]) for k in range(3)))
        dr.eval(p)
        dr.sync_thread()

        def run():
            value = noise.fractal3(p, octaves)
            dr.eval(value)
            dr.sync_thread()

        seconds = _median_seconds(run, repeats)
        width = _vector_width()
    finally:
        dr.set_thread_count(previous_threads)
        if mi.variant() != previous_variant and previous_variant is not None:
            mi.set_variant(previous_variant)
    note = ("one kernel over all points, symbolic octave loop, warm (compile excluded), "
            "trace + cache lookup + run" + (f", vector width {width}" if width else ""))
    return _row(OURS, len(xyz), octaves, seconds, note)


def _vector_width() -> int | None:
    try:
        from mimarble.runtime import llvm_target
        target = llvm_target.configure().target
        return None if target is None else target.vector_width
    except Exception:       # the width is a note; never fail the measurement for it
        return None


def measure_fastnoiselite(xyz: np.ndarray, octaves: int, repeats: int) -> dict:
    """FastNoise Lite's Perlin FBm over ``xyz`` via ``gen_from_coords``, (3, N) float32."""
    fnl = _import_peer("pyfastnoiselite.pyfastnoiselite")
    if fnl is None:
        return _skipped(FASTNOISELITE, len(xyz))
    generator = fnl.FastNoiseLite(0)
    generator.noise_type = fnl.NoiseType.NoiseType_Perlin
    generator.fractal_type = fnl.FractalType.FractalType_FBm
    generator.fractal_octaves = octaves
    generator.fractal_gain = 0.5
    generator.fractal_lacunarity = 2.0
    generator.frequency = 1.0
    coords = np.ascontiguousarray(xyz.T, dtype=np.float32)

    def run():
        generator.gen_from_coords(coords)

    seconds = _median_seconds(run, repeats)
    return _row(FASTNOISELITE, len(xyz), octaves, seconds,
                "gen_from_coords: a serial Cython loop of GetNoise (no thread option), "
                "frequency 1")


def measure_noise(xyz: np.ndarray, octaves: int, repeats: int) -> dict:
    """The ``noise`` package's ``pnoise3``, one call per point in a Python loop."""
    points = min(len(xyz), SCALAR_POINTS)
    noise_package = _import_peer("noise")
    if noise_package is None:
        return _skipped(NOISE, points)
    pnoise3 = noise_package.pnoise3
    coordinates = xyz[:points].astype(np.float64).tolist()

    def run():
        for x, y, z in coordinates:
            pnoise3(x, y, z, octaves, 0.5, 2.0)

    seconds = _median_seconds(run, repeats)
    return _row(NOISE, points, octaves, seconds,
                f"scalar: one call per point, first {points} points, "
                "includes Python call overhead")


def peer_rates(points: int = 1 << 20, octaves: int = 8, repeats: int = 5,
               seed: int = 0) -> list[dict]:
    """One row per implementation (mimarble first): M octave-evals/s on one thread.

    Every row is measured on the same seeded points (the ``noise`` package on the
    first :data:`SCALAR_POINTS` of them). A peer that cannot be imported gets
    ``m_octave_evals_per_s`` None and :data:`NOT_INSTALLED` as its note.
    """
    if points < 1:
        raise ValueError(f"points must be at least 1, got {points}")
    if octaves < 1:
        raise ValueError(f"octaves must be at least 1, got {octaves}")
    xyz = sample_points(points, seed)
    return [measure_ours(xyz, octaves, repeats),
            measure_fastnoiselite(xyz, octaves, repeats),
            measure_noise(xyz, octaves, repeats)]


def machine_description() -> str:
    """The machine line of every mimarble table (mimarble/runtime/machine.py)."""
    from mimarble.runtime.machine import machine_facts, machine_line
    return machine_line(machine_facts())


def peers_table(rows, machine: str | None = None) -> str:
    """A markdown table of :func:`peer_rates`' rows, one table row per row; a row
    without a rate reads "skipped". With ``machine``, a line naming it comes first."""
    lines = [f"Machine: {machine}", ""] if machine else []
    lines += ["| implementation | M octave-evals/s | points | threads | note |",
              "|---|---:|---:|---:|---|"]
    for row in rows:
        rate = row["m_octave_evals_per_s"]
        shown = "skipped" if rate is None else f"{rate:.1f}"
        note = str(row.get("note", "")).replace("|", "\\|")
        lines.append(f"| {row['name']} | {shown} | {row['points']} | {row['threads']} | "
                     f"{note} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    points = int(args[0]) if args else 1 << 20
    rows = peer_rates(points=points)
    print(peers_table(rows, machine=machine_description()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
