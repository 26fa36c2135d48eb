"""The ``mimarble`` command line.

Exit status: 0 success, 1 the environment cannot render (``doctor``), 2 a user
error (bad scene, bad argument, unusable variant). User errors print one
message and no traceback.
"""

from __future__ import annotations

import argparse
import sys


def _doctor(args) -> int:
    from . import environment
    rows, ok = environment.doctor(args.variant)
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"{key:<{width}}  {value}")
    print("rendering can work" if ok else
          "rendering cannot work here, or only in the slow scalar variant: see above")
    return 0 if ok else 1


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mimarble",
        description="The marble solid texture of Park & Park (2004) for Mitsuba 3.")
    parser.add_argument("--variant", help="Mitsuba variant (default: $MIMARBLE_VARIANT, "
                                          "else cuda_ad_rgb, llvm_ad_rgb, scalar_rgb)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

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
    except EnvironmentProblem as e:
        print(f"mimarble: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("mimarble: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
