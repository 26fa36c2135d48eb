"""Peak memory of a whole `mimarble render` against the issue-11 budget.

    ./go python scripts/peak_memory.py [--scene scenes/fig11a.scene] [--size 8192] [--spp 4]
                                       [--mode whitted|path] [--command render|reference]

Renders the scene at SIZE² and SPP in a child process (`python -m mimarble render … -o
OUT.png`) and reports the child's peak resident memory (ru_maxrss) beside the budget:
the 8-bit output + its float32 image + 1 GiB of working set (`reference`: its image is
float64, so the budget counts 8 bytes a channel).
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mimarble.contract import RENDER_MODES

ROOT = Path(__file__).resolve().parents[1]


def cpu_model() -> str:
    try:
        text = Path("/proc/cpuinfo").read_text()
        return re.search(r"model name\s*:\s*(.+)", text).group(1).strip()
    except (OSError, AttributeError):
        return platform.processor() or "unknown CPU"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=str(ROOT / "scenes" / "fig11a.scene"))
    parser.add_argument("--size", type=int, default=8192)
    parser.add_argument("--spp", type=int, default=4)
    parser.add_argument("--mode", choices=RENDER_MODES, default="whitted")
    parser.add_argument("--command", choices=("render", "reference"), default="render")
    args = parser.parse_args()
    text = Path(args.scene).read_text()
    text, count = re.subn(r"image\s*\{[^}]*\}", f"image {{ width {args.size} height {args.size} "
                          f"samples {args.spp} }}", text, count=1)
    if count != 1:
        sys.exit(f"{args.scene}: no image block to resize")
    with tempfile.TemporaryDirectory() as folder:
        scene = Path(folder) / "big.scene"
        scene.write_text(text)
        start = time.perf_counter()
        mode = ["--mode", args.mode] if args.command == "render" else []
        run = subprocess.run([sys.executable, "-m", "mimarble", args.command, str(scene), *mode,
                              "-o", str(Path(folder) / "big.png")], cwd=ROOT)
        seconds = time.perf_counter() - start
    if run.returncode:
        return run.returncode
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024   # KiB on Linux
    pixels = args.size * args.size
    channel = 4 if args.command == "render" else 8          # float32 / the reference's float64
    budget = pixels * 3 + pixels * 3 * channel + (1 << 30)
    gib = 1 << 30
    what = f"{args.command} ({args.mode})" if args.command == "render" else args.command
    print(f"{what} {Path(args.scene).name} {args.size}x{args.size}, {args.spp} spp on {cpu_model()} "
          f"({os.cpu_count()} cores): peak RSS {peak / gib:.2f} GiB, budget {budget / gib:.2f} GiB "
          f"(8-bit {pixels * 3 / gib:.2f} + float{8 * channel} {pixels * 3 * channel / gib:.2f} + 1), "
          f"{'within' if peak <= budget else 'OVER'}; {seconds:.1f} s")
    return 0 if peak <= budget else 1


if __name__ == "__main__":
    sys.exit(main())
