"""Every scene's image, to check that a change of code left the images as they were.

    ./go python scripts/image_check.py save DIR        # before the change
    ./go python scripts/image_check.py compare DIR     # after it: exit 1 if any pixel moved

Renders every scene in scenes/ and scenes/future-work/ at its own size and samples,
three times: plain (the marbles' own filter), and with every marble band-limited and prefiltered
(``filter="bandlimit"``, ``"prefilter"``), and keeps the linear float32 images as .npy files in DIR.
``compare`` renders them again and reports the largest difference per image; the
redesigns keep it within 1e-6.
"""

import sys
from pathlib import Path

import numpy as np

import mimarble

ROOT = Path(__file__).resolve().parent.parent
SCENES = sorted(ROOT.glob("scenes/*.scene")) + sorted(ROOT.glob("scenes/future-work/*.scene"))
FILTERS = (None, "bandlimit", "prefilter")
LIMIT = 1e-6


def images():
    for path in SCENES:
        for filter in FILTERS:
            name = f"{path.stem}-{filter or 'plain'}.npy"
            yield name, mimarble.render(str(path), filter=filter)


def main(argv) -> int:
    if len(argv) != 3 or argv[1] not in ("save", "compare"):
        print(__doc__, file=sys.stderr)
        return 2
    folder = Path(argv[2])
    if argv[1] == "save":
        folder.mkdir(parents=True, exist_ok=True)
        for name, image in images():
            np.save(folder / name, image)
            print(name, flush=True)
        return 0
    worst = 0.0
    for name, image in images():
        before = np.load(folder / name)
        difference = float(np.nanmax(np.abs(image - before))) if image.shape == before.shape \
            else float("inf")
        same_nan = np.array_equal(np.isnan(image), np.isnan(before))
        worst = max(worst, difference if same_nan else float("inf"))
        print(f"{name}: max |difference| {difference:.3g}{'' if same_nan else ', NaN moved'}",
              flush=True)
    print(f"largest difference {worst:.3g} (limit {LIMIT:g})")
    return 0 if worst <= LIMIT else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
