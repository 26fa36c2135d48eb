"""The ``mimarble`` command line.

Exit status: 0 success, 1 the environment cannot render (``doctor``), 2 a user
error (bad scene, bad argument, unusable variant). User errors print one
message and no traceback: ``mimarble: …`` (``mimarble: FILE: …`` for a scene file that
cannot be read), or ``FILE:LINE:COL: …`` for an error at a place in a scene file, as
compilers write it.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import time
from pathlib import Path

from mimarble.mitsuba.rendering.crop import CONVENTION
from mimarble.runtime.image_formats import JPEG_QUALITIES, JPEG_QUALITY
from mimarble.parameters import FILTERS, SWEEPABLE


def _start(args) -> None:
    """Load Dr.Jit and Mitsuba and set the variant, now that the command needs them.

    Everything before this (arguments, output names, the scene file) is checked
    without them, so mistakes answer at once (mimarble/__init__.py). Mitsuba's
    differentiable integrators (``prb``, …) are built only for a command that renders
    with them (the benchmark's targets time an Adam step through ``prb``): they cost a
    fifth of a short command.
    """
    import mimarble
    from mimarble.runtime import environment
    if not (args.command == "bench" and not args.no_targets):
        environment.skip_mitsuba_ad_integrators()
    mimarble.use_variant(args.variant)    # before start(), so the variant is set only once
    mimarble.start()


def _doctor(args) -> int:
    from mimarble.runtime import environment, kernel_cache
    from mimarble import scene as scene_language
    if args.warm is not None:    # every scene error before minutes of compiling
        scenes = [(path, scene_language.load(path)) for path in _scene_list(args.warm)]
    rows, ok = environment.doctor(args.variant)
    rows.append(("kernel cache", kernel_cache.describe()))
    rows.append(("replay", environment.replay_sentence()))
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"{key:<{width}}  {value}")
    print("rendering can work" if ok else
          "rendering cannot work here, or only in the slow scalar variant: see above")
    if not ok:
        return 1
    if args.warm is not None:
        _start(args)
        start, compiled = time.perf_counter(), 0
        for path, seconds, kernels in kernel_cache.warm(scenes, progress=True):
            compiled += kernels
            _say(f"warm: {path}: {kernels} kernel{'s' * (kernels != 1)} compiled, {seconds:.2f} s",
                  flush=True)
        print(f"warm: {compiled} kernels compiled in {time.perf_counter() - start:.1f} s; "
              f"{kernel_cache.describe()}")
    return 0


def _scene_list(given) -> list[str]:
    """The scenes named (each by the SCENE rule: :func:`_scene_path`), else
    ./scenes/*.scene, else the packaged paper figures."""
    from mimarble.runtime import packaged_scenes
    if given:
        return [_scene_path(name) for name in given]
    scenes = (sorted(str(p) for p in Path("scenes").glob("*.scene"))
              or [str(p) for p in packaged_scenes.figures()])
    if not scenes:
        raise UsageError("no scenes given, none in ./scenes and none packaged "
                         f"(looked in {packaged_scenes.FOLDER})")
    return scenes


def _scene_path(argument) -> str:
    """A SCENE argument as the file to read: a path that exists always wins, then a
    packaged scene's name (``fig11a``), else the path itself, whose reading says what is
    wrong (mimarble/runtime/packaged_scenes.py)."""
    from mimarble.runtime import packaged_scenes
    if os.fspath(argument) == "":
        raise UsageError("'': the scene's name is empty; name a scene file, or a packaged "
                         "scene (`mimarble scenes` lists them)")
    path = packaged_scenes.resolve(argument)      # one look through the packaged scenes
    if path == os.fspath(argument) and packaged_scenes.is_unknown_name(argument):
        raise UsageError(f"{argument}: no such file (looked for {os.path.abspath(argument)}), "
                         f"nor a packaged scene of that name (`mimarble scenes` lists them)")
    return path


class UsageError(Exception):
    """A user mistake on the command line (exit status 2)."""


def _say(text: str, **print_options) -> None:
    """Print a line that echoes the user's names (scene files, output names, values), each
    character that would act on the terminal shown escaped (scene/errors.py, printable)."""
    from mimarble.scene.errors import printable
    print(printable(text), **print_options)


def _checked_name(value, option: str | None = None) -> str:
    """``value``, an output option's (``option``: ``-o``, ``--diff``, …; None: a default
    name made from the scene file's), if every writer can write under it: the one rule of
    mimarble/runtime/files.py (:func:`~mimarble.runtime.files.output_name_problem`: not empty, no NUL, UTF-8)."""
    from mimarble.runtime.files import output_name_problem
    problem = output_name_problem(value)
    if problem:
        raise UsageError(f"{option} {shlex.quote(value)}: {problem}" if option else
                         f"{value}: {problem} (the default name, made from the scene file's: "
                         f"give -o NAME)")
    return value


def _check_folder(path) -> Path:
    """``path``, if it can be written as a new file: the folder it goes in exists, and it
    is not a folder or a symbolic link (a rename would replace the link, not write where
    it points: name the file itself)."""
    path = Path(path)
    try:
        if path.is_symlink():
            raise UsageError(f"{path}: is a symbolic link (to {os.readlink(path)}); name the "
                             f"file itself, or another file")
        if path.is_dir():
            raise UsageError(f"{path}: is a folder; name a file")
        if not path.parent.is_dir():
            raise UsageError(f"{path}: folder {path.parent} does not exist")
    except OSError as e:          # a name longer than the file system takes, a loop of links
        raise UsageError(f"{path}: {e.strerror or e}") from None
    return path


def _check_suffix(path: Path, suffixes, what: str) -> Path:
    from mimarble.runtime.image_formats import formats_sentence
    if path.suffix.lower() not in suffixes:
        raise UsageError(f"{path}: unsupported {what} format {path.suffix or '(none)'!r}; "
                         f"use {formats_sentence(suffixes)}")
    return path


def _quality(args, out: Path) -> int | None:
    """``--quality``: an integer in 1..100, for a .jpg or .jpeg output only."""
    from mimarble.runtime.image_formats import JPEG_FORMATS, formats_sentence, quality_problem
    quality = getattr(args, "quality", None)
    if quality is None:
        return None
    problem = quality_problem(quality)
    if problem:
        raise UsageError(f"--quality {quality}: {problem.removeprefix('quality ')}")
    if out.suffix.lower() not in JPEG_FORMATS:
        raise UsageError(f"--quality {quality}: applies to {formats_sentence(JPEG_FORMATS)} "
                         f"output, not {out.suffix.lower() or 'a name without a suffix'} ({out})")
    return quality


def _crop(args, scene):
    """``--crop X0 Y0 X1 Y1``, checked against the image's size (after --width/--height)."""
    from mimarble.mitsuba.rendering.crop import crop_problem, crop_words
    crop = getattr(args, "crop", None)
    if crop is None:
        return None
    problem = crop_problem(crop, scene.image.width, scene.image.height)
    if problem:
        raise UsageError(f"--crop {crop_words(crop)}: {problem}")
    return tuple(crop)


def _output_path(args, default_suffix=".png") -> Path:
    from mimarble.runtime.image_formats import IMAGE_FORMATS
    out = Path(_checked_name(args.output, "-o") if args.output is not None
               else _checked_name(Path(_scene_path(args.scene)).stem + default_suffix))
    try:
        folder = out.is_dir() and not out.is_symlink()
    except OSError:
        folder = False            # said by _check_folder
    if folder:
        raise UsageError(f"{out}: is a folder; name the image file, e.g. "
                         f"{out / (Path(args.scene).stem + default_suffix)}")
    return _check_folder(_check_suffix(out, IMAGE_FORMATS, "image"))


def _load_scene(args):
    """The scene file, with ``--width``/``--height`` applied, and warnings for an empty scene."""
    import warnings

    from mimarble import scene as scene_language
    from mimarble.scene import LIMITS
    from mimarble.scene.edits import with_image_size
    scene = scene_language.load(_scene_path(args.scene))
    lo, hi = LIMITS["image_size"]
    size = {}
    for option in ("width", "height"):
        value = getattr(args, option, None)
        if value is not None:
            if not lo <= value <= hi:
                raise UsageError(f"--{option} {value}: must be in {lo}..{hi}")
            size[option] = value
    spp = getattr(args, "spp", None)         # with a new size: the limit is on what renders
    try:
        scene = with_image_size(scene, **size, spp=spp if size and spp and spp >= 1 else None)
    except ValueError as e:
        raise UsageError(f"{args.scene}: {e}") from None
    if not scene.shapes():
        warnings.warn(f"{args.scene}: the scene has no shapes (no spheres, planes, boxes or "
                      f"meshes): the image is the background")
    elif not scene.lights and not any(scene.ambient):
        warnings.warn(f"{args.scene}: the scene has no lights and no ambient light: "
                      f"the shapes are black")
    return scene


def _check_spp(spp: int, whitted: bool = True, option: str = "--spp") -> int:
    from mimarble.scene.model import samples_per_axis
    if spp < 1:
        raise UsageError(f"{option} {spp}: must be at least 1")
    if whitted:
        try:
            samples_per_axis(spp)
        except ValueError:
            raise UsageError(f"{option} {spp}: whitted mode samples an n×n grid, so it must be a "
                             f"perfect square (1, 4, 9, 16, …)") from None
    return spp


def _spp(args, scene) -> int:
    from mimarble.scene.rules import spp_problem
    from mimarble.scene.model import samples_per_axis
    spp = scene.image.samples if args.spp is None else args.spp
    whitted = getattr(args, "mode", "whitted") == "whitted"
    if args.spp is None and whitted:
        try:
            samples_per_axis(spp)
        except ValueError:
            where = f"{scene.source or args.scene}:{scene.image.pos or '?'}"
            raise UsageError(f"{where}: samples {spp}: whitted mode (and the reference tracer) "
                             f"sample an n×n grid, so it must be a perfect square (1, 4, 9, 16, …); "
                             f"path mode takes any count (--mode path), or override it with --spp")
    _check_spp(spp, whitted)
    problem = spp_problem(spp, scene.image.width, scene.image.height)
    if problem:
        raise UsageError(f"--{problem}")
    if getattr(args, "adaptive", None) is not None:
        from mimarble.scene.rules import adaptive_problem
        problem = adaptive_problem(args.adaptive, _max_spp(args, spp), spp,
                                   scene.image.width, scene.image.height)
        if problem:
            raise UsageError(problem.replace("max_spp=", "--max-spp "))
    return spp


def _max_spp(args, spp: int) -> int:
    """An adaptive render's most samples per pixel: ``--max-spp``, else the default (64, or
    the first pass's spp when that is more: mimarble.render's rule)."""
    return max(64, spp) if args.max_spp is None else args.max_spp


def _write(out: Path, image, eight_bit: bool = False, quality: int | None = None,
           origin=(0, 0)) -> None:
    from mimarble.mitsuba.rendering.image_output import write_image, write_rgb8
    _check_folder(out)
    try:
        if eight_bit:
            write_rgb8(out, image)
        else:
            write_image(out, image, quality=quality, origin=origin)
    except (OSError, RuntimeError) as e:
        raise UsageError(f"{out}: could not write the image: {e}") from None


def _render_to_file(args, renderer, description) -> int:
    """Load, check arguments, render, write whole, report: shared by render and reference.

    ``description(spp)`` names the renderer once it has started.
    """
    out = _output_path(args)
    quality = _quality(args, out)
    scene = _load_scene(args)
    spp = _spp(args, scene)
    crop = _crop(args, scene)
    _start(args)
    start = time.perf_counter()
    image = renderer(scene, spp)
    seconds = time.perf_counter() - start
    # A window's PNG is dithered where its pixels lie in the whole image: the full PNG's.
    _write(out, image, quality=quality, origin=(0, 0) if crop is None else crop[:2])
    size = f"{scene.image.width}x{scene.image.height}"
    if crop is not None:
        from mimarble.mitsuba.rendering.crop import crop_words
        size = f"{image.shape[1]}x{image.shape[0]} (--crop {crop_words(crop)} of {size})"
    _say(f"{out}: {size}, {spp} spp, {description(spp)}, {seconds:.2f} s")
    return 0


def _render(args) -> int:
    import mimarble
    _check_whitted_options(args)
    return _render_to_file(args, lambda scene, spp: mimarble.render(
        scene, spp=spp, mode=args.mode, progress=True, tolerance=args.tolerance,
        filter=args.filter, edge_spp=args.edge_spp,
        crop=None if args.crop is None else tuple(args.crop), adaptive=args.adaptive,
        max_spp=args.max_spp),
        lambda spp: f"{args.mode} mode{_adaptive_words(args, spp)}, {mimarble.mi.variant()}")


def _adaptive_words(args, spp: int) -> str:
    """How an adaptive render is described after its mode ('' for none)."""
    if args.adaptive is None:
        return ""
    return f", adaptive {args.adaptive:g} up to {_max_spp(args, spp)} spp"


def _reference(args) -> int:
    from mimarble import reference
    return _render_to_file(args, lambda scene, spp: reference.render(scene, spp=spp, progress=True),
                           lambda spp: "reference tracer (NumPy float64)")


def _compare(args) -> int:
    import json

    _check_adaptive_options(args)
    if args.diff is not None:
        _check_folder(_check_suffix(Path(_checked_name(args.diff, "--diff")), (".png",),
                                    "error map"))
    scene = _load_scene(args)
    spp = _spp(args, scene)
    _start(args)
    import mimarble
    from mimarble import reference
    from mimarble.tools.compare import error_map_scale, error_map_with_legend, image_metrics
    from mimarble.scene import walk
    filters = {args.filter} if args.filter else {
        getattr(inner, "filter", "none") for material in scene.materials.values()
        for channel in material.channels().values() for inner in walk(channel)}
    if filters - {"none"} or args.edge_spp or args.adaptive:
        print("mimarble: note: the reference tracer renders plain supersampling (the ground "
              "truth): filtered marble, edge samples or adaptive sampling differ from it by "
              "what they filter or sample otherwise", file=sys.stderr)
    start = time.perf_counter()
    ours = mimarble.render(scene, spp=spp, progress=True, tolerance=args.tolerance,
                           filter=args.filter, edge_spp=args.edge_spp,
                           adaptive=args.adaptive, max_spp=args.max_spp)
    mitsuba_seconds = time.perf_counter() - start
    start = time.perf_counter()
    # An adaptive render is compared with the reference at its most samples per pixel.
    reference_spp = spp if args.adaptive is None else _max_spp(args, spp)
    ref = reference.render(scene, spp=reference_spp, progress=True)
    reference_seconds = time.perf_counter() - start
    metrics = image_metrics(ours, ref)
    metrics.update(scene=str(args.scene), spp=spp, variant=mimarble.mi.variant(),
                   mitsuba_seconds=mitsuba_seconds, reference_seconds=reference_seconds)
    if args.adaptive is not None:
        metrics.update(adaptive=args.adaptive, max_spp=reference_spp, reference_spp=reference_spp)
    if args.diff is not None:
        _write(Path(args.diff), error_map_with_legend(ours, ref), eight_bit=True)
    against = "" if reference_spp == spp else f" at {reference_spp} spp"
    _say(f"{args.scene}: {scene.image.width}x{scene.image.height}, {spp} spp"
          f"{_adaptive_words(args, spp)}, whitted ({mimarble.mi.variant()}) vs reference "
          f"(float64){against}")
    print(f"  RMSE {metrics['rmse']:.3g}   PSNR {metrics['psnr']:.2f} dB   max |error| "
          f"{metrics['max_abs']:.3g}   pixels off by > 1/255: {100 * metrics['frac_over_1_255']:.3f} %")
    print(f"  time: Mitsuba {mitsuba_seconds:.2f} s, reference {reference_seconds:.2f} s")
    if args.diff is not None:
        _say(f"  error map {args.diff} (legend under it): {error_map_scale()}")
    if args.json:
        print(json.dumps(metrics))
    return 0


def _bench(args) -> int:
    from mimarble import scene as mimarble_scene
    from mimarble.scene import LIMITS
    scenes = _scene_list(args.scenes)
    if not args.scenes:     # the paper's figures, then the fine veins beside them (issue 24)
        scenes += sorted(str(p) for p in (Path(scenes[0]).parent / "fine-veins").glob("*.scene"))
    lo, hi = LIMITS["image_size"]
    if not lo <= args.size <= hi:
        raise UsageError(f"--size {args.size}: must be in {lo}..{hi}")
    for spp in args.spp:
        _check_spp(spp)
    _check_spp(args.converged_spp, option="--converged-spp")
    _check_spp(args.max_spp, option="--max-spp")
    for threshold in args.adaptive or ():
        if not 0 < threshold < float("inf"):
            raise UsageError(f"--adaptive {threshold}: a threshold must be a finite number > 0")
    if args.adaptive and args.no_adaptive:
        raise UsageError("--adaptive gives the adaptive modes' thresholds; --no-adaptive "
                         "skips those modes: give one of them")
    if args.repeats < 1:
        raise UsageError(f"--repeats {args.repeats}: must be at least 1")
    if args.json is not None:
        _check_folder(_checked_name(args.json, "--json"))
    if args.plot is not None:
        _check_folder(_check_suffix(Path(_checked_name(args.plot, "--plot")),
                                    (".png", ".pdf", ".svg"), "plot"))
    if args.page is not None:
        _check_folder(_check_suffix(Path(_checked_name(args.page, "--page")), (".md",), "page"))
    for path in scenes:
        mimarble_scene.load(path)   # every scene error before minutes of measuring
    _start(args)
    from mimarble.bench import run as bench
    targets_scene = None if args.no_targets else bench.targets_scene(scenes)
    if not args.no_targets and targets_scene is None:
        raise UsageError("the targets are measured on scenes/fig11a.scene, which is not here; "
                         "give it among the scenes or pass --no-targets")
    results = bench.run_bench(scenes, size=args.size, spps=tuple(args.spp), repeats=args.repeats,
                              converged_spp=args.converged_spp, targets=targets_scene,
                              paper=not args.no_paper, povray=not args.no_povray,
                              tolerance=args.tolerance,
                              modes=bench.modes(args.filter, args.edge_spp,
                                                adaptive=not args.no_adaptive),
                              thresholds=tuple(args.adaptive or bench.ADAPTIVE_THRESHOLDS),
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
            _say(f"wrote the section of this machine ({slug}) into {args.page}")
    except OSError as e:
        raise UsageError(f"could not write the results: {e}") from None
    return 0


def _stress(args) -> int:
    if args.points < 1:
        raise UsageError(f"--points {args.points}: must be at least 1")
    if args.json is not None:
        _check_folder(_checked_name(args.json, "--json"))
    _start(args)
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


def _new_folder(path, option: str) -> Path:
    """``path`` (the value of ``option``) as a folder to write into: one that exists, or a
    new one in a folder that exists (made by the caller; a missing parent is refused, as
    ``render -o`` refuses it), never a symbolic link that leads nowhere."""
    folder = Path(_checked_name(path, option))
    try:
        if folder.is_symlink() and not folder.exists():
            raise UsageError(f"{folder}: is a symbolic link to {os.readlink(folder)}, which "
                             f"does not exist; name a folder")
        if folder.exists() and not folder.is_dir():
            raise UsageError(f"{folder}: exists and is not a folder")
        if not folder.exists() and not folder.parent.is_dir():
            raise UsageError(f"{folder}: folder {folder.parent} does not exist")
    except OSError as e:          # a name longer than the file system takes, a loop of links
        raise UsageError(f"{folder}: {e.strerror or e}") from None
    return folder


def _gallery(args) -> int:
    from mimarble.scene import LIMITS
    scenes = _scene_list(args.scenes)
    lo, hi = LIMITS["image_size"]
    if not lo <= args.size <= hi:
        raise UsageError(f"--size {args.size}: must be in {lo}..{hi}")
    from mimarble import scene as mimarble_scene
    from mimarble.runtime.files import output_name_problem
    for path in scenes:
        mimarble_scene.load(path)   # every scene error before a folder is made
        problem = output_name_problem(Path(path).stem + ".png")   # its image's name
        if problem:
            raise UsageError(f"{path}: the gallery names each image after its scene file, "
                             f"and {problem}")
    _start(args)
    from mimarble.runtime.environment import EnvironmentProblem, whitted_problem
    import mitsuba as mi
    problem = whitted_problem(mi.variant()) if args.mode == "whitted" else None
    if problem:                     # before a folder is made
        raise UsageError(problem)
    folder = _new_folder(args.output, "-o")
    from mimarble.tools.gallery import make_gallery
    written = 0
    try:
        for out, seconds in make_gallery(scenes, folder, args.size, args.mode):
            written += 1
            _say(f"{out} ({seconds:.2f} s)")
    except EnvironmentProblem:
        raise                       # what cannot render here (a variant), said as itself
    except (OSError, RuntimeError) as e:
        raise UsageError(f"{folder}: could not write the gallery: {e}") from None
    _say(f"wrote {written} image{'s' * (written != 1)} to {folder}{os.sep}")
    return 0


def _scenes(args) -> int:
    """``mimarble scenes``: the packaged scenes by name; ``--copy DIR``: copied out."""
    from mimarble.runtime import packaged_scenes
    if not packaged_scenes.paths():
        raise UsageError(f"no packaged scenes found (looked in {packaged_scenes.FOLDER})")
    if args.copy is None:
        names = packaged_scenes.names()
        width = max(len(name) for name in names)
        print(f"packaged scenes, in {packaged_scenes.FOLDER}:")
        for name, path in names.items():
            print(f"  {name:<{width}}  {packaged_scenes.summary(path)}".rstrip())
        print("render one by name (`mimarble render fig11a`, when no file of that name is "
              "here); copy them out with `mimarble scenes --copy DIR`")
        return 0
    folder = _new_folder(args.copy, "--copy")
    try:
        written = packaged_scenes.copy_to(folder)
    except packaged_scenes.CopyRefused as e:
        raise UsageError(str(e)) from None
    except OSError as e:
        raise UsageError(f"{folder}: could not copy the scenes: {e.strerror or e}") from None
    scenes = sum(1 for p in written if p.suffix == packaged_scenes.SUFFIX)
    others = len(written) - scenes
    _say(f"copied {scenes} scenes and {others} other file{'s' * (others != 1)} (image maps, "
          f"README) to {folder}{os.sep}")
    return 0


def _sweep(args) -> int:
    from mimarble.sweeps.run import SweepError, check_workers, frames, settings_from
    if not args.set:
        raise UsageError("a sweep needs at least one --set KEY=VALUES")
    out = Path(_checked_name(args.output, "-o"))
    try:
        if out.exists() and not out.is_dir():
            raise UsageError(f"-o {out}: exists and is not a folder")
        if not out.parent.is_dir():
            raise UsageError(f"-o {out}: the folder it would go in, {out.parent}, does not exist")
    except OSError as e:          # a name longer than the file system takes, a loop of links
        raise UsageError(f"-o {out}: {e.strerror or e}") from None
    scene = _load_scene(args)
    try:
        if args.workers is not None:
            check_workers(args.workers)             # at most a few per core
        settings = settings_from(args.set)
        frames(scene, settings)                     # their number, then every key and value
    except SweepError as e:
        raise UsageError(str(e)) from None
    if args.spp is not None:
        _check_spp(args.spp)
    _start(args)
    from mimarble.sweeps.run import summary_sentence, sweep
    start = time.perf_counter()
    try:
        index = sweep(scene, settings, out, spp=args.spp, workers=args.workers,
                      scheduler=args.scheduler, compare=args.compare, progress=True)
    except SweepError as e:
        raise UsageError(str(e)) from None
    failed = [f for f in index["frames"] if f["status"] != "done"]
    # "16 frames: 14 already done, 2 rendered now, 0 failed": what this run did.
    _say(f"{out}: {summary_sentence(index)} ({time.perf_counter() - start:.1f} s); "
          f"index {out / 'sweep.json'}"
          + ("" if failed else f", contact sheet {out / 'contact.png'}"))
    for f in failed:
        _say(f"  frame {f['index']} {f['values']}: {f['error']}", file=sys.stderr)
    return 1 if failed else 0


def _export(args) -> int:
    """``mimarble export``: the scene's Mitsuba dict as XML (or --python: a Python file)."""
    from mimarble.tools.export import PYTHON_SUFFIXES, XML_SUFFIXES
    suffixes = PYTHON_SUFFIXES if args.python else XML_SUFFIXES
    out = Path(_checked_name(args.output, "-o") if args.output is not None
               else _checked_name(Path(_scene_path(args.scene)).stem + suffixes[0]))
    _check_suffix(_check_folder(out), suffixes, "export")
    from mimarble.tools.export import script_name_problem
    problem = script_name_problem(out) if args.python else None
    if problem:
        raise UsageError(f"{out}: {problem}")
    scene = _load_scene(args)
    spp = _spp(args, scene)
    _start(args)
    from mimarble.tools.export import ExportError, export
    command = "mimarble " + " ".join(shlex.quote(a) for a in args.argv)
    try:
        export(scene, out, mode=args.mode, spp=spp, python=args.python, command=command)
    except ExportError as e:
        raise UsageError(f"{out}: {e}") from None
    except OSError as e:
        raise UsageError(f"{out}: could not write it: {e.strerror or e}") from None
    what = "Python (mi.load_dict)" if args.python else "Mitsuba XML (mi.load_file)"
    _say(f"{out}: {what}, {args.mode} mode, {spp} spp, "
          f"{scene.image.width}x{scene.image.height}; `import mimarble` first, for its plugins")
    return 0


def _bake(args) -> int:
    """``mimarble bake``: a shape's channel into an image through its (u, v), or a volume."""
    from mimarble import scene as scene_language
    from mimarble.tools.bake import (DEFAULT_IMAGE_SIZE, DEFAULT_VOLUME_SIZE, IMAGE_SUFFIXES,
        VOLUME_SUFFIXES, BakeError, chosen, size_problem)
    volume = args.volume
    out = _check_suffix(_check_folder(_checked_name(args.output, "-o")), VOLUME_SUFFIXES if volume
                        else IMAGE_SUFFIXES, "volume" if volume else "baked image")
    size = args.size if args.size is not None else \
        DEFAULT_VOLUME_SIZE if volume else DEFAULT_IMAGE_SIZE
    problem = size_problem(size, volume)
    if problem:
        raise UsageError(problem)
    scene = scene_language.load(_scene_path(args.scene))
    try:
        _, channel, _ = chosen(scene, args.shape, args.channel, volume)
    except BakeError as e:
        raise UsageError(str(e)) from None
    from mimarble.tools import bake
    start = time.perf_counter()
    what = f"{args.shape}'s {channel} channel"
    try:
        if volume:
            lo, hi = bake.bake_volume(scene, args.shape, out, size, channel, progress=True)
            box = " to ".join("<" + " ".join(f"{c:g}" for c in b) + ">" for b in (lo, hi))
            _say(f"{out}: {size}x{size}x{size} voxels of {what} over {box}, "
                  f"{time.perf_counter() - start:.1f} s (Mitsuba: gridvolume, use_grid_bbox)")
            return 0
        image = bake.bake_image(scene, args.shape, size, channel, progress=True)
    except BakeError as e:
        raise UsageError(str(e)) from None
    except OSError as e:
        raise UsageError(f"{out}: could not write it: {e.strerror or e}") from None
    _start(args)                       # the image writer is Mitsuba's
    _write(out, image)
    _say(f"{out}: {size}x{size} texels of {what} through its (u, v), "
          f"{time.perf_counter() - start:.1f} s")
    return 0


#: How a SCENE argument may also be given (mimarble/runtime/packaged_scenes.py's rule).
PACKAGED_NAME = "or a packaged scene's name when no such file exists (`mimarble scenes`)"


class _Parser(argparse.ArgumentParser):
    """argparse's parser, with the user's strings in its usage errors made printable (it
    echoes an unrecognised argument as typed: scene/errors.py, printable). Subcommands'
    parsers are of the same class."""

    def error(self, message):
        from mimarble.scene.errors import printable
        super().error(printable(message))


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="mimarble",
        description="The marble solid texture of Park & Park (2004) for Mitsuba 3.")
    parser.add_argument("--variant", help="Mitsuba variant (default: $MIMARBLE_VARIANT, "
                                          "else cuda_ad_rgb, llvm_ad_rgb, scalar_rgb)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add_size(p):
        p.add_argument("--width", type=int, help="image width in pixels (default: the scene's)")
        p.add_argument("--height", type=int, help="image height in pixels (default: the scene's)")

    def add_tolerance(p):
        p.add_argument("--tolerance", type=_tolerance, metavar="T",
                       help="colour error each marble may have for leaving out fine octaves "
                            "(0: every octave; default: the marble's own, else half an 8-bit "
                            "sRGB code value through the scene's lighting; docs/numerical-"
                            "stability.md)")

    def add_filter(p, what):
        p.add_argument("--filter", choices=FILTERS,
                       help="every marble's pixel filter: none (the colour at the sample), "
                            "bandlimit (sub-pixel octaves left out), prefilter (the colour "
                            f"averaged over the pixel's phase); {what}")
        p.add_argument("--edge-spp", type=_edge_spp, metavar="N",
                       help="render pixels on a silhouette again with N samples, a perfect "
                            "square (whitted mode)" + ("" if what.startswith("default: the")
                                                       else "; default 64 in the benchmark's "
                                                            "prefilter+edges mode"))

    def add_adaptive(p):
        p.add_argument("--adaptive", type=_adaptive_threshold, metavar="T",
                       help="adaptive sampling (whitted mode): --spp is the first pass, then "
                            "every pixel whose estimated error is above T (linear colour "
                            "units, e.g. 0.0003; times n² at n² samples) is "
                            "rendered again with twice the samples per axis, up to --max-spp; "
                            "refines silhouettes itself (not with --edge-spp). With --filter "
                            "prefilter the estimate costs least (docs/rendering-model.md)")
        p.add_argument("--max-spp", type=int, metavar="N",
                       help="adaptive sampling's most samples per pixel, a perfect square "
                            "(default 64)")

    def add_variant(p):   # also after the command: `render x.scene --variant scalar_rgb`
        p.add_argument("--variant", default=argparse.SUPPRESS, help="Mitsuba variant")

    def add_quality(p):
        p.add_argument("--quality", type=int, metavar="Q",
                       help=f"JPEG quality, {JPEG_QUALITIES[0]}..{JPEG_QUALITIES[1]}, for a "
                            f".jpg or .jpeg output (default {JPEG_QUALITY}; full-resolution "
                            f"colour, 4:4:4)")

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
    p.add_argument("--mode", choices=("whitted", "path"), default="whitted",
                   help="whitted: the paper's shading (default); path: physically based — "
                        "marble as a dielectric (a highlight of a few percent, not the paper's "
                        "Phong highlight), black background, noisy at few samples (use --spp 256); "
                        "see docs/rendering-model.md")
    add_size(p)
    add_quality(p)
    add_tolerance(p)
    add_filter(p, "default: the marbles' own")
    add_adaptive(p)
    add_variant(p)
    p.set_defaults(run=_render)

    p = sub.add_parser("reference", help="render a scene with the float64 reference tracer")
    p.add_argument("scene", help=f"scene file, {PACKAGED_NAME}")
    p.add_argument("-o", "--output", help="OUT.png, OUT.jpg, OUT.jpeg or OUT.exr (default: the "
                                          "scene's name with .png)")
    p.add_argument("--spp", type=int, help="samples per pixel, a perfect square (default: the scene's)")
    add_size(p)
    add_quality(p)
    add_variant(p)
    p.set_defaults(run=_reference, mode="whitted")

    p = sub.add_parser("compare", help="Mitsuba (whitted) against the reference tracer")
    p.add_argument("scene", help=f"scene file, {PACKAGED_NAME}")
    p.add_argument("--spp", type=int, help="samples per pixel, a perfect square (default: the scene's)")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON on the last line")
    p.add_argument("--diff", metavar="OUT.png",
                   help="write a false-colour error map: each pixel's largest channel "
                        "|Mitsuba - reference| on a log scale, black <= 1e-6, blue, magenta, "
                        "yellow, white >= 0.1 (and NaN), with a legend strip under it (the "
                        "colour bar, its decades labelled)")
    add_size(p)
    add_tolerance(p)
    add_filter(p, "default: the marbles' own (the reference renders plain supersampling)")
    add_adaptive(p)
    add_variant(p)
    p.set_defaults(run=_compare, mode="whitted")

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
                        "n² at n² samples), one run per T (default: 0.005 halving down to "
                        "4.5e-6, mimarble.bench.run.ADAPTIVE_THRESHOLDS)")
    p.add_argument("--max-spp", type=int, default=64, metavar="N",
                   help="the adaptive modes' most samples per pixel, a perfect square (default 64)")
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
    add_tolerance(p)
    add_filter(p, "measures only this one, and adaptive sampling of it (default: plain, "
                  "bandlimit, prefilter, prefilter with edge samples, adaptive sampling of plain "
                  "and of prefiltered marble)")
    add_variant(p)
    p.set_defaults(run=_bench)

    p = sub.add_parser("sweep", help="render every combination of parameter values, with an "
                                     "index and a contact sheet (one process or Dask)",
                       epilog="Run the same command again to resume: it renders only what is "
                              "missing and says so (\"16 frames: 14 already done, 2 rendered "
                              "now, 0 failed\"). Ctrl-C stops the sweep, its workers too: "
                              "\"mimarble: interrupted\", exit status 130.")
    p.add_argument("scene", help=f"scene file, {PACKAGED_NAME}")
    p.add_argument("--set", action="append", metavar="KEY=VALUES",
                   help="a parameter and its values: v1,v2,… or start:stop:count; KEY is "
                        "marble.K, MATERIAL.K or MATERIAL.CHANNEL.K "
                        f"(K: {', '.join(SWEEPABLE)}), "
                        "camera.fov, image.samples or light.N.intensity; repeat for a grid")
    p.add_argument("-o", "--output", required=True, help="folder for the images, sweep.json "
                                                         "and contact.png (resumed if it holds "
                                                         "this sweep)")
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
    add_size(p)
    add_variant(p)
    p.set_defaults(run=_sweep, mode="whitted")

    p = sub.add_parser("stress", help="float32 error of noise and marble against float64, "
                                      "beside the derived bound")
    p.add_argument("--points", type=int, default=2048, help="random points per table cell")
    p.add_argument("--json", metavar="OUT", help="write the measurements as JSON")
    add_variant(p)
    p.set_defaults(run=_stress)

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
    p.add_argument("--mode", choices=("whitted", "path"), default="whitted")
    add_variant(p)
    p.set_defaults(run=_gallery)

    p = sub.add_parser("scenes", help="list the paper's scenes shipped with mimarble; --copy: "
                                      "copy them (with their image maps) into a folder")
    p.add_argument("--copy", metavar="DIR", help="copy every packaged scene into DIR, made if "
                                                 "missing (files there are never overwritten)")
    p.set_defaults(run=_scenes)

    p = sub.add_parser("export", help="write the scene as Mitsuba 3 XML (or --python: a Python "
                                      "file) that Mitsuba renders as mimarble does")
    p.add_argument("scene", help=f"scene file, {PACKAGED_NAME}")
    p.add_argument("-o", "--output", help="OUT.xml, or OUT.py with --python (default: the "
                                          "scene's name with .xml or .py, here)")
    p.add_argument("--mode", choices=("whitted", "path"), default="whitted",
                   help="the rendering model translated (default whitted; see render --mode)")
    p.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    p.add_argument("--python", action="store_true",
                   help="write a Python file that builds the scene dict (mi.load_dict), "
                        "instead of XML (mi.load_file); both need `import mimarble` first, "
                        "which registers its plugins")
    add_size(p)
    add_variant(p)
    p.set_defaults(run=_export)

    from mimarble.tools.bake import (CHANNELS, DEFAULT_IMAGE_SIZE, DEFAULT_VOLUME_SIZE,
        MAX_IMAGE_SIZE, MAX_VOLUME_SIZE)
    p = sub.add_parser("bake", help="evaluate a shape's channel into an image through its "
                                    "(u, v), or --volume: into a volume grid over its bounds")
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
                        "albedo and density: a subsurface's, with --volume)")
    p.add_argument("--volume", action="store_true",
                   help="bake the channel on an N×N×N grid over the shape's world bounding box, "
                        "as a Mitsuba volume grid (.vol: gridvolume); spheres, boxes, meshes")
    add_variant(p)
    p.set_defaults(run=_bake)

    p = sub.add_parser("doctor", help="show the libLLVM, variant, versions and kernel cache "
                                      "in use; --warm: compile the scenes' kernels now")
    p.add_argument("--warm", nargs="*", metavar="SCENE",
                   help="render these scenes (files or packaged names; default: ./scenes/*.scene, "
                        "else the packaged paper figures) once at 1 spp, so that "
                        "their kernels are compiled and cached before the first real render")
    add_variant(p)
    p.set_defaults(run=_doctor)
    return parser


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


def _check_adaptive_options(args) -> None:
    """``--adaptive`` needs whitted mode and no ``--edge-spp``; ``--max-spp`` needs it."""
    if args.adaptive is None:
        if args.max_spp is not None:
            raise UsageError("--max-spp applies to adaptive sampling: give --adaptive T too")
        return
    if args.mode != "whitted":
        raise UsageError(f"--adaptive needs whitted mode (its stratum centres), not --mode "
                         f"{args.mode}")
    if args.edge_spp:
        raise UsageError("--adaptive refines silhouettes itself: give --adaptive or "
                         "--edge-spp, not both")


def _check_whitted_options(args) -> None:
    """``--edge-spp`` and a ``--filter`` other than none need whitted mode."""
    _check_adaptive_options(args)
    if args.edge_spp and args.mode != "whitted":
        raise UsageError(f"--edge-spp needs whitted mode (its stratum centres), not --mode {args.mode}")
    if args.filter not in (None, "none") and args.mode != "whitted":
        raise UsageError(f"--filter {args.filter} needs whitted mode (its ray differentials); "
                         f"Mitsuba's path integrator gives the marble none")


def _adaptive_threshold(text: str) -> float:
    """``--adaptive``: a finite number > 0 (argparse reports the error as a usage error)."""
    from mimarble.scene.rules import adaptive_problem
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    problem = adaptive_problem(value, None, 1, 1, 1)
    if problem:
        raise argparse.ArgumentTypeError(f"{text} {problem.split(' ', 1)[1]}")
    return value


def _tolerance(text: str) -> float:
    """``--tolerance``: a finite number ≥ 0 (argparse reports the error as a usage error)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"{text} must be a finite number ≥ 0")
    return value


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """Warnings are sentences for the user, not source locations of ours (the user's
    strings in them made printable: scene/errors.py)."""
    from mimarble.scene.errors import printable
    print(f"mimarble: warning: {printable(message)}", file=sys.stderr if file is None else file)


def main(argv=None) -> int:
    import warnings
    warnings.showwarning = _show_warning
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)   # as typed, for provenance
    from mimarble.runtime.environment import EnvironmentProblem
    from mimarble.scene.errors import SceneError, printable
    try:
        return args.run(args)
    except (EnvironmentProblem, UsageError) as e:
        # One line: a newline or an escape code in a name it quotes is shown, not sent.
        print(f"mimarble: {printable(e)}", file=sys.stderr)
        return 2
    except SceneError as e:
        # FILE:LINE:COL: message, as compilers write it (editors jump to it); an error with
        # no position (a scene file that cannot be read) is the program's: "mimarble: FILE: …".
        print(e if e.line is not None else f"mimarble: {e}", file=sys.stderr)
        return e.exit_status
    except KeyboardInterrupt:
        print("mimarble: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`mimarble compare … | head`): not an error of ours.
        sys.stdout = open(os.devnull, "w")
        return 0


if __name__ == "__main__":
    sys.exit(main())
