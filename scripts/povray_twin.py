"""A POV-Ray marble sphere and its twin in this language, rendered side by side and compared.

    ./go python scripts/povray_twin.py

Renders docs/examples/povray-twin/marble.pov with ``povray`` (POV-Ray 3.7, no
anti-aliasing, 320×240) and its twin marble.scene with
``mimarble.render`` (whitted mode, 1 sample a pixel), and writes into that folder:
povray.png, mimarble.png, side-by-side.png (POV-Ray left) and agreement.json, the measured
agreement (docs/coming-from-povray.md cites it). Needs POV-Ray (Debian: apt-get install
povray); nothing in the tests runs it.

What agreement.json holds, all on the 8-bit sRGB images unless it says linear:

* ``psnr_db``, ``mean_abs_diff``: the whole images (codes 0..255 as 0..1).
* ``silhouette_agreement``: the fraction of pixels where both are background or both are
  sphere. Each image's sphere pixels are its own, found the same way for both: the pixels
  that stay the same when the scene is rendered again with a magenta background.
* ``sphere_mean_srgb``: each image's mean colour over its sphere pixels.
* ``sphere_luminance_quantiles``: the 10/50/90 % quantiles of linear luminance there.
* ``vein_fraction``: the fraction of the lit, highlight-free sphere pixels (n·l > 0.3 and
  0.4·(n·h)^40 < 0.01, from the shared geometry) whose shading-free luminance — the
  linear luminance over 0.1 + 0.9·(n·l), the two scenes' ambient and diffuse — is below
  ``VEIN_THRESHOLD``: the ramp's dark end, the veins.
* ``pattern_correlation``: the Pearson correlation of that shading-free luminance between
  the two images over the same pixels: near 0 when the vein patterns are unrelated.
"""

from __future__ import annotations

import dataclasses
import json
import math
import platform
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
FOLDER = ROOT / "docs" / "examples" / "povray-twin"
POV_FILE = FOLDER / "marble.pov"
TWIN_FILE = FOLDER / "marble.scene"
WIDTH, HEIGHT = 320, 240
VEIN_THRESHOLD = 0.35        # linear luminance: between the ramp's 0.6 and 0.85 colours


BACKGROUND = "background { rgb <0.02, 0.02, 0.03> }"   # as marble.pov writes it
OTHER_BACKGROUND = "background { rgb <1, 0, 1> }"


def povray_command(source: Path, output: Path) -> list[str]:
    """The POV-Ray command that renders ``source`` (no AA, no display, PNG)."""
    return ["povray", "-D", "-A", "+FN", f"+W{WIDTH}", f"+H{HEIGHT}", f"+O{output}",
            str(source)]


def _povray(source: Path, folder: Path) -> np.ndarray:
    from PIL import Image
    out = folder / (source.stem + ".png")
    run = subprocess.run(povray_command(source, out), capture_output=True, text=True,
                         timeout=600)
    if run.returncode != 0:
        raise RuntimeError(f"povray failed: {(run.stderr or run.stdout)[-800:]}")
    return np.asarray(Image.open(out).convert("RGB"))


def render_povray() -> tuple[np.ndarray, np.ndarray, str]:
    """POV-Ray's image of :data:`POV_FILE` (H, W, 3 uint8), its sphere mask — the pixels
    that stay when a copy with another background is rendered — and its version line."""
    text = POV_FILE.read_text()
    if BACKGROUND not in text:
        raise RuntimeError(f"{POV_FILE} does not set {BACKGROUND}")
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        image = _povray(POV_FILE, folder)
        other = folder / "other.pov"
        other.write_text(text.replace(BACKGROUND, OTHER_BACKGROUND))
        mask = np.all(_povray(other, folder) == image, axis=2)
    version = subprocess.run(["povray", "--version"], capture_output=True, text=True)
    line = next((s for s in (version.stdout + version.stderr).splitlines()
                 if s.startswith("POV-Ray")), "POV-Ray")
    return image, mask, line.strip()


def render_twin() -> tuple[np.ndarray, np.ndarray]:
    """The twin's image (H, W, 3 uint8, as `mimarble render` writes its PNG) and sphere mask."""
    import mimarble
    from mimarble import scene as scene_language
    from mimarble.mitsuba.rendering.image_output import srgb8
    model = scene_language.parse(TWIN_FILE.read_text())
    image = mimarble.render(model)
    other = dataclasses.replace(model, image=dataclasses.replace(model.image,
                                                                 background=(1.0, 0.0, 1.0)))
    mask = np.all(mimarble.render(other) == image, axis=2)   # the sphere: what stays
    return srgb8(np.ascontiguousarray(image, dtype=np.float32)), mask


def geometry() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel, from the twin's camera and light (right-handed): hit mask, n·l, n·h."""
    fov = math.radians(35.32)
    t = math.tan(fov / 2)
    i, j = np.meshgrid(np.arange(WIDTH) + 0.5, np.arange(HEIGHT) + 0.5)
    d = np.stack([(2 * i / WIDTH - 1) * t * WIDTH / HEIGHT, (1 - 2 * j / HEIGHT) * t,
                  -np.ones_like(i)], axis=-1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    eye = np.array([0.0, 0.0, 9.0])
    b = d @ eye
    disc = b * b - (eye @ eye - 4.0)
    hit = disc > 0
    s = -b - np.sqrt(np.maximum(disc, 0))
    n = (eye + s[..., None] * d) / 2.0
    to_light = np.array([-6.0, 8.0, 10.0]) - 2.0 * n
    to_light /= np.linalg.norm(to_light, axis=-1, keepdims=True)
    h = to_light - d
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    return hit, np.sum(n * to_light, axis=-1), np.sum(n * h, axis=-1)


def _luminance(srgb: np.ndarray) -> np.ndarray:
    c = srgb / 255.0
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return linear @ np.array([0.2126, 0.7152, 0.0722])


def agreement(pov, pov_mask, twin, twin_mask) -> dict:
    a, b = pov / 255.0, twin / 255.0
    mse = float(np.mean((a - b) ** 2))
    hit, nl, nh = geometry()
    measured = hit & (nl > 0.3) & (0.4 * np.maximum(nh, 0) ** 40 < 0.01) & pov_mask & twin_mask
    albedo = {name: _luminance(img)[measured] / (0.1 + 0.9 * nl[measured])
              for name, img in (("povray", pov), ("mimarble", twin))}
    out = {
        "size": [WIDTH, HEIGHT],
        "psnr_db": round(10 * math.log10(1 / mse), 2),
        "mean_abs_diff": round(float(np.mean(np.abs(a - b))), 4),
        "silhouette_agreement": round(float(np.mean(pov_mask == twin_mask)), 5),
        "sphere_pixels": {"povray": int(pov_mask.sum()), "mimarble": int(twin_mask.sum()),
                          "geometry": int(hit.sum())},
        "sphere_mean_srgb": {}, "sphere_luminance_quantiles": {},
        "vein_threshold_linear_luminance": VEIN_THRESHOLD,
        "vein_pixels_measured": int(measured.sum()),
        "vein_fraction": {},
        "pattern_correlation": round(float(np.corrcoef(albedo["povray"],
                                                       albedo["mimarble"])[0, 1]), 3),
    }
    for name, img, mask in (("povray", pov, pov_mask), ("mimarble", twin, twin_mask)):
        out["sphere_mean_srgb"][name] = [round(float(v), 4) for v in (img[mask] / 255.0).mean(0)]
        out["sphere_luminance_quantiles"][name] = [
            round(float(q), 4) for q in np.quantile(_luminance(img)[mask], [0.1, 0.5, 0.9])]
        out["vein_fraction"][name] = round(float(np.mean(albedo[name] < VEIN_THRESHOLD)), 4)
    return out


def main() -> int:
    if shutil.which("povray") is None:
        print("povray is not installed (Debian: apt-get install povray)", file=sys.stderr)
        return 1
    from PIL import Image
    pov, pov_mask, version = render_povray()
    twin, twin_mask = render_twin()
    Image.fromarray(pov).save(FOLDER / "povray.png")
    Image.fromarray(twin).save(FOLDER / "mimarble.png")
    gap = np.full((HEIGHT, 8, 3), 255, np.uint8)
    Image.fromarray(np.concatenate([pov, gap, twin], axis=1)).save(FOLDER / "side-by-side.png")
    result = agreement(pov, pov_mask, twin, twin_mask)
    import mitsuba
    result["versions"] = {"povray": version, "mitsuba": mitsuba.__version__,
                          "python": platform.python_version()}
    result["command"] = "./go python scripts/povray_twin.py"
    (FOLDER / "agreement.json").write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
