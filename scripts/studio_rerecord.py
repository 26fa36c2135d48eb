"""What recording a kept structure's passes again costs the studio after a structural edit.

    ./go python scripts/studio_rerecord.py [--size 512] [--repeats 3]

On fig11a at ``--size``² (a StudioSession, refinement held off): the reduced frames of a
drag shown at stride 2 and 4 (the frame budget set so that each comes), then
``marble.octaves`` 12 → 9, a new structure; the render thread then records again the
passes of 12, the structure kept (mimarble/studio/worker.py, "Going back compiles
nothing"): its 1 spp pass, and since this change its reduced passes too. Printed: each
pass recorded again and its seconds (each traced once, its image dropped), against the
new structure's first frame; then, back at 12, whether a drag's reduced frame recorded
anything. ``--repeats``: 12 → 9 → 12, 12 → 10 → 12, … (each a new structure, a load
that makes 12's recordings stale); the figures are per pass, medians.

Prints the machine and ``uptime``'s load with the figures (the machine is shared).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import time
from collections import defaultdict

from mimarble.runtime.machine import machine_facts, machine_line
from mimarble.studio import StudioSession
from mimarble.studio import worker as worker_module


def timed(function, into: list):
    """``function`` timed into ``into`` (seconds a call), when the render thread is
    recording kept passes (``worker._record_kept`` on the stack)."""
    def wrapper(*args, **kwargs):
        start = time.perf_counter()
        result = function(*args, **kwargs)
        into.append(time.perf_counter() - start)
        return result
    return wrapper


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    from mimarble.mitsuba.rendering import passes
    session = StudioSession("fig11a", watch=False, idle_s=3600.0)
    worker = session._worker
    session.wait_frame(session.edits({"image.width": args.size, "image.height": args.size}),
                       timeout=600)
    spent = defaultdict(list)
    record_kept = worker._record_kept

    def record_kept_timed():
        saved = worker_module.trace_samples, worker_module._reduced
        worker_module.trace_samples = timed(saved[0], spent[1])
        worker_module._reduced = timed(saved[1], spent["reduced"])
        try:
            record_kept()
        finally:
            worker_module.trace_samples, worker_module._reduced = saved
    worker._record_kept = record_kept_timed

    period = 1.3
    def drag(budget: float) -> int:
        """A whole timed frame, then a drag's reduced frame under ``budget``: its stride."""
        nonlocal period
        period += 0.01
        session.wait_frame(session.edit("marble.period", period))
        worker.frame_budget_s = budget(worker.last_frame_s) if callable(budget) else budget
        period += 0.01
        session.edit("marble.period", period)
        period += 0.01
        stride = session.wait_frame(session.edit("marble.period", period)).stride
        worker.frame_budget_s = float("inf")
        time.sleep(0.2)
        return stride

    strides = [drag(lambda last: last / 2), drag(lambda last: last / 2), drag(0.0), drag(0.0)]
    first_frames, recorded_back = [], []
    for repeat in range(args.repeats):
        start = time.perf_counter()
        session.wait_frame(session.edit("marble.octaves", 9 + repeat), timeout=600)
        first_frames.append(time.perf_counter() - start)
        while not worker.resting.is_set():
            time.sleep(0.01)
        session.wait_frame(session.edit("marble.octaves", 12), timeout=600)
        while not worker.resting.is_set():
            time.sleep(0.01)
        recordings = passes.traced_pass.recordings
        drag(0.0)
        recorded_back.append(passes.traced_pass.recordings - recordings)
    session.close()
    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(machine_line(machine_facts()))
    print(f"load: {load}")
    print(f"fig11a at {args.size}², strides shown before the structural edit: {strides}")
    print(f"new structure's first frame (octaves 12 → 9, 10, …), median s: "
          f"{statistics.median(first_frames):.3f}")
    for key, times in spent.items():
        what = "1 spp pass" if key == 1 else "reduced pass"
        print(f"{what} recorded again: {len(times)} times, median {statistics.median(times):.4f} s, "
              f"total {sum(times):.3f} s")
    print(f"recordings made by a drag's reduced frame back at 12: {recorded_back}")


if __name__ == "__main__":
    main()
