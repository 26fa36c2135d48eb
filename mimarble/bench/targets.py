"""The issue's targets, measured on fig11a: octaves 32 against 8, marble against a
constant colour, octave evaluations per second, time to RMSE 0.01; the whole command's
process times (help, a malformed scene, a render warm and cold); POV-Ray beside it."""

from __future__ import annotations

import os
import statistics
import time
from pathlib import Path

from mimarble import scene as scene_language
from mimarble.bench.modes import TARGET_MODES
from mimarble.bench.timing import converged, hit_fraction, time_render
from mimarble.mitsuba.translate.scene_dict import marble_tolerance
from mimarble.scene.edits import filling_the_view, resized, with_constant_colours, with_marbles
from mimarble.tools import stress
from mimarble.tools.compare import image_metrics



def targets_scene(scene_paths):
    """The scene the targets are measured on: fig11a among ``scene_paths``, else the
    repository's ``scenes/fig11a.scene`` when there is one, else None."""
    for path in scene_paths:
        if Path(path).stem == "fig11a":
            return str(path)
    beside_package = Path(__file__).resolve().parents[2] / "scenes" / "fig11a.scene"
    return str(beside_package) if beside_package.is_file() else None



#: The malformed scene's answer is the best of this many whole-process runs (issue 39):
#: the least time is the one the machine's other work added least to.
MALFORMED_SCENE_RUNS = 5


def _process_seconds(args, repeats: int, expect: int = 0, fresh_caches=False,
                     best=False) -> float:
    """Median wall time (``best``: the least) of ``python -m mimarble ARGS`` (the
    command's whole process), which must exit with status ``expect``.

    ``fresh_caches``: each run gets empty kernel and parser caches, as a new user has.
    Python's bytecode is written and used as an installed package's is, whatever
    ``PYTHONDONTWRITEBYTECODE`` says here (without it, every run compiles mimarble and Lark
    from source, a cost the user's installed package does not have: docs/benchmarks.md,
    "Figures moved out of the code").
    """
    import subprocess
    import sys
    import tempfile
    times = []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as folder:
            run_env = dict(os.environ)
            run_env.pop("PYTHONDONTWRITEBYTECODE", None)
            if fresh_caches:
                run_env.update(DRJIT_CACHE_DIR=str(Path(folder) / "drjit"),
                               XDG_CACHE_HOME=str(Path(folder) / "cache"))
            start = time.perf_counter()
            result = subprocess.run([sys.executable, "-m", "mimarble", *map(str, args)],
                                    env=run_env, capture_output=True, text=True)
            times.append(time.perf_counter() - start)
            if result.returncode != expect:
                raise RuntimeError(f"mimarble {' '.join(map(str, args))}: exit status "
                                   f"{result.returncode}, expected {expect}: {result.stderr}")
    return min(times) if best else statistics.median(times)


def process_times(scene_path, repeats) -> dict:
    """Whole-process seconds of the command (issue 17): help, a malformed scene (the best
    of :data:`MALFORMED_SCENE_RUNS`, as ``mimarble render bad.scene`` is timed: issue 39),
    and a render of ``scene_path`` at 500², 1 spp with warm caches and with empty ones."""
    import tempfile
    with tempfile.TemporaryDirectory() as folder:
        bad = Path(folder) / "malformed.scene"
        bad.write_text("camera {\n  eye < 0 0 10 >\n  foo\n}\n")
        out = Path(folder) / "out.png"
        render = ["render", scene_path, "--spp", "1", "--width", "500", "--height", "500",
                  "-o", out]
        _process_seconds(render, 1)                  # fills the caches
        return {"help_s": _process_seconds(["--help"], repeats),
                "malformed_scene_s": _process_seconds(["render", bad, "-o", out],
                                                      MALFORMED_SCENE_RUNS, expect=2,
                                                      best=True),
                "malformed_scene_runs": MALFORMED_SCENE_RUNS,
                "render_warm_s": _process_seconds(render, repeats),
                "render_cold_s": _process_seconds(render, min(repeats, 3), fresh_caches=True),
                "repeats": repeats}


def against_povray(scene_path, repeats, ours_process_s) -> dict | None:
    """POV-Ray 3.7 and mimarble on the same kind of marble sphere (fig11a, 500², 1 sample):
    render against trace time, and whole process against whole process (warm caches)."""
    from mimarble.bench.calls import povray_row
    from mimarble.tools.povray import available
    scene = resized(scene_language.load(scene_path), 500)
    if not available():
        return None
    row = povray_row(scene, time_render(scene, 1, repeats).run_ms, repeats=3)
    return {**row, "ours_process_s": ours_process_s,
            "process_over_ours": row["process_s"] / ours_process_s}


def measure_targets(scene_path, repeats, cache_dir, step, tolerance=None) -> dict:
    """The issue's targets on fig11a at 500×500, the sphere filling the view (its marbles
    at ``tolerance``, None: the scene's default); ``step(label)`` after each of its 7
    steps."""
    base = with_marbles(filling_the_view(resized(scene_language.load(scene_path), 500)),
                        tolerance=tolerance)
    t = {}

    def run(scene, spp=1):
        return time_render(scene, spp, repeats)

    for mode in TARGET_MODES:
        t8 = run(with_marbles(base, octaves=8, filter=mode.filter)).run_ms
        t32 = run(with_marbles(base, octaves=32, filter=mode.filter)).run_ms
        step(f"targets: octaves 32 vs 8 ({mode.name})")
        t[f"octaves32_over_8_{mode.name}"] = {"t8_ms": t8, "t32_ms": t32, "ratio": t32 / t8}
    # What the error budget costs in colour at 32 octaves: the texture at its tolerance
    # against the float64 reference's full sum (mimarble.tools.stress.tolerance_error).
    marble32 = next(c for m in with_marbles(base, octaves=32).materials.values()
                    for c in m.channels().values()
                    if isinstance(c, scene_language.MarbleChannel))
    t["tolerance_error_32"] = stress.tolerance_error(marble32,
                                                     marble_tolerance(base, marble32, tolerance))

    marble8 = run(with_marbles(base, octaves=8))
    constant = run(with_constant_colours(base))
    step("targets: marble vs constant")
    t["marble8_over_constant"] = {"marble_ms": marble8.run_ms, "constant_ms": constant.run_ms,
                                  "ratio": marble8.run_ms / constant.run_ms}

    # Octave evaluations per second per core: the marginal cost of 24 octaves over
    # none, per evaluated octave (one texture evaluation per hit: the paper scenes'
    # ambient and diffuse marble is one shared texture).
    no_noise = run(with_marbles(base, octaves=0)).run_ms
    many = run(with_marbles(base, octaves=24, tolerance=0.0)).run_ms   # all 24 evaluated
    hits = hit_fraction(constant.image, base.image.background) * 500 * 500
    cores = os.cpu_count() or 1
    # On a busy machine the difference can vanish in the noise: then there is no rate.
    rate = hits * 24 / ((many - no_noise) / 1000) / cores if many > no_noise else None
    step("targets: octave evaluations per second")
    t["octave_evals_per_s_per_core"] = {"rate": rate, "hits": hits, "cores": cores,
                                        "t24_ms": many, "t0_ms": no_noise}

    # Time to RMSE ≤ 0.01 against the converged image, per mode.
    truth = converged(base, 64, cache_dir)
    step("targets: converged reference at 500x500")
    reach = {}
    for mode in TARGET_MODES:
        curve = []
        for spp in (1, 4, 9, 16, 25, 36, 64):
            timing = run(with_marbles(base, filter=mode.filter), spp)
            rmse = image_metrics(timing.image, truth)["rmse"]
            curve.append({"spp": spp, "run_ms": timing.run_ms, "rmse": rmse})
            if rmse <= 0.01:
                break
        first = next((c for c in curve if c["rmse"] <= 0.01), None)
        reach[mode.name] = {"curve": curve, "ms_to_rmse_0.01": first["run_ms"] if first else None}
        step(f"targets: time to RMSE 0.01 ({mode.name})")
    plain, limited = reach["plain"]["ms_to_rmse_0.01"], reach["bandlimit"]["ms_to_rmse_0.01"]
    t["rmse_0.01"] = {"by_mode": reach,
                      "speedup": plain / limited if plain and limited else None}
    return t
