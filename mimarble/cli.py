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


def _write(out: Path, image) -> None:
    from .mitsuba import write_image
    try:
        write_image(out, image)
    except (OSError, RuntimeError) as e:
        raise UsageError(f"{out}: could not write the image: {e}") from None


def _render(args) -> int:
    import mimarble
    out = _output_path(args)
    scene = mimarble.scene.load(args.scene)
    spp = _spp(args, scene)
    start = time.perf_counter()
    image = mimarble.render(scene, spp=spp, mode=args.mode)
    seconds = time.perf_counter() - start
    _write(out, image)
    print(f"{out}: {scene.image.width}x{scene.image.height}, {spp} spp, {args.mode} mode, "
          f"{mimarble.mi.variant()}, {seconds:.2f} s")
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
