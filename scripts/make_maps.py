"""Write the image maps of scenes/future-work/ (8-bit sRGB PNGs), made here, not downloaded.

    ./go python scripts/make_maps.py            # writes scenes/future-work/maps/*.png

``flagstones.png`` (256×128): warm sandstone flags in a running bond, mortar joints, a
mottled surface and a little per-stone tint — something photograph-like for marble
veins to be laid over. Deterministic (NumPy's PCG64 with a fixed seed; Pillow's PNG
encoder): ``tests/test_future_work_scenes.py`` checks the committed file is this output.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent
MAPS = ROOT / "scenes" / "future-work" / "maps"


def smooth_noise(shape, cells, rng) -> np.ndarray:
    """Value noise: a coarse random grid, bilinearly upsampled (wrapping), in [0, 1]."""
    height, width = shape
    grid = rng.uniform(0.0, 1.0, (cells[0], cells[1]))
    y = np.arange(height) * cells[0] / height
    x = np.arange(width) * cells[1] / width
    y0, x0 = np.floor(y).astype(int), np.floor(x).astype(int)
    fy, fx = (y - y0)[:, None], (x - x0)[None, :]
    y1, x1 = (y0 + 1) % cells[0], (x0 + 1) % cells[1]
    fy, fx = fy * fy * (3 - 2 * fy), fx * fx * (3 - 2 * fx)
    top = grid[y0][:, x0] * (1 - fx) + grid[y0][:, x1] * fx
    bottom = grid[y1][:, x0] * (1 - fx) + grid[y1][:, x1] * fx
    return top * (1 - fy) + bottom * fy


def flagstones(width: int = 256, height: int = 128, seed: int = 2004) -> np.ndarray:
    """(height, width, 3) uint8 sRGB."""
    rng = np.random.default_rng(seed)
    rows, columns = 4, 6
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    row = np.floor(y * rows / height).astype(int)
    shifted = x * columns / width + 0.5 * (row % 2)          # running bond
    column = np.floor(shifted).astype(int) % columns
    u, v = shifted % 1.0, (y * rows / height) % 1.0
    joint = np.minimum(np.minimum(u, 1 - u) * width / columns, np.minimum(v, 1 - v) * height / rows)
    mortar = np.clip((joint - 1.0) / 1.5, 0.0, 1.0)          # 0 in the joint, 1 on the stone
    tint = rng.uniform(-0.08, 0.08, (rows, columns, 3))[row, column]
    mottle = (0.6 * smooth_noise((height, width), (8, 16), rng)
              + 0.4 * smooth_noise((height, width), (32, 64), rng))[..., None]
    stone = np.array([0.78, 0.66, 0.50]) + tint + 0.18 * (mottle - 0.5)
    joint_colour = np.array([0.35, 0.33, 0.30])
    rgb = stone * mortar[..., None] + joint_colour * (1 - mortar[..., None])
    return np.clip(np.round(rgb * 255.0), 0, 255).astype(np.uint8)


MAKERS = {"flagstones.png": flagstones}


def main(folder: Path = MAPS) -> int:
    folder.mkdir(parents=True, exist_ok=True)
    for name, make in MAKERS.items():
        Image.fromarray(make(), "RGB").save(folder / name)
        print(folder / name)
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1]) if len(sys.argv) > 1 else MAPS))
