"""The pass loop: pixels traced in passes of a bounded number of samples, summed per pixel.

A render, its edge samples and the search for silhouettes all trace ``spp``
samples in each of a set of pixels (every pixel of the image, or a list of
them) and need per pixel only the sum of the samples' radiance and the
smallest and largest id of the first shape they hit. :func:`trace_in_passes`
plans passes of at most :data:`PASS_SAMPLES` samples — runs of whole pixels,
or, when one pixel has more samples than a pass, runs of that pixel's samples
— traces each with a :class:`~mimarble.mitsuba.pixel_tracer.PixelTracer` and
reduces it in Dr.Jit, so that memory is a pass's working set whatever the
image size and spp, and only values per pixel come back to NumPy.

Pass offsets and sizes are opaque, so every pass and spp of a scene runs one
compiled kernel (a new image size compiles another: docs/design-decisions.md,
"Start-up and the kernel cache").
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .. import environment

dr, mi = environment.import_drjit_and_mitsuba()

#: Samples traced at once. A lane of fig11a costs about 85 bytes in whitted and in
#: path mode (measured), so a pass of 2²² samples holds ~0.35 GiB; larger images are
#: rendered in passes of whole pixels (docs/design-decisions.md, "Rendering").
PASS_SAMPLES = 1 << 22


class TracedPass(NamedTuple):
    """The pixels one pass completed, and how many samples it traced.

    ``pixels`` indexes the image's pixels (a slice, or an array of pixel
    indices); it is empty after a pass that took only some of a split pixel's
    samples, which the arrays then match. ``sums``: (len, 3) float64, each
    pixel's radiance summed over all of its spp samples (None when radiance
    was not traced); ``first_shape``, ``last_shape``: uint32, the smallest and
    largest id of the first shape hit among them, 0 for a miss (None unless
    asked for).
    """
    pixels: slice | np.ndarray
    samples: int
    sums: np.ndarray | None
    first_shape: np.ndarray | None
    last_shape: np.ndarray | None


def trace_in_passes(tracer, spp: int, pixels: np.ndarray | None = None, *,
                    with_radiance: bool = True, with_shapes: bool = False,
                    pass_samples: int | None = None, seed: int = 0):
    """Yield a :class:`TracedPass` per pass of ``spp`` samples in each pixel.

    ``pixels``: uint32 pixel indices, default every pixel of ``tracer``'s
    image in order. ``with_radiance``: trace the integrator (``tracer.trace``),
    else only the first shape hit (``tracer.first_shape``); ``with_shapes``:
    also reduce the first shape hit per pixel. ``pass_samples``: lanes per pass
    (default :data:`PASS_SAMPLES`). A pass's sampler seed (path mode) is its number
    plus ``seed`` times an odd 32-bit constant (Fibonacci hashing), modulo 2³², so that
    renders of different seeds draw different samples (seed 0: the pass's number).

    A pixel split over passes is summed in float64 in pass order and handed
    back whole, by the pass that takes its last samples.
    """
    pass_samples = PASS_SAMPLES if pass_samples is None else int(pass_samples)
    count = tracer.width * tracer.height if pixels is None else len(pixels)
    u32 = tracer.u32
    so_far = None                    # a split pixel's (sums, first, last) so far
    for index, (p0, q0, n_pixels, n_samples) in enumerate(_plan(count, spp, pass_samples)):
        lanes = n_pixels * n_samples
        lane = dr.arange(mi.UInt32, lanes)
        if pixels is None:                           # opaque offsets: one kernel for every pass
            pixel = u32(p0) + lane // u32(n_samples)
            sub = u32(q0) + lane % u32(n_samples)
        else:
            pixel = dr.gather(mi.UInt32, mi.UInt32(pixels[p0:p0 + n_pixels]),
                              lane // u32(n_samples))
            # Only the later passes of a split pixel start past sample 0.
            sub = lane % u32(n_samples) if q0 == 0 else u32(q0) + lane % u32(n_samples)
        if with_radiance:
            value, hit_shape = tracer.trace(pixel, sub, spp,
                                            (seed * 0x9E3779B1 + index) & 0xFFFFFFFF, with_shapes)
        else:
            value, hit_shape = None, tracer.first_shape(pixel, sub, spp)
        traced = _pixel_sums(value, hit_shape, lanes, n_samples)
        if n_samples < spp:                          # one pixel, over several passes
            so_far = _accumulate(so_far if q0 else None, traced)
            n_pixels = int(q0 + n_samples == spp)     # none until its last samples are in
            traced = tuple(None if x is None else x[:n_pixels] for x in so_far)
        span = slice(p0, p0 + n_pixels)
        yield TracedPass(span if pixels is None else pixels[span], lanes, *traced)


def _pixel_sums(radiance, shapes, lanes: int, n_samples: int):
    """(sums, first, last) of each run of ``n_samples`` lanes: the sums of ``radiance``
    (a Color3f per lane, or None) in float64 → (lanes/n_samples, 3); the smallest and
    largest of ``shapes`` (a UInt32 per lane, or None). None where its input is None.

    Reduced by Dr.Jit (``block_sum``, ``block_reduce``) after one kernel that computes
    every lane, so only values per pixel come back to NumPy; sums in float64, whose
    rounding is far below float32's.
    """
    if radiance is not None:
        radiance = mi.Color3d(radiance) + dr.zeros(mi.Color3d, lanes)   # constants: full width
    dr.eval(*(x for x in (radiance, shapes) if x is not None))         # one kernel for all
    if radiance is not None and n_samples > 1:
        radiance = dr.block_sum(radiance, n_samples)
    first = last = shapes
    if shapes is not None and n_samples > 1:
        first = dr.block_reduce(dr.ReduceOp.Min, shapes, n_samples)
        last = dr.block_reduce(dr.ReduceOp.Max, shapes, n_samples)
    return (None if radiance is None else np.array(radiance, dtype=np.float64).T,
            None if shapes is None else np.array(first, dtype=np.uint32),
            None if shapes is None else np.array(last, dtype=np.uint32))


def _accumulate(so_far, traced):
    """A split pixel's (sums, first, last) after one more pass's ``traced``: sums added
    in pass order, from 0.0, in float64; shape ids by min and max. ``so_far``: None at
    the pixel's first pass."""
    if so_far is None:
        so_far = (None if traced[0] is None else np.zeros_like(traced[0]),) + traced[1:]
    return tuple(None if old is None else combine(old, new)
                 for combine, old, new in zip((np.add, np.minimum, np.maximum), so_far, traced))


def _plan(pixels: int, spp: int, pass_samples: int):
    """(first pixel, first sample, pixel count, samples per pixel) of each pass over
    ``pixels`` pixels of ``spp`` samples: runs of whole pixels of at most ``pass_samples``
    samples (at least one pixel), or, when one pixel has more samples than that, runs of
    ``pass_samples`` samples of one pixel."""
    if pass_samples >= spp:
        step = pass_samples // spp
        for p0 in range(0, pixels, step):
            yield p0, 0, min(step, pixels - p0), spp
    else:
        for p0 in range(pixels):
            for q0 in range(0, spp, pass_samples):
                yield p0, q0, 1, min(pass_samples, spp - q0)
