"""Silhouettes, and the edge samples that resolve them.

Inside a sphere a pixel's samples all see one surface, whose texture the
marble's own filter can average over the pixel (mimarble/texture/prefilter.py); a
pixel that a silhouette crosses sees two surfaces, or a surface and the
background, a step no texture filter smooths and a few samples render poorly. A pixel is on a
silhouette when the first shapes hit by its own samples and by its 8
neighbours' are not all the same (a miss counts as shape 0): the neighbours
matter at 1 spp, where a pixel's one sample cannot see that a sphere covers
part of it. Those pixels are traced again with ``edge_spp`` = m² stratum
centres, which replace all of their samples (docs/design-decisions.md, "Edge
samples").
"""

from __future__ import annotations

import numpy as np

from .passes import Target, trace_in_passes


def silhouette_pixels(shapes: np.ndarray, width: int, height: int) -> np.ndarray:
    """Indices of the pixels whose 3×3 neighbourhood holds more than one first-hit shape.

    ``shapes``: (2, pixels), each pixel's smallest and largest shape id over its
    samples (0 for a miss)."""
    lo = shapes[0].reshape(height, width)
    hi = shapes[1].reshape(height, width)
    lo = np.pad(lo, 1, mode="edge")
    hi = np.pad(hi, 1, mode="edge")
    least, most = lo[1:-1, 1:-1].copy(), hi[1:-1, 1:-1].copy()
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            np.minimum(least, lo[dy:dy + height, dx:dx + width], out=least)
            np.maximum(most, hi[dy:dy + height, dx:dx + width], out=most)
    return np.flatnonzero(least != most).astype(np.uint32)


def edge_sample_passes(target: Target, shapes: np.ndarray, edge_spp: int,
                       pass_samples: int | None = None, window=None):
    """(samples, passes): the edge pass of an image whose first passes found ``shapes``
    ((2, pixels), as for :func:`silhouette_pixels`). ``passes`` traces ``edge_spp``
    stratum centres in every silhouette pixel (whitted mode), ``samples`` in all.

    ``window`` (a crop: mimarble/mitsuba/rendering/window.py's ``Window``): ``shapes`` are of its
    traced pixels, the crop and a ring of one pixel around it within the image, so that
    each crop pixel's 3×3 neighbourhood is the whole image's; only the crop's silhouette
    pixels are traced again."""
    if window is None or window.whole:
        edges = silhouette_pixels(shapes, target.width, target.height)
    else:
        local = silhouette_pixels(shapes, window.width, window.height)
        edges = window.global_(local[window.contains(local)])
    return len(edges) * edge_spp, trace_in_passes(target, edge_spp, edges,
                                                  pass_samples=pass_samples)


def edge_mask(mitsuba_scene, spp: int = 16) -> np.ndarray:
    """(H, W) bool: the pixels :func:`~mimarble.mitsuba.rendering.render.render_in_passes` gives
    edge samples, found with ``spp`` stratum centres per pixel, tracing only the
    first shape hit (the benchmark's "edge" pixels; the rest is the interior)."""
    target = Target.of(mitsuba_scene, "whitted")
    pixels = target.width * target.height
    shapes = np.zeros((2, pixels), dtype=np.uint32)
    for traced in trace_in_passes(target, spp, with_radiance=False, with_shapes=True):
        shapes[0, traced.pixels] = traced.first_shape
        shapes[1, traced.pixels] = traced.last_shape
    mask = np.zeros(pixels, dtype=bool)
    mask[silhouette_pixels(shapes, target.width, target.height)] = True
    return mask.reshape(target.height, target.width)
