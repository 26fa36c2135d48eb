"""What an oracle that knows every pixel's true error needs: the samples a pixel for an
RMSE, when each pixel may end at any level of adaptive sampling's ladder.

The oracle is given, for each level, the image every pixel would have there (an adaptive
render that takes every pixel to that level, :func:`level_images`, the first round's
jump to 16 included; at 1, 9, 16, 81 spp a point-sampled one is the plain render's) and the converged image. For a price λ per sample each pixel ends at the
level k that minimises e_k² + λ·c_k — e_k² its squared error summed over the colours,
c_k the samples traced to end there (the ladder's kept samples are not traced again;
a level that replaces traces its own anew) — which is the least total squared error for
that many samples (a Lagrangian relaxation of the budget: exact on the curve's convex
hull). Swept over λ, coarse to fine, it is a curve of (samples a pixel, RMSE) that no
estimate of the error can beat with these levels; :func:`oracle_samples` reads where it
reaches an RMSE. NumPy only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mimarble.bench.curves import value_at_crossing


def level_images(mitsuba_scene, spp: int, max_spp: int) -> tuple[list[np.ndarray], list[int]]:
    """(images, costs): every pixel of a loaded whitted scene taken to each level of
    adaptive sampling's ladder from ``spp`` to ``max_spp`` (a threshold below every
    estimate), and to each level after the first round's jump (``jump_ladder``), and the
    samples a pixel traces to end at each level; in order of cost."""
    from mimarble.mitsuba.rendering.adaptive import jump_ladder, ladder, render_adaptive
    levels, jumped = ladder(spp, max_spp), jump_ladder(spp, max_spp)
    runs = [render_adaptive(mitsuba_scene, spp, -1.0, max_spp, rounds=k, jump="never")
            for k in range(len(levels))]
    runs += [render_adaptive(mitsuba_scene, spp, -1.0, max_spp, rounds=k, jump="always")
             for k in range(1, len(jumped or ()))]
    runs.sort(key=lambda r: r.traced)
    pixels = runs[0].image.shape[0] * runs[0].image.shape[1]
    return [r.image for r in runs], [r.traced // pixels for r in runs]


def oracle_curve(images: list[np.ndarray], truth: np.ndarray, costs: list[int],
                 prices: int = 64) -> list[dict]:
    """The oracle's runs, coarse to fine: ``{"mean_spp", "rmse"}`` for each of ``prices``
    prices per sample (logarithmically from one that keeps every pixel at the first level
    to one that takes every pixel to the last). ``images``: (H, W, 3) per level, in the
    ladder's order; ``costs``: the samples a pixel traces to end at each
    (:func:`level_images`)."""
    errors = squared_errors(images, truth)                          # (levels, pixels)
    cost = np.asarray(costs, np.float64)[:, None]
    gains = np.abs(np.diff(errors, axis=0)) / np.maximum(np.diff(cost, axis=0), 1.0)
    top = max(float(gains.max()) if gains.size else 1.0, 1e-30) * 2
    runs = []
    for price in np.geomspace(top, top * 1e-12, prices):
        chosen = np.argmin(errors + price * cost, axis=0)
        pixels = np.arange(errors.shape[1])
        runs.append({"mean_spp": float(np.mean(cost[chosen, 0])),
                     "rmse": float(np.sqrt(np.mean(errors[chosen, pixels]) / 3.0))})
    return runs


def oracle_samples(images: list[np.ndarray], truth: np.ndarray, costs: list[int],
                   target: float) -> float | None:
    """Samples a pixel the oracle needs for RMSE ``target`` (interpolated in log-log
    between its runs), None when even every pixel at its best level misses it."""
    return value_at_crossing(oracle_curve(images, truth, costs), target, "mean_spp")


def price_for(rmse_at, target: float, low: float = 1e-16, high: float = 1e2,
              steps: int = 100) -> float:
    """The largest price per sample, bisected in the logarithm between ``low`` and ``high``,
    at which ``rmse_at(price)`` (a rule's RMSE, growing with the price) is at most
    ``target``: where a priced rule reaches an RMSE."""
    for _ in range(steps):
        price = (low * high) ** 0.5
        if rmse_at(price) > target:
            high = price
        else:
            low = price
    return low


def oracle_choice(errors: np.ndarray, costs: list[int], target: float) -> np.ndarray:
    """Each pixel's level (an index into ``costs``) in the oracle's run of RMSE ``target``:
    ``errors`` (levels, pixels) the squared errors summed over the colours, ``costs`` the
    samples a pixel traces to end at each level (:func:`level_images`)."""
    cost = np.asarray(costs, np.float64)[:, None]
    pixels = np.arange(errors.shape[1])
    choose = lambda price: np.argmin(errors + price * cost, axis=0)
    rmse_at = lambda price: float(np.sqrt(np.mean(errors[choose(price), pixels]) / 3.0))
    return choose(price_for(rmse_at, target))


def squared_errors(images: list[np.ndarray], truth: np.ndarray) -> np.ndarray:
    """(levels, pixels): each image's squared error against ``truth`` per pixel, summed over
    the colours, in float64."""
    truth = np.asarray(truth, np.float64)
    return np.stack([np.sum(np.square(np.asarray(i, np.float64) - truth), axis=-1).ravel()
                     for i in images])


class OracleScene(NamedTuple):
    """A scene file as the oracle's scripts measure it (:func:`oracle_scene`): the loaded
    whitted scene ``mitsuba``, the float64 reference ``truth`` (H, W, 3), and the oracle's
    level ``images``, their ``costs`` and ``errors`` (:func:`squared_errors`)."""
    mitsuba: object
    truth: np.ndarray
    images: list
    costs: list
    errors: np.ndarray

    def rmse(self, image) -> float:
        """RMSE of ``image`` (H, W, 3) against the truth, over pixels and colours."""
        return float(np.sqrt(np.mean(np.square(np.asarray(image, np.float64) - self.truth))))


def oracle_scene(path: str, size: int = 256, reference_spp: int = 256) -> OracleScene:
    """The scene file ``path`` resized to ``size`` (point-sampled), its reference at
    ``reference_spp`` (cached), and its level images from 1 to 81 samples a pixel
    (:func:`level_images`)."""
    from pathlib import Path
    import mimarble
    from mimarble.bench.timing import converged
    from mimarble.mitsuba import to_mitsuba
    from mimarble.runtime import files
    from mimarble.scene.edits import resized
    scene = resized(mimarble.scene.load(path), size)
    truth = converged(scene, reference_spp, Path(files.cache_folder())).astype(np.float64)
    mitsuba = mimarble.mi.load_dict(to_mitsuba(scene, spp=1))
    images, costs = level_images(mitsuba, 1, 81)
    return OracleScene(mitsuba, truth, images, costs, squared_errors(images, truth))
