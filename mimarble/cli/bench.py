"""The measuring commands: ``mimarble bench`` (run time against error) and
``mimarble stress`` (float32 error against float64)."""

from __future__ import annotations

import shlex
from pathlib import Path

from mimarble.cli.shared import (UsageError, check_folder, check_spp, check_suffix,
    checked_name, say, scene_list, start_mitsuba)
from mimarble.runtime.extras import require_extra


def _bench(args) -> int:
    from mimarble import scene as mimarble_scene
    from mimarble.scene import LIMITS
    scenes = scene_list(args.scenes)
    if not args.scenes:     # the paper's figures, then the fine veins beside them (issue 24)
        scenes += sorted(str(p) for p in (Path(scenes[0]).parent / "fine-veins").glob("*.scene"))
    lo, hi = LIMITS["image_size"]
    if not lo <= args.size <= hi:
        raise UsageError(f"--size {args.size}: must be in {lo}..{hi}")
    for spp in args.spp:
        check_spp(spp)
    check_spp(args.converged_spp, option="--converged-spp")
    check_spp(args.max_spp, option="--max-spp")
    for threshold in args.adaptive or ():
        if not 0 < threshold < float("inf"):
            raise UsageError(f"--adaptive {threshold}: a threshold must be a finite number > 0")
    if args.adaptive and args.no_adaptive:
        raise UsageError("--adaptive gives the adaptive modes' thresholds; --no-adaptive "
                         "skips those modes: give one of them")
    if args.repeats < 1:
        raise UsageError(f"--repeats {args.repeats}: must be at least 1")
    if args.json is not None:
        check_folder(checked_name(args.json, "--json"))
    if args.plot is not None:
        check_folder(check_suffix(Path(checked_name(args.plot, "--plot")),
                                    (".png", ".pdf", ".svg"), "plot"))
        require_extra("bench --plot")
    if args.page is not None:
        check_folder(check_suffix(Path(checked_name(args.page, "--page")), (".md",), "page"))
    for path in scenes:
        mimarble_scene.load(path)   # every scene error before minutes of measuring
    start_mitsuba(args)
    from mimarble.bench.modes import ADAPTIVE_THRESHOLDS, modes
    from mimarble.bench.run import run_bench
    from mimarble.bench.targets import targets_scene
    targets = None if args.no_targets else targets_scene(scenes)
    if not args.no_targets and targets is None:
        raise UsageError("the targets are measured on scenes/fig11a.scene, which is not here; "
                         "give it among the scenes or pass --no-targets")
    results = run_bench(scenes, size=args.size, spps=tuple(args.spp), repeats=args.repeats,
                        converged_spp=args.converged_spp, targets=targets,
                        paper=not args.no_paper, povray=not args.no_povray,
                        tolerance=args.tolerance,
                        modes=modes(args.filter, args.edge_spp, adaptive=not args.no_adaptive),
                        thresholds=tuple(args.adaptive or ADAPTIVE_THRESHOLDS),
                        max_spp=args.max_spp)
    from mimarble.bench.report import format_report
    from mimarble.runtime.files import write_json
    results["command"] = "mimarble " + " ".join(shlex.quote(a) for a in args.argv)
    print(format_report(results))
    try:
        if args.json:
            write_json(results, args.json)
        if args.plot:
            from mimarble.bench.plot import plot_error_against_time
            plot_error_against_time(results, args.plot)
        if args.page:
            from mimarble.bench.page import plot_relative_to, write_section
            slug = write_section(args.page, results, plot_relative_to(args.page, args.plot))
            say(f"wrote the section of this machine ({slug}) into {args.page}")
    except OSError as e:
        raise UsageError(f"could not write the results: {e}") from None
    return 0


def _stress(args) -> int:
    if args.points < 1:
        raise UsageError(f"--points {args.points}: must be at least 1")
    if args.json is not None:
        check_folder(checked_name(args.json, "--json"))
    start_mitsuba(args)
    from mimarble.runtime.files import write_json
    from mimarble.tools.stress import format_report, run_stress
    data = run_stress(points=args.points)
    print(format_report(data))
    if args.json:
        try:
            write_json(data, args.json)
        except OSError as e:
            raise UsageError(f"{args.json}: could not write: {e}") from None
    return 0
