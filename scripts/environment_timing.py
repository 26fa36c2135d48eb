"""Environment files: the parser's header check and the reference tracer's decoder, timed.

    ./go python scripts/environment_timing.py [--width 2048] [--repeat 5]

Writes the tests' sky (tests/test_environment_light.py, ``sky``) at width × width/2 as a
run-length-encoded Radiance HDR and a ZIP OpenEXR (tests/environment_files.py) into a
temporary folder, then prints, for each, the file's size and the median over ``--repeat``
runs (after one warm run) of ``environment_file_problem`` (what the parser runs) and of the reference's
``load_environment`` (its cache cleared each time). docs/benchmarks.md, "Environment files".
"""

import argparse
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from environment_files import write_exr, write_hdr  # noqa: E402
from test_environment_light import sky  # noqa: E402

from mimarble.bench.peers import _median_seconds as median_seconds  # noqa: E402  (one warm run)
from mimarble.reference import environment  # noqa: E402
from mimarble.scene.environment_header import environment_file_problem  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=2048)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    image = sky(args.width // 2, args.width)
    with tempfile.TemporaryDirectory() as folder:
        files = {"Radiance HDR, run-length encoded": Path(folder) / "sky.hdr",
                 "OpenEXR, ZIP, FLOAT": Path(folder) / "sky.exr"}
        write_hdr(files["Radiance HDR, run-length encoded"], image)
        write_exr(files["OpenEXR, ZIP, FLOAT"], image, zip_compression=True)
        print(f"{args.width}x{args.width // 2}, median of {args.repeat}; load: {os.getloadavg()}")
        for what, path in files.items():
            check = median_seconds(lambda: environment_file_problem(str(path)), args.repeat)

            def decode():
                environment._load.cache_clear()
                environment.load_environment(path)

            print(f"{what}: {path.stat().st_size / 1e6:.1f} MB, header check {check:.3f} s, "
                  f"reference decode {median_seconds(decode, args.repeat):.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
