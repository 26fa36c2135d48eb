"""The ``mimarble`` command line.

Exit status: 0 success, 1 the environment cannot render (``doctor``), 2 a user
error (bad scene, bad argument, unusable variant). User errors print one
message and no traceback.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path


def _doctor(args) -> int:
    from . import environment
    rows, ok = environment.doctor(args.variant)
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"{key:<{width}}  {value}")
    print("rendering can work" if ok else
          "rendering cannot work here, or only in the slow scalar variant: see above")
    return 0 if ok else 1


class UsageError(Exception):
    """A user mistake on the command line (exit status 2)."""


def _output_path(args, default_suffix=".png") -> Path:
    from .mitsuba.render import IMAGE_FORMATS
    out = Path(args.output) if args.output else Path(Path(args.scene).stem + default_suffix)
    if out.suffix.lower() not in IMAGE_FORMATS:
        raise UsageError(f"{out}: unsupported image format {out.suffix or '(none)'!r}; "
                         f"use {' or '.join(IMAGE_FORMATS)}")
    if not (out.parent if str(out.parent) else Path(".")).is_dir():
        raise UsageError(f"{out}: folder {out.parent} does not exist")
    return out


def _spp(args, scene) -> int:
    spp = scene.image.samples if args.spp is None else args.spp
    if spp < 1:
        raise UsageError(f"--spp {spp}: must be at least 1")
    if getattr(args, "mode", "whitted") == "whitted" and math.isqrt(spp) ** 2 != spp:
        raise UsageError(f"--spp {spp}: whitted mode samples an n×n grid, so spp must be a "
                         f"perfect square (1, 4, 9, 16, …)")
    return spp


def _write(out: Path, image, eight_bit: bool = False) -> None:
    from .mitsuba.render import write_image, write_rgb8
    if not (out.parent if str(out.parent) else Path(".")).is_dir():
        raise UsageError(f"{out}: folder {out.parent} does not exist")
    try:
        (write_rgb8 if eight_bit else write_image)(out, image)
    except (OSError, RuntimeError) as e:
        raise UsageError(f"{out}: could not write the image: {e}") from None


def _render_to_file(args, renderer, description: str) -> int:
    """Load, check arguments, render, write whole, report: shared by render and reference."""
    import mimarble
    out = _output_path(args)
    scene = mimarble.scene.load(args.scene)
    spp = _spp(args, scene)
    start = time.perf_counter()
    image = renderer(scene, spp)
    seconds = time.perf_counter() - start
    _write(out, image)
    print(f"{out}: {scene.image.width}x{scene.image.height}, {spp} spp, {description}, "
          f"{seconds:.2f} s")
    return 0


def _render(args) -> int:
    import mimarble
    return _render_to_file(args, lambda scene, spp: mimarble.render(scene, spp=spp, mode=args.mode),
                           f"{args.mode} mode, {mimarble.mi.variant()}")


def _reference(args) -> int:
    from . import reference
    return _render_to_file(args, lambda scene, spp: reference.render(scene, spp=spp),
                           "reference tracer (NumPy float64)")


def _compare(args) -> int:
    import json

    import mimarble
    from . import reference
    from .compare import error_map, image_metrics
    if args.diff and Path(args.diff).suffix.lower() != ".png":
        raise UsageError(f"--diff {args.diff}: the error map is written as .png")
    scene = mimarble.scene.load(args.scene)
    spp = _spp(args, scene)
    start = time.perf_counter()
    ours = mimarble.render(scene, spp=spp)
    mitsuba_seconds = time.perf_counter() - start
    start = time.perf_counter()
    ref = reference.render(scene, spp=spp)
    reference_seconds = time.perf_counter() - start
    metrics = image_metrics(ours, ref)
    metrics.update(scene=str(args.scene), spp=spp, variant=mimarble.mi.variant(),
                   mitsuba_seconds=mitsuba_seconds, reference_seconds=reference_seconds)
    if args.diff:
        _write(Path(args.diff), error_map(ours, ref), eight_bit=True)
    print(f"{args.scene}: {scene.image.width}x{scene.image.height}, {spp} spp, whitted "
          f"({mimarble.mi.variant()}) vs reference (float64)")
    print(f"  RMSE {metrics['rmse']:.3g}   PSNR {metrics['psnr']:.2f} dB   max |error| "
          f"{metrics['max_abs']:.3g}   pixels off by > 1/255: {100 * metrics['frac_over_1_255']:.3f} %")
    print(f"  time: Mitsuba {mitsuba_seconds:.2f} s, reference {reference_seconds:.2f} s")
    if args.json:
        print(json.dumps(metrics))
    return 0


def _bench(args) -> int:
    from . import bench
    scenes = args.scenes or sorted(str(p) for p in Path("scenes").glob("*.scene"))
    if not scenes:
        raise UsageError("no scenes given and none in ./scenes")
    for path in (args.json, args.plot):
        if path and not (Path(path).parent if str(Path(path).parent) else Path(".")).is_dir():
            raise UsageError(f"{path}: folder {Path(path).parent} does not exist")
    results = bench.run_bench(scenes, size=args.size, spps=tuple(args.spp), repeats=args.repeats,
                              converged_spp=args.converged_spp, targets=not args.no_targets,
                              paper=not args.no_paper)
    print(bench.format_report(results))
    if args.json:
        bench.write_json(results, args.json)
    if args.plot:
        bench.plot(results, args.plot)
    return 0


def _stress(args) -> int:
    import json

    from .stress import format_report, run_stress
    if args.points < 1:
        raise UsageError(f"--points {args.points}: must be at least 1")
    data = run_stress(points=args.points)
    print(format_report(data))
    if args.json:
        out = Path(args.json)
        if not (out.parent if str(out.parent) else Path(".")).is_dir():
            raise UsageError(f"{out}: folder {out.parent} does not exist")
        out.write_text(json.dumps(data, indent=1))
    return 0


def _gallery(args) -> int:
    from .gallery import make_gallery
    scenes = args.scenes or sorted(str(p) for p in Path("scenes").glob("*.scene"))
    if not scenes:
        raise UsageError("no scenes given and none in ./scenes")
    for out, seconds in make_gallery(scenes, args.output, args.size, args.mode):
        print(f"{out} ({seconds:.2f} s)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mimarble",
        description="The marble solid texture of Park & Park (2004) for Mitsuba 3.")
    parser.add_argument("--variant", help="Mitsuba variant (default: $MIMARBLE_VARIANT, "
                                          "else cuda_ad_rgb, llvm_ad_rgb, scalar_rgb)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("render", help="render a scene file through Mitsuba")
    p.add_argument("scene", help="scene file (see docs/scene-language.md)")
    p.add_argument("-o", "--output", help="OUT.png (8-bit sRGB) or OUT.exr (linear float); "
                                          "default: the scene's name with .png, here")
    p.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    p.add_argument("--mode", choices=("whitted", "path"), default="whitted",
                   help="whitted: the paper's shading (default); path: physically based")
    p.set_defaults(run=_render)

    p = sub.add_parser("reference", help="render a scene with the float64 reference tracer")
    p.add_argument("scene", help="scene file")
    p.add_argument("-o", "--output", help="OUT.png or OUT.exr (default: the scene's name with .png)")
    p.add_argument("--spp", type=int, help="samples per pixel, a perfect square (default: the scene's)")
    p.set_defaults(run=_reference, mode="whitted")

    p = sub.add_parser("compare", help="Mitsuba (whitted) against the reference tracer")
    p.add_argument("scene", help="scene file")
    p.add_argument("--spp", type=int, help="samples per pixel, a perfect square (default: the scene's)")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON on the last line")
    p.add_argument("--diff", metavar="OUT.png", help="write a false-colour error map")
    p.set_defaults(run=_compare, mode="whitted")

    p = sub.add_parser("bench", help="run time against error against the converged reference")
    p.add_argument("scenes", nargs="*", help="scene files (default: scenes/*.scene)")
    p.add_argument("--json", metavar="OUT", help="write all measurements as JSON")
    p.add_argument("--plot", metavar="OUT.png", help="write the error-against-time plot")
    p.add_argument("--size", type=int, default=256, help="image size for the sweeps (default 256)")
    p.add_argument("--spp", type=int, nargs="+", default=[1, 4, 16], help="spp values swept")
    p.add_argument("--repeats", type=int, default=5, help="warm runs per timing (median)")
    p.add_argument("--converged-spp", type=int, default=64, help="reference spp (default 64)")
    p.add_argument("--no-targets", action="store_true", help="skip the issue's target measurements")
    p.add_argument("--no-paper", action="store_true", help="skip the comparison with the paper")
    p.set_defaults(run=_bench)

    p = sub.add_parser("stress", help="float32 error of noise and marble against float64, "
                                      "beside the derived bound")
    p.add_argument("--points", type=int, default=2048, help="random points per table cell")
    p.add_argument("--json", metavar="OUT", help="write the measurements as JSON")
    p.set_defaults(run=_stress)

    p = sub.add_parser("gallery", help="render scenes small for the README gallery")
    p.add_argument("scenes", nargs="*", help="scene files (default: scenes/*.scene)")
    p.add_argument("-o", "--output", default="docs/gallery", help="folder (default: docs/gallery)")
    p.add_argument("--size", type=int, default=160, help="image width and height (default: 160)")
    p.add_argument("--mode", choices=("whitted", "path"), default="whitted")
    p.set_defaults(run=_gallery)

    p = sub.add_parser("doctor", help="show the libLLVM, variant and versions in use")
    p.set_defaults(run=_doctor, needs_variant=False)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    # The package import chose the libLLVM before Dr.Jit loaded; it never raises.
    import mimarble
    from .environment import EnvironmentProblem
    try:
        if getattr(args, "needs_variant", True):
            mimarble.use_variant(args.variant)
        return args.run(args)
    except (EnvironmentProblem, UsageError) as e:
        print(f"mimarble: {e}", file=sys.stderr)
        return 2
    except mimarble.scene.SceneError as e:
        print(e, file=sys.stderr)
        return e.exit_status
    except KeyboardInterrupt:
        print("mimarble: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
