"""The paper's scenes, a sweep and translucent marble timed on a CUDA GPU, into OUT_DIR.

    python3 scripts/gpu_timing.py OUT_DIR [--budget 100] [--size 512]

Run by the GPU check (`.device/check.sh`, ../shared/device/README.md) in the
``cuda_ad_rgb`` variant (``$MIMARBLE_VARIANT``; any variant runs it). Each figure is a
median of warm renders after a sync (Dr.Jit's launches are asynchronous); a scene's first
render is timed apart, its compile time read from ``dr.kernel_history``. Against the float64
reference tracer at a small size, as ``mimarble compare`` measures it (PSNR). Results are
written to ``OUT_DIR/gpu-timing.json`` after every item, so a run cut short by the
budget or a timeout keeps what it measured; a Markdown table is printed at the end.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import mimarble  # noqa: E402
from mimarble.scene.edits import resized  # noqa: E402

REPEATS = 5                       # warm renders per figure (the median is quoted)
COMPARED = ("fig10a", "fig11a", "fig07a")   # against the reference tracer, at COMPARE_SIZE
COMPARE_SIZE = 64
SWEEP_FRAMES = 24
SPPS = (1, 16, 256)
#: Also timed in llvm_ad_rgb on the same machine's CPU, for the ratio (as cpu_timing.py).
ON_THE_CPU_TOO = ("fig10a", "fig10d", "fig11a", "fig11b")


def gpu_name() -> str:
    try:
        run = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version",
                              "--format=csv,noheader"], capture_output=True, text=True,
                             timeout=20)
        return run.stdout.strip() or "unknown GPU"
    except (OSError, subprocess.SubprocessError):
        return "no nvidia-smi"


class Clock:
    """Wall time of Dr.Jit work, the device synchronised at both ends; the kernels'
    compile (codegen + backend) time from ``dr.kernel_history`` over the same span."""

    def __init__(self, dr):
        self.dr = dr

    def once(self, f) -> tuple[float, float]:
        dr = self.dr
        dr.sync_thread()
        dr.kernel_history_clear()
        start = time.perf_counter()
        f()
        dr.sync_thread()
        seconds = time.perf_counter() - start
        compile_ms = sum(k.get("codegen_time", 0.0) + k.get("backend_time", 0.0)
                         for k in dr.kernel_history() if "codegen_time" in k)
        return seconds, compile_ms / 1000

    def median(self, f, repeats: int = REPEATS) -> float:
        times = sorted(self.once(f)[0] for _ in range(repeats))
        return times[len(times) // 2]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--budget", type=float, default=100.0,
                        help="seconds; items not started by then are skipped (default 100)")
    parser.add_argument("--size", type=int, default=512, help="image side in pixels (512)")
    args = parser.parse_args()
    began = time.monotonic()
    args.out_dir.mkdir(parents=True, exist_ok=True)
    mimarble.start()
    dr, mi = mimarble.dr, mimarble.mi
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    clock = Clock(dr)
    results = {"gpu": gpu_name(), "variant": mi.variant(), "size": args.size,
               "mitsuba": mi.__version__, "drjit": dr.__version__,
               "scenes": {}, "compare": {}, "sweep": None, "translucent": {}, "cpu": {},
               "cpu_threads": dr.thread_count(), "skipped": []}
    out_json = args.out_dir / "gpu-timing.json"

    def save():
        out_json.write_text(json.dumps(results, indent=1))

    def time_left(item: str) -> bool:
        if time.monotonic() - began < args.budget:
            return True
        results["skipped"].append(item)
        return False

    save()
    paper = sorted(p.stem for p in (ROOT / "scenes").glob("fig*.scene"))
    # 1. Every paper scene, whitted, at 1 and 16 spp: cold (compile) and warm.
    for name in paper:
        if not time_left(name):
            continue
        model = resized(mimarble.scene.load(ROOT / "scenes" / f"{name}.scene"), args.size)
        row = {}
        try:
            scene = mi.load_dict(mimarble.to_mitsuba(model, spp=1))
            first, compile_s = clock.once(lambda: mimarble.render(scene, spp=1))
            row["first_s"], row["compile_s"] = first, compile_s
            for spp in SPPS:
                row[f"warm_{spp}spp_ms"] = 1000 * clock.median(
                    lambda: mimarble.render(scene, spp=spp))
            if name == "fig11a":
                mimarble.write_image(str(args.out_dir / "fig11a-cuda-16spp.png"),
                                     mimarble.render(scene, spp=16))
        except Exception as error:          # a failure is a result here, said and kept
            row["error"] = f"{type(error).__name__}: {error}"
        results["scenes"][name] = row
        save()
    # 2. Against the float64 reference (PSNR), as `mimarble compare`.
    from mimarble.tools.compare import compare_with_reference
    for name in COMPARED:
        if not time_left(f"compare {name}"):
            continue
        model = resized(mimarble.scene.load(ROOT / "scenes" / f"{name}.scene"), COMPARE_SIZE)
        try:
            metrics, _, _ = compare_with_reference(model, spp=1, name=name)
            results["compare"][name] = {k: metrics[k] for k in ("psnr", "rmse", "variant")}
        except Exception as error:
            results["compare"][name] = {"error": f"{type(error).__name__}: {error}"}
        save()
    # 3. A sweep of fig11a's period, in this process.
    if time_left("sweep"):
        with tempfile.TemporaryDirectory() as folder:
            try:
                start = time.perf_counter()
                model = resized(mimarble.scene.load(ROOT / "scenes" / "fig11a.scene"), 256)
                index = mimarble.sweep(model, [f"marble.period=0.5:4:{SWEEP_FRAMES}"],
                                       Path(folder) / "sweep", spp=4, contact_sheet=False)
                seconds = time.perf_counter() - start
                done = sum(f["status"] == "done" for f in index["frames"])
                results["sweep"] = {"frames": done, "seconds": seconds,
                                    "frames_per_s": done / seconds, "size": 256, "spp": 4}
            except Exception as error:
                results["sweep"] = {"error": f"{type(error).__name__}: {error}"}
        save()
    # 4. Translucent marble, path mode (the random walk).
    for name, spp in (("fig11a-translucent", 16), ("carrara", 16)):
        if not time_left(name):
            continue
        try:
            model = resized(mimarble.scene.load(ROOT / "scenes" / "translucent" /
                                                f"{name}.scene"), args.size)
            scene = mi.load_dict(mimarble.to_mitsuba(model, mode="path", spp=spp))
            first, compile_s = clock.once(lambda: mimarble.render(scene, spp=spp))
            warm = clock.median(lambda: mimarble.render(scene, spp=spp), repeats=3)
            results["translucent"][name] = {"spp": spp, "first_s": first,
                                            "compile_s": compile_s, "warm_s": warm}
            mimarble.write_image(str(args.out_dir / f"{name}-cuda.png"),
                                 mimarble.render(scene, spp=spp))
        except Exception as error:
            results["translucent"][name] = {"error": f"{type(error).__name__}: {error}"}
        save()
    # 5. The same machine's CPU (llvm_ad_rgb), where it can render.
    gpu_variant = mi.variant()
    try:
        mi.set_variant("llvm_ad_rgb")
        for name in ON_THE_CPU_TOO:
            if not time_left(f"cpu {name}"):
                continue
            model = resized(mimarble.scene.load(ROOT / "scenes" / f"{name}.scene"), args.size)
            scene = mi.load_dict(mimarble.to_mitsuba(model, spp=1))
            mimarble.render(scene, spp=1)
            results["cpu"][name] = {f"warm_{spp}spp_ms": 1000 * clock.median(
                lambda: mimarble.render(scene, spp=spp), repeats=3) for spp in (1, 16)}
            save()
    except Exception as error:
        results["cpu"]["error"] = f"{type(error).__name__}: {error}"
    finally:
        mi.set_variant(gpu_variant)
    save()
    print(f"{results['gpu']} · {results['variant']} · Mitsuba {results['mitsuba']}, "
          f"Dr.Jit {results['drjit']} · {args.size}²\n")
    print("| scene | first render s (compile s) | warm 1 spp ms | warm 16 spp ms | warm 256 spp ms |\n"
          "|---|---|---|---|---|")
    for name, row in results["scenes"].items():
        if "error" in row:
            print(f"| {name} | {row['error'][:80]} | | |")
            continue
        print(f"| {name} | {row['first_s']:.2f} ({row['compile_s']:.2f}) | "
              f"{row['warm_1spp_ms']:.2f} | {row['warm_16spp_ms']:.2f} | "
              f"{row['warm_256spp_ms']:.2f} |")
    for key in ("compare", "translucent", "cpu"):
        for name, row in results[key].items():
            print(f"{key} {name}: {row}")
    print(f"sweep: {results['sweep']}\nCPU threads: {results['cpu_threads']}")
    print(f"skipped (budget): {results['skipped']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
