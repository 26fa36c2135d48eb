"""Path-mode renders of the paper scenes in llvm_ad_spectral against llvm_ad_rgb.

    ./go python scripts/spectral_check.py [SIZE [SPP]]      # default 64 pixels square, 256 spp

For every scene of scenes/*.scene (the paper's figures), renders path mode in both
variants at SIZE² pixels and SPP samples (seed 0), as translated and again with
``roughplastic``'s ``nonlinear`` off (its internal scattering, d/(1 − F_dr·d), is not linear
in the reflectance, so a spectrum and its RGB projection give different answers there,
most for saturated colours near 1), and prints per scene: the image mean's relative
difference per channel (spectral / RGB − 1, for channels whose mean is above 0.02), the
largest difference of a channel's mean, the mean and the 99th percentile of the per-pixel
|difference| (linear units, noise of both renders included), and the same two for two RGB
renders of other seeds (the noise alone). Last, the largest of each over the scenes.
The figures of docs/benchmarks.md, "Spectral variants".
"""

import sys
from pathlib import Path

import numpy as np

import mimarble
from mimarble import scene as scene_language
from mimarble.mitsuba.translate.scene_dict import to_mitsuba
from mimarble.scene.edits import with_image_size

mi = mimarble.mi
ROOT = Path(__file__).resolve().parent.parent
SCENES = sorted(ROOT.glob("scenes/fig*.scene"))
VARIANTS = ("llvm_ad_rgb", "llvm_ad_spectral")


def linear(scene_dict: dict) -> dict:
    """The scene dict with every roughplastic's ``nonlinear`` off."""
    out = {}
    for key, value in scene_dict.items():
        if isinstance(value, dict):
            value = linear(value)
            if value.get("type") == "roughplastic":
                value = {**value, "nonlinear": False}
        out[key] = value
    return out


def render(scene, variant: str, spp: int, nonlinear: bool, seed: int = 0) -> np.ndarray:
    mi.set_variant(variant)
    scene_dict = to_mitsuba(scene, mode="path", spp=spp)
    loaded = mi.load_dict(scene_dict if nonlinear else linear(scene_dict))
    return mimarble.render(loaded, spp=spp, seed=seed)


def main(argv) -> int:
    size = int(argv[1]) if len(argv) > 1 else 64
    spp = int(argv[2]) if len(argv) > 2 else 256
    worst = {}
    print(f"{size}x{size}, {spp} spp, path mode; spectral vs rgb (seed 0); noise: rgb seed 0 "
          f"vs rgb seed 1")
    print(f"{'scene':8} {'nonlinear':9} {'mean rel R, G, B':>26} {'|d mean|':>8} "
          f"{'mean |d|':>9} {'p99 |d|':>8} {'noise mean |d|, p99':>20}")
    for path in SCENES:
        scene = with_image_size(scene_language.load(path), width=size, height=size)
        for nonlinear in (True, False):
            rgb, spectral = (render(scene, v, spp, nonlinear) for v in VARIANTS)
            noise = np.abs(render(scene, VARIANTS[0], spp, nonlinear, seed=1) - rgb)
            means = rgb.mean(axis=(0, 1)), spectral.mean(axis=(0, 1))
            lit = means[0] > 0.02                      # a dark channel (fig11's blue): no ratio
            relative = np.where(lit, means[1] / np.where(lit, means[0], 1.0) - 1.0, np.nan)
            difference = np.abs(spectral - rgb)
            row = (float(np.nanmax(np.abs(relative))), float(np.max(np.abs(means[1] - means[0]))),
                   float(difference.mean()), float(np.quantile(difference, 0.99)),
                   float(noise.mean()), float(np.quantile(noise, 0.99)))
            worst[nonlinear] = tuple(max(a, b) for a, b in zip(worst.get(nonlinear, row), row))
            print(f"{path.stem:8} {str(nonlinear):9} "
                  f"{', '.join(f'{r:+.4f}' for r in relative):>26} {row[1]:8.4f} {row[2]:9.4f} "
                  f"{row[3]:8.4f} {row[4]:9.4f}, {row[5]:.4f}")
    for nonlinear, row in worst.items():
        print(f"largest, nonlinear {nonlinear}: |mean rel| {row[0]:.4f} (lit channels), "
              f"|d mean| {row[1]:.4f}, mean |d| {row[2]:.4f}, p99 |d| {row[3]:.4f}; noise "
              f"mean |d| {row[4]:.4f}, p99 {row[5]:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
