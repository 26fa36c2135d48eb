"""A gallery: scenes rendered small, one PNG each (``./go gallery -o docs/gallery`` remakes the README's)."""

from __future__ import annotations

import time
from pathlib import Path

from mimarble import scene as scene_language
from mimarble.mitsuba.rendering.render import render
from mimarble.mitsuba import write_image
from mimarble.scene.edits import with_image_size


def fitted(scene, size: int):
    """The scene with its longer side ``size`` pixels and its aspect kept: the shorter side
    is ``size`` × short / long rounded to the nearest pixel (halves up), at least 1. The fov
    is the full vertical angle, so the view is the scene's own (up to that rounding, a
    fraction of a pixel at the sides); a square scene comes out ``size``²."""
    width, height = scene.image.width, scene.image.height
    long = max(width, height)
    short = max(1, (2 * size * min(width, height) + long) // (2 * long))
    return with_image_size(scene, *((size, short) if width >= height else (short, size)))


def make_gallery(scene_paths, out_dir, size: int = 160, mode: str = "whitted"):
    """Render each scene with its longer side ``size`` pixels, its aspect kept
    (:func:`fitted`), and write ``out_dir/<scene name>.png``; yields (path, seconds).

    ``out_dir`` is made if it is missing, but not its parent: ``mimarble gallery`` writes
    into ``./gallery`` unless told otherwise (``-o docs/gallery`` remakes the README's
    images), and a mistyped parent is an error, as for ``render -o``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(exist_ok=True)
    for path in scene_paths:
        scene = fitted(scene_language.load(path), size)
        start = time.perf_counter()
        image = render(scene, mode=mode)
        out = out_dir / (Path(path).stem + ".png")
        write_image(out, image)
        yield out, time.perf_counter() - start
