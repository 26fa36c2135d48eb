"""``mimarble export`` (the scene as Mitsuba XML or Python) and ``mimarble bake`` (a
shape's channel into an image or a volume): the scene written for other programs."""

from __future__ import annotations

import shlex
import time
from pathlib import Path

from mimarble.cli.shared import (UsageError, check_folder, check_suffix, checked_name,
    load_scene, say, scene_path, chosen_spp, start_mitsuba, write_output)


def _export(args) -> int:
    """``mimarble export``: the scene's Mitsuba dict as XML (or --python: a Python file)."""
    from mimarble.tools.export import PYTHON_SUFFIXES, XML_SUFFIXES
    suffixes = PYTHON_SUFFIXES if args.python else XML_SUFFIXES
    out = Path(checked_name(args.output, "-o") if args.output is not None
               else checked_name(Path(scene_path(args.scene)).stem + suffixes[0]))
    check_suffix(check_folder(out), suffixes, "export")
    from mimarble.tools.export import script_name_problem
    problem = script_name_problem(out) if args.python else None
    if problem:
        raise UsageError(f"{out}: {problem}")
    scene = load_scene(args)
    spp = chosen_spp(args, scene)
    start_mitsuba(args)
    from mimarble.tools.export import ExportError, export
    command = "mimarble " + " ".join(shlex.quote(a) for a in args.argv)
    try:
        export(scene, out, mode=args.mode, spp=spp, python=args.python, command=command)
    except ExportError as e:
        raise UsageError(f"{out}: {e}") from None
    except OSError as e:
        raise UsageError(f"{out}: could not write it: {e.strerror or e}") from None
    what = "Python (mi.load_dict)" if args.python else "Mitsuba XML (mi.load_file)"
    say(f"{out}: {what}, {args.mode} mode, {spp} spp, "
          f"{scene.image.width}x{scene.image.height}; `import mimarble` first, for its plugins")
    return 0


def _bake(args) -> int:
    """``mimarble bake``: a shape's channel into an image through its (u, v), or a volume."""
    from mimarble import scene as scene_language
    from mimarble.tools.bake import (DEFAULT_IMAGE_SIZE, DEFAULT_VOLUME_SIZE, IMAGE_SUFFIXES,
        VOLUME_SUFFIXES, BakeError, chosen, size_problem)
    volume = args.volume
    out = check_suffix(check_folder(checked_name(args.output, "-o")), VOLUME_SUFFIXES if volume
                        else IMAGE_SUFFIXES, "volume" if volume else "baked image")
    size = args.size if args.size is not None else \
        DEFAULT_VOLUME_SIZE if volume else DEFAULT_IMAGE_SIZE
    problem = size_problem(size, volume)
    if problem:
        raise UsageError(problem)
    scene = scene_language.load(scene_path(args.scene))
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
            say(f"{out}: {size}x{size}x{size} voxels of {what} over {box}, "
                  f"{time.perf_counter() - start:.1f} s (Mitsuba: gridvolume, use_grid_bbox)")
            return 0
        image = bake.bake_image(scene, args.shape, size, channel, progress=True)
    except BakeError as e:
        raise UsageError(str(e)) from None
    except OSError as e:
        raise UsageError(f"{out}: could not write it: {e.strerror or e}") from None
    start_mitsuba(args)                       # the image writer is Mitsuba's
    write_output(out, image)
    say(f"{out}: {size}x{size} texels of {what} through its (u, v), "
          f"{time.perf_counter() - start:.1f} s")
    return 0
