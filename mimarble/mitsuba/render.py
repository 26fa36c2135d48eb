"""Rendering a scene through Mitsuba, and writing images whole or not at all."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from .. import environment
from .. import scene as scene_language
from .translate import to_mitsuba

dr, mi = environment.import_drjit_and_mitsuba()

IMAGE_FORMATS = (".png", ".exr")


def render(scene_or_path, spp: int | None = None, mode: str = "whitted") -> np.ndarray:
    """Render a scene (model, or path of a scene file) → linear float32 (H, W, 3)."""
    scene = scene_or_path
    if isinstance(scene_or_path, (str, os.PathLike)):
        scene = scene_language.load(scene_or_path)
    mitsuba_scene = mi.load_dict(to_mitsuba(scene, mode=mode, spp=spp))
    image = mi.render(mitsuba_scene)
    return np.array(image, dtype=np.float32)[..., :3]


def write_image(path, image: np.ndarray) -> None:
    """Write linear RGB ``image`` to ``path`` (.exr: float; .png: 8-bit sRGB).

    PNG: the sRGB transfer curve (IEC 61966-2-1, Mitsuba's ``srgb_gamma``) after
    clamping to [0, 1]. The file is written under a temporary name in the same
    folder and renamed into place, so a failure never leaves half a file.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in IMAGE_FORMATS:
        raise ValueError(f"{path}: unsupported image format {suffix or '(none)'!r}; "
                         f"use {' or '.join(IMAGE_FORMATS)}")
    if suffix == ".png":
        clamped = np.clip(np.nan_to_num(image, nan=0.0), 0.0, 1.0).astype(np.float32)
        bitmap = mi.Bitmap(np.ascontiguousarray(clamped)).convert(
            mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True)
    else:
        bitmap = mi.Bitmap(np.ascontiguousarray(image, dtype=np.float32))
    write_atomically(path, bitmap)


def write_rgb8(path, pixels: np.ndarray) -> None:
    """Write 8-bit RGB ``pixels`` (H, W, 3) to a .png as they are (no transfer curve)."""
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"{path}: 8-bit images are written as .png")
    write_atomically(path, mi.Bitmap(np.ascontiguousarray(pixels, dtype=np.uint8)))


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomically(path: Path, bitmap) -> None:
    """Write under a temporary name in the same folder, then rename: whole or not at all."""
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=folder)
    os.close(fd)
    try:
        bitmap.write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())   # mkstemp makes 0600; a new image gets the usual mode
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
