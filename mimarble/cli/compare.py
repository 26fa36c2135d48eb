"""``mimarble compare``: Mitsuba (whitted) against the reference tracer, printed."""

from __future__ import annotations

import sys
from pathlib import Path

from mimarble.cli.shared import (adaptive_words, check_adaptive_options, check_folder, check_suffix,
                                 checked_name, load_scene, chosen_max_spp, say, chosen_spp,
                                 start_mitsuba, write_output)
from mimarble.runtime.extras import require_extra


def _compare(args) -> int:
    import json

    check_adaptive_options(args)
    if args.diff is not None:
        check_folder(check_suffix(Path(checked_name(args.diff, "--diff")), (".png",),
                                    "error map"))
        require_extra("compare --diff")
    scene = load_scene(args)
    spp = chosen_spp(args, scene)
    start_mitsuba(args)
    from mimarble.tools.compare import (compare_with_reference, error_map_scale,
                                        error_map_with_legend, reference_differs)
    if reference_differs(scene, args.filter, args.edge_spp, args.adaptive):
        print("mimarble: note: the reference tracer renders plain supersampling (the ground "
              "truth): filtered marble, edge samples or adaptive sampling differ from it by "
              "what they filter or sample otherwise", file=sys.stderr)
    metrics, ours, ref = compare_with_reference(
        scene, spp, tolerance=args.tolerance, filter=args.filter, edge_spp=args.edge_spp,
        adaptive=args.adaptive, max_spp=None if args.adaptive is None else chosen_max_spp(args, spp),
        name=args.scene, progress=True)
    if args.diff is not None:
        write_output(Path(args.diff), error_map_with_legend(ours, ref), eight_bit=True)
    reference_spp = metrics.get("reference_spp", spp)
    against = "" if reference_spp == spp else f" at {reference_spp} spp"
    say(f"{args.scene}: {scene.image.width}x{scene.image.height}, {spp} spp"
          f"{adaptive_words(args, spp)}, whitted ({metrics['variant']}) vs reference "
          f"(float64){against}")
    print(f"  RMSE {metrics['rmse']:.3g}   PSNR {metrics['psnr']:.2f} dB   max |error| "
          f"{metrics['max_abs']:.3g}   pixels off by > 1/255: {100 * metrics['frac_over_1_255']:.3f} %")
    print(f"  time: Mitsuba {metrics['mitsuba_seconds']:.2f} s, reference "
          f"{metrics['reference_seconds']:.2f} s")
    if args.diff is not None:
        say(f"  error map {args.diff} (legend under it): {error_map_scale()}")
    if args.json:
        print(json.dumps(metrics))
    return 0
