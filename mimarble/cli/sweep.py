"""``mimarble sweep``: the options checked, then mimarble/sweeps/run.py's ``sweep``."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from mimarble.cli.shared import (UsageError, check_spp, checked_name, load_scene, say,
    start_mitsuba)


def _sweep(args) -> int:
    from mimarble.sweeps.cluster import check_workers
    from mimarble.sweeps.frames import frames
    from mimarble.sweeps.settings import SweepError, settings_from
    if args.keys:                                   # the scene's keys, and no sweep
        from mimarble.scene.keys import keys_listing
        for line in keys_listing(load_scene(args)).splitlines():
            say(line)                              # names from the file, shown escaped
        return 0
    if not args.set:
        raise UsageError("a sweep needs at least one --set KEY=VALUES")
    if args.output is None:
        raise UsageError("a sweep needs -o FOLDER (its images, sweep.json and contact.png)")
    out = Path(checked_name(args.output, "-o"))
    try:
        if out.exists() and not out.is_dir():
            raise UsageError(f"-o {out}: exists and is not a folder")
        if not out.parent.is_dir():
            raise UsageError(f"-o {out}: the folder it would go in, {out.parent}, does not exist")
    except OSError as e:          # a name longer than the file system takes, a loop of links
        raise UsageError(f"-o {out}: {e.strerror or e}") from None
    scene = load_scene(args)
    try:
        if args.workers is not None:
            check_workers(args.workers)             # at most a few per core
        settings = settings_from(args.set)
        frames(scene, settings)                     # their number, then every key and value
    except SweepError as e:
        raise UsageError(str(e)) from None
    if args.spp is not None:
        check_spp(args.spp)
    start_mitsuba(args)
    from mimarble.sweeps.index import summary_sentence
    from mimarble.sweeps.run import sweep
    start = time.perf_counter()
    try:
        index = sweep(scene, settings, out, spp=args.spp, workers=args.workers,
                      scheduler=args.scheduler, compare=args.compare, progress=True)
    except SweepError as e:
        raise UsageError(str(e)) from None
    failed = [f for f in index["frames"] if f["status"] != "done"]
    # "16 frames: 14 already done, 2 rendered now, 0 failed": what this run did.
    say(f"{out}: {summary_sentence(index)} ({time.perf_counter() - start:.1f} s); "
          f"index {out / 'sweep.json'}"
          + ("" if failed else f", contact sheet {out / 'contact.png'}"))
    for f in failed:
        say(f"  frame {f['index']} {f['values']}: {f['error']}", file=sys.stderr)
    return 1 if failed else 0
