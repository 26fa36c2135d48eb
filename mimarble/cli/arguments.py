"""The command line's grammar: every command's options (argparse), each value's type
checked as it is parsed (a usage error, exit status 2).

One function a command adds its parser (``_render_command``, …), in the order ``--help``
lists them; the options several commands take are added by the ``_add_…`` functions.
What a command does is not here: mimarble/cli/main.py dispatches to its module.
This module imports no more than the command's help needs (no Dr.Jit, Mitsuba or NumPy).
"""

from __future__ import annotations

import argparse

from mimarble.contract import RENDER_MODES
from mimarble.mitsuba.rendering.crop import CONVENTION
from mimarble.runtime.image_formats import JPEG_QUALITIES, JPEG_QUALITY
from mimarble.parameters import FILTERS, SWEEPABLE
from mimarble.contract import DEFAULT_MAX_SPP

#: How a SCENE argument may also be given (mimarble/runtime/packaged_scenes.py's rule).
PACKAGED_NAME = "or a packaged scene's name when no such file exists (`mimarble scenes`)"


class _Parser(argparse.ArgumentParser):
    """argparse's parser, with the user's strings in its usage errors made printable (it
    echoes an unrecognised argument as typed: scene/errors.py, printable). Subcommands'
    parsers are of the same class."""

    def error(self, message):
        from mimarble.scene.errors import printable
        super().error(printable(message))


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The command line's parser; with ``command`` (one of :func:`command_named`'s), every
    other command is added by its name and help line only (enough for ``--help`` and for
    refusing an unknown command): argparse takes ~20 ms to add every option, a fifth of
    a malformed scene's answer."""
    parser = _Parser(
        prog="mimarble",
        description="The marble solid texture of Park & Park (2004) for Mitsuba 3.")
    parser.add_argument("--variant", help="Mitsuba variant (default: $MIMARBLE_VARIANT, "
                                          "else cuda_ad_rgb, llvm_ad_rgb, scalar_rgb)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, add_command in _COMMANDS.items():
        add_command(sub if command in (None, name) else _NamesOnly(sub))
    return parser


def command_named(argv) -> str | None:
    """The command ``argv`` runs (its first word that is not an option or the value of
    ``--variant``), or None when it names none (``--help``, a mistake)."""
    words = iter(argv)
    for word in words:
        if word == "--variant":
            next(words, None)
        elif not word.startswith("-"):
            return word if word in _COMMANDS else None
    return None


class _NamesOnly:
    """The subcommands' adder for the commands not run: each is added with its name and
    help line, and its options are dropped."""

    def __init__(self, sub):
        self._sub = sub

    def add_parser(self, name, **kwargs):
        self._sub.add_parser(name, **kwargs)
        return _Dropped()


class _Dropped:
    """A dropped parser: every call on it (add_argument, groups, set_defaults) does nothing."""

    def __getattr__(self, name):
        return lambda *args, **kwargs: self


def _add_size(p):
    p.add_argument("--width", type=int, help="image width in pixels (default: the scene's)")
    p.add_argument("--height", type=int, help="image height in pixels (default: the scene's)")


def _add_tolerance(p):
    p.add_argument("--tolerance", type=_tolerance, metavar="T",
                   help="colour error each marble may have for leaving out fine octaves "
                        "(0: every octave; default: the marble's own, else half an 8-bit "
                        "sRGB code value through the scene's lighting; docs/numerical-"
                        "stability.md)")


def _add_filter(p, what):
    p.add_argument("--filter", choices=FILTERS,
                   help="every marble's pixel filter: none (the colour at the sample), "
                        "bandlimit (sub-pixel octaves left out), prefilter (the colour "
                        f"averaged over the pixel's phase); {what}")
    p.add_argument("--edge-spp", type=_edge_spp, metavar="N",
                   help="render pixels on a silhouette again with N samples, a perfect "
                        "square (whitted mode)" + ("" if what.startswith("default: the")
                                                   else "; default 64 in the benchmark's "
                                                        "prefilter+edges mode"))


def _add_adaptive(p):
    p.add_argument("--adaptive", type=_adaptive_threshold, metavar="T",
                   help="adaptive sampling (whitted mode): --spp is the first pass, then "
                        "every pixel whose estimated error is above T (linear colour "
                        "units, e.g. 0.0003; times n³ at n² samples) gets three "
                        "times its samples (keeping its own), up to --max-spp; "
                        "refines silhouettes itself (not with --edge-spp). With --filter "
                        "prefilter the estimate costs least (docs/rendering-model.md)")
    p.add_argument("--max-spp", type=int, metavar="N",
                   help="adaptive sampling's most samples per pixel, a perfect square "
                        f"(default {DEFAULT_MAX_SPP}, or --spp when that is more)")


def _add_variant(p):   # also after the command: `render x.scene --variant scalar_rgb`
    p.add_argument("--variant", default=argparse.SUPPRESS, help="Mitsuba variant")


def _add_quality(p):
    p.add_argument("--quality", type=int, metavar="Q",
                   help=f"JPEG quality, {JPEG_QUALITIES[0]}..{JPEG_QUALITIES[1]}, for a "
                        f".jpg or .jpeg output (default {JPEG_QUALITY}; full-resolution "
                        f"colour, 4:4:4)")


def _render_command(sub) -> None:
    p = sub.add_parser("render", help="render a scene file through Mitsuba")
    p.add_argument("scene", help=f"scene file (see docs/scene-language.md), {PACKAGED_NAME}")
    p.add_argument("-o", "--output", help="OUT.png (8-bit sRGB), OUT.jpg or OUT.jpeg (the "
                                          "same 8-bit sRGB, compressed: --quality) or OUT.exr "
                                          "(linear float); default: the scene's name with "
                                          ".png, here")
    p.add_argument("--crop", type=int, nargs=4, metavar=("X0", "Y0", "X1", "Y1"),
                   help="render only a window of the image (POV-Ray's +SC/+EC/+SR/+ER): "
                        f"{CONVENTION} — the full image's [Y0:Y1, X0:X1], so POV-Ray's "
                        "+SCa +ECb +SRc +ERd is --crop a-1 c-1 b d; after --width/--height. "
                        "Whitted mode gives the full render's pixels there, bit for bit (edge "
                        "samples too); path mode draws the window's own samples, so its noise "
                        "differs from the full render's (the same expected image)")
    p.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    p.add_argument("--mode", choices=RENDER_MODES, default="whitted",
                   help="whitted: the paper's shading (default); path: physically based — "
                        "marble as a dielectric (a highlight of a few percent, not the paper's "
                        "Phong highlight), black background, noisy at few samples (use --spp 256); "
                        "preview: path with each translucent material's fast preview (light "
                        "leaves where it enters: no walk, no glow through thin parts); "
                        "see docs/rendering-model.md")
    _add_size(p)
    _add_quality(p)
    _add_tolerance(p)
    _add_filter(p, "default: the marbles' own")
    _add_adaptive(p)
    _add_variant(p)


def _reference_command(sub) -> None:
    p = sub.add_parser("reference", help="render a scene with the float64 reference tracer")
    p.add_argument("scene", help=f"scene file, {PACKAGED_NAME}")
    p.add_argument("-o", "--output", help="OUT.png, OUT.jpg, OUT.jpeg or OUT.exr (default: the "
                                          "scene's name with .png)")
    p.add_argument("--spp", type=int, help="samples per pixel, a perfect square (default: the scene's)")
    _add_size(p)
    _add_quality(p)
    _add_variant(p)
    p.set_defaults(mode="whitted")


def _compare_command(sub) -> None:
    p = sub.add_parser("compare", help="Mitsuba (whitted) against the reference tracer")
    p.add_argument("scene", help=f"scene file, {PACKAGED_NAME}")
    p.add_argument("--spp", type=int, help="samples per pixel, a perfect square (default: the scene's)")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON on the last line")
    p.add_argument("--diff", metavar="OUT.png",
                   help="write a false-colour error map: each pixel's largest channel "
                        "|Mitsuba - reference| on a log scale, black <= 1e-6, blue, magenta, "
                        "yellow, white >= 0.1 (and NaN), with a legend strip under it (the "
                        "colour bar, its decades labelled)")
    _add_size(p)
    _add_tolerance(p)
    _add_filter(p, "default: the marbles' own (the reference renders plain supersampling)")
    _add_adaptive(p)
    _add_variant(p)
    p.set_defaults(mode="whitted")


def _bench_command(sub) -> None:
    p = sub.add_parser("bench", help="run time against error against the converged reference")
    p.add_argument("scenes", nargs="*", help="scene files or packaged scenes' names (default: "
                                             "./scenes/*.scene and ./scenes/fine-veins/*.scene, "
                                             "else the packaged paper figures and fine veins)")
    p.add_argument("--json", metavar="OUT", help="write all measurements as JSON")
    p.add_argument("--plot", metavar="OUT.png", help="write the error-against-time plot")
    p.add_argument("--page", metavar="PAGE.md",
                   help="write this machine's section into a benchmarks page (e.g. "
                        "docs/benchmarks.md), keeping the other machines' sections")
    p.add_argument("--size", type=int, default=256, help="image size of the measured renders (default 256)")
    p.add_argument("--spp", type=int, nargs="+", default=[1, 4, 16, 64],
                   help="the spp values measured in the modes that are not adaptive (default "
                        "1 4 16 64; each mode's time to plain 16 and 64 spp's RMSE needs those two)")
    p.add_argument("--adaptive", type=float, nargs="+", metavar="T",
                   help="the adaptive modes' thresholds: a first pass of 1 spp, then more samples "
                        "where a pixel's estimated error (linear colour) is above T (times "
                        "n³ at n² samples), one run per T (default: 0.005 quartered down to "
                        "7.6e-8, mimarble.bench.modes.ADAPTIVE_THRESHOLDS)")
    p.add_argument("--max-spp", type=int, default=DEFAULT_MAX_SPP, metavar="N",
                   help="the adaptive modes' most samples per pixel, a perfect square "
                        f"(default {DEFAULT_MAX_SPP})")
    p.add_argument("--no-adaptive", action="store_true",
                   help="skip the adaptive modes (adaptive, adaptive+prefilter)")
    p.add_argument("--repeats", type=int, default=5, help="warm runs per timing (median)")
    p.add_argument("--converged-spp", type=int, default=256,
                   help="reference spp (default 256: finer than the runs' 64)")
    p.add_argument("--no-targets", action="store_true", help="skip the issue's target measurements")
    p.add_argument("--no-paper", action="store_true", help="skip the comparison with the paper")
    p.add_argument("--no-povray", action="store_true",
                   help="skip timing POV-Ray 3.7 on a comparable marble sphere (done with the "
                        "targets when `povray` is installed)")
    _add_tolerance(p)
    _add_filter(p, "measures only this one, and adaptive sampling of it (default: plain, "
                  "bandlimit, prefilter, prefilter with edge samples, adaptive sampling of plain "
                  "and of prefiltered marble)")
    _add_variant(p)


def _sweep_command(sub) -> None:
    p = sub.add_parser("sweep", help="render every combination of parameter values, with an "
                                     "index and a contact sheet (one process or Dask)",
                       epilog="Run the same command again to resume: it renders only what is "
                              "missing and says so (\"16 frames: 14 already done, 2 rendered "
                              "now, 0 failed\"). Ctrl-C stops the sweep, its workers too: "
                              "\"mimarble: interrupted\", exit status 130.")
    p.add_argument("scene", help=f"scene file, {PACKAGED_NAME}")
    p.add_argument("--set", action="append", metavar="KEY=VALUES",
                   help="a parameter and its values: v1,v2,… or start:stop:count (a whole "
                        "ramp's values: separated by ';'); KEY is "
                        "marble.K, TEXTURE.K, MATERIAL.K or MATERIAL.CHANNEL.K "
                        f"(K: {', '.join(SWEEPABLE)}, ramp or ramp.N), camera.fov|eye|lookat|up, "
                        "light.N.intensity|color|position or image.samples "
                        "(--keys lists the scene's); repeat for a grid")
    p.add_argument("--keys", action="store_true",
                   help="print the scene's keys, grouped, with their values, and exit")
    p.add_argument("-o", "--output", help="folder for the images, sweep.json "
                                          "and contact.png (resumed if it holds "
                                          "this sweep); required unless --keys")
    p.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--workers", type=int,
                       help="render on a Dask LocalCluster of N processes (a few per core at "
                            "most). Its start-up costs seconds and one process already uses "
                            "every core: on 2 cores it was slower at every size and frame "
                            "count measured (docs/benchmarks.md, \"Sweeps\"), so leave it "
                            "out there")
    group.add_argument("--scheduler", metavar="ADDRESS",
                       help="render on a running Dask scheduler, e.g. tcp://host:8786")
    p.add_argument("--compare", action="store_true",
                   help="also each frame's RMSE and PSNR against the reference tracer")
    _add_size(p)
    _add_variant(p)
    p.set_defaults(mode="whitted")


def _stress_command(sub) -> None:
    p = sub.add_parser("stress", help="float32 error of noise and marble against float64, "
                                      "beside the derived bound")
    p.add_argument("--points", type=int, default=2048, help="random points per table cell")
    p.add_argument("--json", metavar="OUT", help="write the measurements as JSON")
    _add_variant(p)


def _gallery_command(sub) -> None:
    p = sub.add_parser("gallery", help="render scenes small, one PNG each (the README's gallery)")
    p.add_argument("scenes", nargs="*", help="scene files or packaged scenes' names (default: "
                                             "./scenes/*.scene, else the packaged paper figures)")
    p.add_argument("-o", "--output", default="gallery",
                   help="folder, made if missing (default: ./gallery; the README's images: "
                        "-o docs/gallery)")
    p.add_argument("--size", type=int, default=160,
                   help="the longer side of each image in pixels; the shorter keeps the "
                        "scene's aspect, rounded to the nearest pixel (a 320x240 scene at "
                        "--size 160 is 160x120; default: 160)")
    p.add_argument("--mode", choices=RENDER_MODES, default="whitted")
    _add_variant(p)


def _scenes_command(sub) -> None:
    p = sub.add_parser("scenes", help="list the paper's scenes shipped with mimarble; --copy: "
                                      "copy them (with their image maps) into a folder")
    p.add_argument("--copy", metavar="DIR", help="copy every packaged scene into DIR, made if "
                                                 "missing (files there are never overwritten)")


def _presets_command(sub) -> None:
    p = sub.add_parser("presets", help="list the marble library's presets (marble { preset "
                                       "\"carrara\" }); with a NAME: its values")
    p.add_argument("name", nargs="?", help="a preset's name: print what it is and its values")


def _export_command(sub) -> None:
    p = sub.add_parser("export", help="write the scene as Mitsuba 3 XML (or --python: a Python "
                                      "file) that Mitsuba renders as mimarble does")
    p.add_argument("scene", help=f"scene file, {PACKAGED_NAME}")
    p.add_argument("-o", "--output", help="OUT.xml, or OUT.py with --python (default: the "
                                          "scene's name with .xml or .py, here)")
    p.add_argument("--mode", choices=RENDER_MODES, default="whitted",
                   help="the rendering model translated (default whitted; see render --mode)")
    p.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    p.add_argument("--python", action="store_true",
                   help="write a Python file that builds the scene dict (mi.load_dict), "
                        "instead of XML (mi.load_file); both need `import mimarble` first, "
                        "which registers its plugins")
    _add_size(p)
    _add_variant(p)


def _bake_command(sub) -> None:
    p = sub.add_parser("bake", help="evaluate a shape's channel into an image through its "
                                    "(u, v), or --volume: into a volume grid over its bounds")
    if isinstance(p, _Dropped):
        return   # its options need tools.bake, not imported for another command
    from mimarble.tools.bake import (CHANNELS, DEFAULT_IMAGE_SIZE, DEFAULT_VOLUME_SIZE,
        MAX_IMAGE_SIZE, MAX_VOLUME_SIZE)
    p.add_argument("scene", help=f"scene file, {PACKAGED_NAME}")
    p.add_argument("--shape", required=True, metavar="ID",
                   help="the shape: sphere_0, mesh_0, box_0, … (each kind numbered in file "
                        "order)")
    p.add_argument("-o", "--output", required=True,
                   help="OUT.png (8-bit sRGB) or OUT.exr (linear float); OUT.vol with --volume")
    p.add_argument("--size", type=int, metavar="N",
                   help=f"texels along a side of the image (default {DEFAULT_IMAGE_SIZE}, at "
                        f"most {MAX_IMAGE_SIZE}), or voxels along a side of the volume "
                        f"(default {DEFAULT_VOLUME_SIZE}, at most {MAX_VOLUME_SIZE})")
    p.add_argument("--channel", choices=CHANNELS,
                   help="the material's channel (default: diffuse, else the first it has; "
                        "albedo, reflectance and density: a subsurface's, with --volume)")
    p.add_argument("--volume", action="store_true",
                   help="bake the channel on an N×N×N grid over the shape's world bounding box, "
                        "as a Mitsuba volume grid (.vol: gridvolume); spheres, boxes, meshes")
    _add_variant(p)



def _doctor_command(sub) -> None:
    p = sub.add_parser("doctor", help="show the libLLVM, variant, versions and kernel cache "
                                      "in use; --warm: compile the scenes' kernels now")
    p.add_argument("--warm", nargs="*", metavar="SCENE",
                   help="render these scenes (files or packaged names; default: ./scenes/*.scene, "
                        "else the packaged paper figures) once at 1 spp, so that "
                        "their kernels are compiled and cached before the first real render")
    _add_variant(p)


def _studio_command(sub) -> None:
    p = sub.add_parser("studio", help="tune a scene's marbles live in the browser: serve the "
                                      "studio page on this machine and open it")
    p.add_argument("scene", help=f"scene file, {PACKAGED_NAME}")
    p.add_argument("--port", type=_port, default=0, metavar="N",
                   help="the port to listen on (default: a free one)")
    p.add_argument("--host", default="127.0.0.1", metavar="H",
                   help="the address to listen on (default 127.0.0.1, this machine only; "
                        "another one lets other machines reach the studio: a warning)")
    p.add_argument("--no-browser", action="store_true",
                   help="print the URL (with its token) but do not open a browser")
    p.add_argument("--mode", choices=RENDER_MODES,
                   help="whitted or path (default: the scene's; the page can switch)")
    _add_variant(p)


#: Every command, in the order ``--help`` lists them: name -> the function that adds it.
_COMMANDS = {"render": _render_command, "reference": _reference_command,
             "compare": _compare_command, "bench": _bench_command, "sweep": _sweep_command,
             "stress": _stress_command, "gallery": _gallery_command, "scenes": _scenes_command,
             "presets": _presets_command, "export": _export_command, "bake": _bake_command,
             "doctor": _doctor_command, "studio": _studio_command}


def _port(text: str) -> int:
    """A TCP port: 0 (a free one) to 65535."""
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"{port}: a port lies in 0..65535 (0: a free one)")
    return port


def _edge_spp(text: str) -> int:
    """``--edge-spp``: a perfect square ≥ 1 (argparse reports the error as a usage error)."""
    from mimarble.scene.model import samples_per_axis
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    try:
        samples_per_axis(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{value} must be a perfect square ≥ 1 (1, 4, 9, 16, …): "
                                         f"the edge samples are an n×n grid") from None
    return value


def _adaptive_threshold(text: str) -> float:
    """``--adaptive``: a finite number > 0 (argparse reports the error as a usage error)."""
    from mimarble.scene.rules import adaptive_problem
    value = _number(text)
    problem = adaptive_problem(value, None, 1, 1, 1)
    if problem:
        raise argparse.ArgumentTypeError(f"{text} {problem.split(' ', 1)[1]}")
    return value


def _tolerance(text: str) -> float:
    """``--tolerance``: a finite number ≥ 0 (argparse reports the error as a usage error)."""
    value = _number(text)
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"{text} must be a finite number ≥ 0")
    return value


def _number(text: str) -> float:
    """``text`` as a float, or argparse's usage error saying it is no number."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
