"""What the commands share: the user error, the checks of their scene and output
arguments (each said in one sentence before Dr.Jit and Mitsuba load), starting Mitsuba,
and printing the user's names.

Nothing here imports more than the standard library at module level: a malformed scene
or a bad option answers at once (tests/test_startup.py).
"""

from __future__ import annotations

import os
import shlex
from pathlib import Path


class UsageError(Exception):
    """A user mistake on the command line (exit status 2)."""


def start_mitsuba(args) -> None:
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


def scene_list(given) -> list[str]:
    """The scenes named (each by the SCENE rule: :func:`scene_path`), else
    ./scenes/*.scene, else the packaged paper figures."""
    from mimarble.runtime import packaged_scenes
    if given:
        return [scene_path(name) for name in given]
    scenes = (sorted(str(p) for p in Path("scenes").glob("*.scene"))
              or [str(p) for p in packaged_scenes.figures()])
    if not scenes:
        raise UsageError("no scenes given, none in ./scenes and none packaged "
                         f"(looked in {packaged_scenes.FOLDER})")
    return scenes


def scene_path(argument) -> str:
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


def say(text: str, **print_options) -> None:
    """Print a line that echoes the user's names (scene files, output names, values), each
    character that would act on the terminal shown escaped (scene/errors.py, printable)."""
    from mimarble.scene.errors import printable
    print(printable(text), **print_options)


def checked_name(value, option: str | None = None) -> str:
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


def check_folder(path) -> Path:
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


def check_suffix(path: Path, suffixes, what: str) -> Path:
    """``path`` if its suffix is one of ``suffixes`` (any case), else a UsageError naming them."""
    from mimarble.runtime.image_formats import formats_sentence
    if path.suffix.lower() not in suffixes:
        raise UsageError(f"{path}: unsupported {what} format {path.suffix or '(none)'!r}; "
                         f"use {formats_sentence(suffixes)}")
    return path


def chosen_quality(args, out: Path) -> int | None:
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


def chosen_crop(args, scene):
    """``--crop X0 Y0 X1 Y1``, checked against the image's size (after --width/--height)."""
    from mimarble.mitsuba.rendering.crop import crop_problem, crop_words
    crop = getattr(args, "crop", None)
    if crop is None:
        return None
    problem = crop_problem(crop, scene.image.width, scene.image.height)
    if problem:
        raise UsageError(f"--crop {crop_words(crop)}: {problem}")
    return tuple(crop)


def output_path(args, default_suffix=".png") -> Path:
    """The image file to write: ``-o``, else the scene's stem with ``default_suffix``; its
    name, format and folder checked (a UsageError for a folder, a format or a name)."""
    from mimarble.runtime.image_formats import IMAGE_FORMATS
    out = Path(checked_name(args.output, "-o") if args.output is not None
               else checked_name(Path(scene_path(args.scene)).stem + default_suffix))
    try:
        folder = out.is_dir() and not out.is_symlink()
    except OSError:
        folder = False            # said by check_folder
    if folder:
        raise UsageError(f"{out}: is a folder; name the image file, e.g. "
                         f"{out / (Path(args.scene).stem + default_suffix)}")
    return check_folder(check_suffix(out, IMAGE_FORMATS, "image"))


def load_scene(args):
    """The scene file, with ``--width``/``--height`` applied, and warnings for an empty scene."""
    import warnings

    from mimarble import scene as scene_language
    from mimarble.scene import LIMITS
    from mimarble.scene.edits import with_image_size
    scene = scene_language.load(scene_path(args.scene))
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
        from mimarble.scene.shapes import SHAPE_KINDS
        plurals = [kind.plural for kind in SHAPE_KINDS]
        warnings.warn(f"{args.scene}: the scene has no shapes (no {', '.join(plurals[:-1])} or "
                      f"{plurals[-1]}): the image is the background")
    elif not scene.lights and not any(scene.ambient) and not (
            scene.environment is not None and getattr(args, "mode", None) in ("path", "preview")):
        # (path mode's environment lights the shapes; whitted mode's is their background)
        warnings.warn(f"{args.scene}: the scene has no lights and no ambient light: "
                      f"the shapes are black"
                      + (" (its environment lights path mode only)" if scene.environment else ""))
    return scene


def check_spp(spp: int, whitted: bool = True, option: str = "--spp") -> int:
    """``spp`` if it is at least 1 and, in whitted mode, a perfect square (n×n grid)."""
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


def chosen_spp(args, scene) -> int:
    """The render's samples per pixel: ``--spp``, else the scene's ``samples``, checked for
    the mode, the image's sample limit and (with ``--adaptive``) the adaptive options."""
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
    check_spp(spp, whitted)
    problem = spp_problem(spp, scene.image.width, scene.image.height)
    if problem:
        raise UsageError(f"--{problem}")
    if getattr(args, "adaptive", None) is not None:
        from mimarble.scene.rules import adaptive_problem
        problem = adaptive_problem(args.adaptive, chosen_max_spp(args, spp), spp,
                                   scene.image.width, scene.image.height)
        if problem:
            raise UsageError(problem.replace("max_spp=", "--max-spp "))
    return spp


def chosen_max_spp(args, spp: int) -> int:
    """An adaptive render's most samples per pixel: ``--max-spp``, else the default
    (``scene.rules.default_max_spp``: mimarble.render's rule)."""
    from mimarble.scene.rules import default_max_spp
    return default_max_spp(spp, args.max_spp)


def write_output(out: Path, image, eight_bit: bool = False, quality: int | None = None,
                 origin=(0, 0)) -> None:
    """Write ``image`` to ``out`` (8-bit RGB, or the format its suffix names); a failure as a
    UsageError naming the file."""
    from mimarble.mitsuba.rendering.image_output import write_image, write_rgb8
    check_folder(out)
    try:
        if eight_bit:
            write_rgb8(out, image)
        else:
            write_image(out, image, quality=quality, origin=origin)
    except (OSError, RuntimeError) as e:
        raise UsageError(f"{out}: could not write the image: {e}") from None


def adaptive_words(args, spp: int) -> str:
    """How an adaptive render is described after its mode ('' for none)."""
    if args.adaptive is None:
        return ""
    return f", adaptive {args.adaptive:g} up to {chosen_max_spp(args, spp)} spp"


def new_folder(path, option: str) -> Path:
    """``path`` (the value of ``option``) as a folder to write into: one that exists, or a
    new one in a folder that exists (made by the caller; a missing parent is refused, as
    ``render -o`` refuses it), never a symbolic link that leads nowhere."""
    folder = Path(checked_name(path, option))
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


def check_adaptive_options(args) -> None:
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


def check_whitted_options(args) -> None:
    """``--edge-spp`` and a ``--filter`` other than none need whitted mode."""
    check_adaptive_options(args)
    if args.edge_spp and args.mode != "whitted":
        raise UsageError(f"--edge-spp needs whitted mode (its stratum centres), not --mode {args.mode}")
    if args.filter not in (None, "none") and args.mode != "whitted":
        raise UsageError(f"--filter {args.filter} needs whitted mode (its ray differentials); "
                         f"Mitsuba's path integrator gives the marble none")
