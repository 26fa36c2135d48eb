"""The studio engine's latency (issue 41's targets, the engine's side; no browser).

    ./go python scripts/studio_latency.py [--size 512] [--edits 60] [--pause 1.0]
        [--structure-only] [--json OUT]

On fig11a at ``--size``² (a StudioSession, as the page uses it):

1. **edit → frame**: ``edit("marble.period", …)`` called, then the time until the frame of
   that version is handed to a listener (rendered at 1 spp and encoded), each edit after
   the last one's frame, refinement held off; median and 95th percentile, for JPEG
   frames (what the studio sends while a frame is not final) and PNG. The page adds the
   transport and the browser's decode (the page branch measures that, in the browser).
2. **refinement**: the time from an edit's first (1 spp) frame to its final frame at the
   scene's spp (4) and at 16 spp, refinement starting at once (``idle_s`` 0), against
   ``mimarble.render`` of the same scene and spp in this process, warm, alone and with
   its PNG encoded (what ``mimarble render`` does past its start-up); medians of 5.
   Target ≤ 1.5×. Also the edit's time to its final frame.
3. **structure**: ``marble.octaves`` 8 → 9 → 8 → 9 (tolerance 0, so that 9 is a new
   kernel; 8 → 9 a new structure, loaded and compiled with an empty kernel cache:
   ``DRJIT_CACHE_DIR`` is set to a new folder before Dr.Jit loads; back to 8, loaded
   before, its pass recorded again behind 9's frame; then 9 again: nothing new), each
   edit ``--pause`` seconds after the last one's frame (as a user looks at it) — each
   edit's time for ``edit`` to return, to its frame, whether ``compiling`` was said and
   how many recordings were made from the edit to its frame.

Prints the machine and ``uptime``'s load with the figures (the machine is shared: quote
them with it).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import tempfile
import threading
import time

os.environ["DRJIT_CACHE_DIR"] = tempfile.mkdtemp(prefix="studio-latency-cache-")

import numpy as np  # noqa: E402

import mimarble  # noqa: E402
from mimarble.runtime.files import write_json  # noqa: E402
from mimarble.runtime.machine import machine_facts, machine_line  # noqa: E402
from mimarble.studio import StudioSession  # noqa: E402
from mimarble.studio.frames import encode  # noqa: E402


class Clock:
    """When each version's first frame (and its final frame) reached a listener."""

    def __init__(self, session):
        self.first, self.final, self.compiling = {}, {}, set()
        self.event = threading.Condition()
        session.subscribe(self)

    def __call__(self, kind, payload):
        now = time.perf_counter()
        with self.event:
            if kind == "frame":
                self.first.setdefault(payload.version, now)
                if payload.final:
                    self.final.setdefault(payload.version, now)
            elif kind == "state" and payload["compiling"]:
                self.compiling.add(payload["version"])
            self.event.notify_all()

    def wait(self, version, final=False, timeout=600.0):
        table = self.final if final else self.first
        with self.event:
            if not self.event.wait_for(lambda: version in table, timeout):
                raise TimeoutError(f"no frame of version {version}")
            return table[version]


def percentile(values, q):
    return float(np.percentile(np.asarray(values), q))


def edit_latency(size: int, edits: int, fmt: str) -> dict:
    session = StudioSession("fig11a", frame_format=fmt, watch=False, idle_s=3600.0)
    clock = Clock(session)
    session.edits({"image.width": size, "image.height": size})
    session.wait_frame(timeout=600)
    times, render_ms, encode_ms = [], [], []
    for k in range(edits + 5):
        start = time.perf_counter()
        version = session.edit("marble.period", 1.2 + 0.01 * (k % 20))
        seen = clock.wait(version)
        frame = session.wait_frame(version)
        if k >= 5:                                      # the first few: warming up
            times.append((seen - start) * 1e3)
            render_ms.append(frame.render_ms)
            encode_ms.append(frame.encode_ms)
    session.close()
    return {"format": fmt, "median_ms": statistics.median(times),
            "p95_ms": percentile(times, 95), "render_median_ms": statistics.median(render_ms),
            "encode_median_ms": statistics.median(encode_ms), "edits": edits}


def refinement(size: int, spp: int) -> dict:
    session = StudioSession("fig11a", watch=False, idle_s=0.0)
    clock = Clock(session)
    session.edits({"image.width": size, "image.height": size, "image.samples": spp})
    session.wait_frame(final=True, timeout=600)
    totals, refinements = [], []
    for k in range(5):
        start = time.perf_counter()
        version = session.edit("marble.period", 1.25 + 0.01 * k)
        final = clock.wait(version, final=True)
        totals.append(final - start)
        refinements.append(final - clock.wait(version))
    scene = session.scene
    session.close()
    mimarble.render(scene, spp=spp)                    # warm
    renders, written = [], []
    for _ in range(5):
        start = time.perf_counter()
        image = mimarble.render(scene, spp=spp)
        renders.append(time.perf_counter() - start)
        encode(image, "png")                           # what `mimarble render` writes
        written.append(time.perf_counter() - start)
    refinement_s, render_s = statistics.median(refinements), statistics.median(renders)
    written_s = statistics.median(written)
    return {"spp": spp, "edit_to_final_s": statistics.median(totals),
            "refinement_s": refinement_s, "render_s": render_s,
            "render_and_png_s": written_s, "ratio_to_render": refinement_s / render_s,
            "ratio_to_render_and_png": refinement_s / written_s}


def structure(size: int, pause: float) -> dict:
    from mimarble.mitsuba.rendering import passes
    session = StudioSession("fig11a", watch=False, idle_s=3600.0)
    clock = Clock(session)
    # Tolerance 0: every octave evaluated (at the default error budget octaves 8 and 9 of
    # fig11a evaluate the same octaves: one kernel), so that 8 → 9 is a new kernel.
    version = session.edits({"image.width": size, "image.height": size, "marble.octaves": 8,
                             "marble.tolerance": 0.0})
    session.wait_frame(version, timeout=600)
    out = {}
    for octaves in (9, 8, 9):
        time.sleep(pause)
        recordings = passes.traced_pass.recordings
        start = time.perf_counter()
        version = session.edit("marble.octaves", octaves)
        returned = time.perf_counter() - start
        seen = clock.wait(version)
        out[f"{len(out) + 1}: octaves to {octaves}"] = {"edit_returned_ms": returned * 1e3,
                                "frame_s": seen - start,
                                "compiling_said": version in clock.compiling,
                                "recordings": passes.traced_pass.recordings - recordings}
    session.close()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--edits", type=int, default=60)
    parser.add_argument("--pause", type=float, default=1.0,
                        help="seconds between a structural edit's frame and the next edit")
    parser.add_argument("--structure-only", action="store_true")
    parser.add_argument("--json")
    args = parser.parse_args()
    results = {"machine": machine_line(machine_facts()),
               "load": subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()}
    results["structure"] = structure(args.size, args.pause)   # first: the cache is empty
    if args.structure_only:
        print(json.dumps(results, indent=2))
        return
    results["edit_to_frame"] = [edit_latency(args.size, args.edits, fmt)
                                for fmt in ("jpeg", "png")]
    results["refinement"] = [refinement(args.size, spp) for spp in (4, 16)]
    results["load_after"] = subprocess.run(["uptime"], capture_output=True,
                                           text=True).stdout.strip()
    print(json.dumps(results, indent=2))
    if args.json:
        write_json(results, args.json)


if __name__ == "__main__":
    main()
