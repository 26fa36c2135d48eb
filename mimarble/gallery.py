"""The README gallery: every paper scene rendered small, one command to remake it."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from . import scene as scene_language
from .mitsuba import render, write_image


def resized(scene, size: int):
    """The same scene at size×size pixels (the paper's images are square)."""
    return dataclasses.replace(scene, image=dataclasses.replace(scene.image, width=size, height=size))


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
