"""Adaptive sampling in whitted mode: samples where the error is.

A first pass renders every pixel with ``spp`` = n² stratum centres, as a plain render
does. Then rounds: every pixel of the last round whose estimated error E exceeds
``threshold`` · n² is rendered again with (2n)² stratum centres (the last round:
``max_spp``'s), which replace its samples — so each pixel ends equal to a plain render's
at the spp it ended with. Only the pixels a round refined are candidates in the next.
Deterministic, like the rest of whitted mode.

Why a bar that grows with n: a round costs a pixel 4n² samples, so the error it removes
per sample falls as n grows; a bar of ``threshold`` · n spends samples where they remove the
most error per sample if E were exact, and ``threshold`` · n², which leaves deeper rounds
to fewer pixels still, was measured better (docs/design-decisions.md, "Adaptive
sampling"). At 1 spp the threshold is the estimated error in colour units.

The estimate of a pixel of n² samples, in linear colour units (the largest of the
three colours):

    E = DOUBT_WEIGHT · doubt / n²                                   every pixel
    E = max(E, CONTRAST_WEIGHT · contrast / n^1.5)                  on a silhouette

``doubt`` is the mean over the pixel's samples of whitted's doubt (``Whitted.shade``):
the marbles' own estimate of how wrong one sample of them can be there — |the filter's
colour − its other view of the footprint| (mimarble/texture/filters.py), large where the
colour changes across the footprint, 0 where it is smooth. It says where a sample can be
wrong, not whether the prefilter is: inside fine veins a prefiltered pixel is refined as a
point-sampled one is, and only a marble without noise (linear phase, where the prefilter is
exact) gives a prefiltered pixel no doubt. A silhouette pixel is one whose 3×3
neighbourhood sees more than one first-hit shape (the edge samples' test,
mimarble/mitsuba/rendering/silhouettes.py); its ``contrast`` is what its own samples and its
neighbours disagree on — the larger of its samples' range (high − low) and the range of
its 3×3 neighbourhood's means (POV-Ray's ``+A`` compares a pixel with its neighbours): a
sliver of a sphere between the stratum centres shows in the neighbours only. The powers
are those of the error of n×n stratum centres: 1/n² for a smooth integrand (the midpoint
rule), about n^−1.5 for an edge across the pixel (n of the n² cells cut, errors of random
sign). The weights were chosen by measurement (docs/benchmarks.md, "Adaptive sampling").

Textures without a second estimate (``rgb``, ``bitmap``) have doubt 0: their pixels are
refined on silhouettes only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mimarble.runtime import environment
from mimarble.runtime.progress import report
from mimarble.scene.model import samples_per_axis
from .loaded_scenes import LOADED
from .passes import Target, trace_in_passes
from .replay import scene_facts
from .silhouettes import silhouette_pixels
from mimarble.mitsuba.plugins.whitted import Whitted
from .window import Window

dr, mi = environment.import_drjit_and_mitsuba()

#: The estimate's weights (module docstring), chosen by measurement.
DOUBT_WEIGHT = 0.5
CONTRAST_WEIGHT = 0.25
#: Samples per pixel when ``max_spp`` is not given.
DEFAULT_MAX_SPP = 64


class AdaptiveRender(NamedTuple):
    """An adaptive render: ``image`` (H, W, 3) float32, as ``render_in_passes`` returns
    it; ``samples`` (H, W), each pixel's samples at the end; ``traced``, every sample
    traced for a pixel, replaced ones included (the cost; not the few a pass over a pixel
    list pads itself with, :func:`~mimarble.mitsuba.rendering.passes.padded_count`); ``rounds``, the
    passes over pixel lists after the first pass."""
    image: np.ndarray
    samples: np.ndarray
    traced: int
    rounds: int


def sample_levels(spp: int, max_spp: int) -> list[int]:
    """The spp of the first pass and of each round: n², (2n)², (4n)², … below ``max_spp``,
    then ``max_spp`` (both perfect squares, ``spp`` ≤ ``max_spp``)."""
    n, most = samples_per_axis(spp), samples_per_axis(max_spp)
    levels = [n]
    while levels[-1] < most:
        levels.append(min(2 * levels[-1], most))
    return [k * k for k in levels]


def estimated_errors(axis: int, doubt: np.ndarray, contrast: np.ndarray,
                     on_silhouette: np.ndarray) -> np.ndarray:
    """E of pixels of ``axis``² samples (module docstring), from their mean doubt,
    contrast and silhouette flags."""
    errors = (DOUBT_WEIGHT / axis ** 2) * doubt.astype(np.float64)
    silhouette = CONTRAST_WEIGHT / axis ** 1.5 * contrast.astype(np.float64)
    return np.where(on_silhouette, np.maximum(errors, silhouette), errors)


def neighbourhoods(pixels: np.ndarray, width: int, height: int) -> np.ndarray:
    """(9, len) indices of the 3×3 neighbourhood of each of ``pixels`` in a width × height
    image (clipped at its border: an edge pixel's own row or column again)."""
    rows, columns = np.divmod(pixels.astype(np.int64), width)
    return np.stack([np.clip(rows + dy, 0, height - 1) * width
                     + np.clip(columns + dx, 0, width - 1)
                     for dy in (-1, 0, 1) for dx in (-1, 0, 1)])


def neighbourhood_range(image: np.ndarray, around: np.ndarray) -> np.ndarray:
    """The largest over the colours of (max − min) of the (pixels, 3) ``image``'s means at
    each neighbourhood of ``around`` (:func:`neighbourhoods`)."""
    values = image[around]                                 # (9, len, 3)
    return (values.max(axis=0) - values.min(axis=0)).max(axis=-1)


def render_adaptive(mitsuba_scene, spp: int, threshold: float,
                    max_spp: int = DEFAULT_MAX_SPP, progress=False, crop=None,
                    pass_samples: int | None = None) -> AdaptiveRender:
    """Render a loaded whitted scene (JIT variants) adaptively: a first pass of ``spp``
    stratum centres, then rounds that refine every pixel whose estimated error is above
    ``threshold`` (linear colour units) up to ``max_spp`` (module docstring).

    ``crop`` ``(x0, y0, x1, y1)`` (checked by the caller): that window is traced with a
    ring of one pixel around it, so that its pixels' neighbourhoods are the image's in
    the first pass; a round's estimates at the window's border then see the ring's
    pixels only, so they can be refined otherwise than in the whole image. ``progress``:
    as ``mimarble.render`` takes it (the total grows with each round)."""
    if not isinstance(mitsuba_scene.integrator(), Whitted):
        raise ValueError(f"render_adaptive: the scene's integrator is "
                         f"{type(mitsuba_scene.integrator()).__name__}; adaptive sampling "
                         f"needs mimarble's 'whitted' (its stratum centres and doubts)")
    target = Target.of(mitsuba_scene, "whitted", LOADED.parameters_of(mitsuba_scene))
    Whitted.prepare_doubts(mitsuba_scene)
    facts = scene_facts(target.scene, target.params)
    traced_pixels = Window.of(target, crop, ring=1)
    width, height = traced_pixels.width, traced_pixels.height
    count = width * height
    image = np.empty((count, 3), dtype=np.float32)
    shapes = np.zeros((2, count), dtype=np.uint32)
    doubt = np.zeros(count, dtype=np.float32)
    spread = np.zeros(count, dtype=np.float32)
    samples = np.zeros(count, dtype=np.int64)
    done = report(progress, "render")
    traced, total = 0, count * spp
    done(0, total + 1)                         # open until the last round has said its size
    levels = sample_levels(spp, max_spp)
    candidates = np.arange(count, dtype=np.int64)          # local indices
    rounds = 0
    for level, level_spp in enumerate(levels):
        pixels = None if level == 0 else traced_pixels.global_(candidates)
        if level == 0 and not traced_pixels.whole:
            pixels = traced_pixels.pixels
        last = level + 1 == len(levels)    # no estimates: nothing reads them after it
        for traced_pass in trace_in_passes(target, level_spp, pixels, with_shapes=not last,
                                           with_estimates=not last, pass_samples=pass_samples,
                                           key=facts):
            local = traced_pixels.local(traced_pass.pixels)
            image[local] = traced_pass.means
            samples[local] = level_spp
            estimates = traced_pass.estimates
            if estimates is not None:
                shapes[0, local] = traced_pass.first_shape
                shapes[1, local] = traced_pass.last_shape
                doubt[local] = estimates.doubt
                spread[local] = estimates.spread
            traced += traced_pass.samples
            done(traced, total + 1)
        rounds += level > 0
        if last:
            break
        edge = np.zeros(count, dtype=bool)
        edge[silhouette_pixels(shapes, width, height)] = True
        edge = edge[candidates]
        contrast = np.zeros(len(candidates), dtype=np.float32)
        edges = candidates[edge]
        contrast[edge] = np.maximum(
            spread[edges], neighbourhood_range(image, neighbourhoods(edges, width, height)))
        axis = samples_per_axis(level_spp)
        errors = estimated_errors(axis, doubt[candidates], contrast, edge)
        candidates = candidates[errors > threshold * axis ** 2]
        if len(candidates) == 0:
            break
        total = traced + len(candidates) * levels[level + 1]
    done(traced, traced)
    window = traced_pixels.window_of
    return AdaptiveRender(window(image.reshape(height, width, 3)),
                          window(samples.reshape(height, width, 1))[..., 0], traced, rounds)
