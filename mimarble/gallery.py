"""The README gallery: every paper scene rendered small, one command to remake it."""

from __future__ import annotations

import time
from pathlib import Path

from . import scene as scene_language
from .mitsuba import render, write_image
from .scene_edits import resized


def make_gallery(scene_paths, out_dir, size: int = 160, mode: str = "whitted"):
    """Render each scene at ``size``² and write ``out_dir/<scene name>.png``; yields (path, seconds)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    for path in scene_paths:
        scene = resized(scene_language.load(path), size)
        start = time.perf_counter()
        image = render(scene, mode=mode)
        out = out_dir / (Path(path).stem + ".png")
        write_image(out, image)
        yield out, time.perf_counter() - start
