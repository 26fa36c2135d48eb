"""``mimarble scenes`` (the packaged scenes, listed or copied out) and ``mimarble
gallery`` (scenes rendered small, one PNG each)."""

from __future__ import annotations

import os
from pathlib import Path

from mimarble.cli.shared import UsageError, new_folder, say, scene_list, start_mitsuba


def _gallery(args) -> int:
    from mimarble.scene import LIMITS
    scenes = scene_list(args.scenes)
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
    start_mitsuba(args)
    from mimarble.runtime.environment import EnvironmentProblem, whitted_problem
    import mitsuba as mi
    problem = whitted_problem(mi.variant()) if args.mode == "whitted" else None
    if problem:                     # before a folder is made
        raise UsageError(problem)
    folder = new_folder(args.output, "-o")
    from mimarble.tools.gallery import make_gallery
    written = 0
    try:
        for out, seconds in make_gallery(scenes, folder, args.size, args.mode):
            written += 1
            say(f"{out} ({seconds:.2f} s)")
    except EnvironmentProblem:
        raise                       # what cannot render here (a variant), said as itself
    except (OSError, RuntimeError) as e:
        raise UsageError(f"{folder}: could not write the gallery: {e}") from None
    say(f"wrote {written} image{'s' * (written != 1)} to {folder}{os.sep}")
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
    folder = new_folder(args.copy, "--copy")
    try:
        written = packaged_scenes.copy_to(folder)
    except packaged_scenes.CopyRefused as e:
        raise UsageError(str(e)) from None
    except OSError as e:
        raise UsageError(f"{folder}: could not copy the scenes: {e.strerror or e}") from None
    scenes = sum(1 for p in written if p.suffix == packaged_scenes.SUFFIX)
    others = len(written) - scenes
    say(f"copied {scenes} scenes and {others} other file{'s' * (others != 1)} (image maps, "
          f"README) to {folder}{os.sep}")
    return 0
