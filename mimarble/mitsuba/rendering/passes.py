"""The pass loop: pixels traced in passes of a bounded number of samples, summed per pixel.

A render, its edge samples and the search for silhouettes all trace ``spp``
samples in each of a set of pixels (every pixel of the image, or a list of
them) and need per pixel only the sum of the samples' radiance and the
smallest and largest id of the first shape they hit. :func:`trace_in_passes`
plans passes of at most :data:`PASS_SAMPLES` samples — runs of whole pixels,
or, when one pixel has more samples than a pass, runs of that pixel's samples
— traces each with a :class:`~mimarble.mitsuba.rendering.pixel_tracer.PixelTracer` and
reduces it in Dr.Jit, so that memory is a pass's working set whatever the
image size and spp, and only values per pixel come back to NumPy.

A pass is traced once and then replayed from its recording (mimarble/mitsuba/
replay.py): its numbers (offsets, samples, seed) are opaque inputs, and its width
and samples per pixel part of the recording's key, so a scene's passes replay one
recording per pass width and spp, and compile one kernel for every spp (a new
image size compiles another: docs/design-decisions.md, "Start-up and the kernel
cache").
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import largest_component
from .pixel_tracer import PassNumbers, PixelTracer, nested_stratum
from .replay import Recorded, scene_facts

dr, mi = environment.import_drjit_and_mitsuba()

#: Samples traced at once. A lane of fig11a costs about 85 bytes in whitted and in
#: path mode (measured), so a pass of 2²² samples holds ~0.35 GiB; larger images are
#: rendered in passes of whole pixels (docs/design-decisions.md, "Rendering").
PASS_SAMPLES = 1 << 22


class Target(NamedTuple):
    """What passes trace: a loaded scene, in ``whitted`` or ``path`` mode, drawing from
    ``sampler`` (path mode), into an image of ``width`` × ``height`` pixels; ``params``: the
    scene's ``mi.traverse`` if one is kept (the loaded scenes keep theirs), else None."""
    scene: object
    mode: str
    sampler: object
    width: int
    height: int
    params: object = None

    @classmethod
    def of(cls, scene, mode: str, params=None) -> "Target":
        film = scene.sensors()[0].film()
        width, height = (int(x) for x in film.crop_size())
        return cls(scene, mode, _sampler(scene, mode), width, height, params)


#: Path mode's sampler for each scene's sensor sampler: a clone made once (a new one
#: per render would be a new instance in Dr.Jit's registry, which a recording sees),
#: held with the sampler it was cloned from, so that neither id is reused while kept.
_CLONES: dict = {}


def _sampler(scene, mode: str):
    original = scene.sensors()[0].sampler()
    if mode == "whitted":                      # draws nothing: the sensor's own will do
        return original
    if id(original) not in _CLONES:
        if len(_CLONES) >= 4:
            _CLONES.pop(next(iter(_CLONES)))       # the least recently used
        _CLONES[id(original)] = (original, original.clone())
    _CLONES[id(original)] = _CLONES.pop(id(original))
    return _CLONES[id(original)][1]


def stratify(target: Target, samples: int, spp: int) -> bool:
    """Set ``target``'s sampler (path mode) to stratify a pass's lanes across their pixel's
    samples; whether it does.

    Mitsuba's samplers number a lane's sample ``sample_index · w + lane mod w`` (w:
    ``set_samples_per_wavefront``) and seed one sequence per run of w lanes
    (``Sampler::compute_per_sequence_seed``). A pass's lanes are pixel-major, ``samples``
    per pixel, so w = ``samples`` makes a pixel's lanes samples 0 … spp − 1 of one
    stratified sequence (``stratified``: each dimension a per-pixel permutation of spp
    jittered strata; ``multijitter``: the same with multi-jittered 2-D points). That holds
    when the pass holds all of the pixel's samples (``samples`` = ``spp``) and the sampler
    takes spp samples as they are (``stratified``: a square; ``multijitter``: a ⌈spp/r⌉·r
    grid, r = ⌊√spp⌋); otherwise w = 1: one lane, one sequence of which it draws sample 0,
    a uniform point (the samples are then independent, as before stratification). Whitted
    mode's sampler draws nothing, and ``independent`` draws the same either way: both are
    left as they are (opaque path-mode images unchanged bit for bit)."""
    sampler = target.sampler
    if target.mode == "whitted" or sampler.class_name() == "IndependentSampler":
        return False
    if 1 < samples == spp and sampler.sample_count() != spp:
        level = mi.log_level()
        mi.set_log_level(mi.LogLevel.Error)      # its warning that it rounds spp up
        try:
            sampler.set_sample_count(spp)
        finally:
            mi.set_log_level(level)
    stratified = 1 < samples == spp and sampler.sample_count() == spp
    sampler.set_samples_per_wavefront(samples if stratified else 1)
    return stratified


def stratified_mark(stratified: bool) -> tuple:
    """What a stratified pass adds to its recording's key: its sampler draws a pixel's
    samples as one sequence (samples per wavefront), other numbers than a pass without."""
    return (True,) if stratified else ()


class TracedPass(NamedTuple):
    """The pixels one pass completed, and how many of their samples it traced (a pass
    over a pixel list also traces the few it pads the list with; they are not counted).

    ``pixels`` indexes the image's pixels (a slice, or an array of pixel
    indices); it is empty after a pass that took only some of a split pixel's
    samples, which the arrays then match. ``means``: (len, 3) float32, each
    pixel's radiance summed over all of its spp samples (float32 with compensation,
    the pair added in float64: :func:`compensated_block_sum`), divided by
    the spp and rounded once (None when radiance was not traced);
    ``first_shape``, ``last_shape``: uint32, the smallest and largest id of the
    first shape hit among them, 0 for a miss (None unless asked for).
    """
    pixels: slice | np.ndarray
    samples: int
    means: np.ndarray | None
    first_shape: np.ndarray | None
    last_shape: np.ndarray | None
    estimates: "Estimates | None" = None


class Estimates(NamedTuple):
    """What a pass with estimates finds about each pixel's error, beside its mean (for
    adaptive sampling, mimarble/mitsuba/rendering/adaptive.py), float32: ``doubt``, the mean over
    its samples of whitted's doubt (``Whitted.shade``); ``spread``, the largest over the
    colours of the range (largest − least) of its samples' radiance."""
    doubt: np.ndarray
    spread: np.ndarray


def trace_in_passes(target: Target, spp: int, pixels: np.ndarray | None = None, *,
                    with_radiance: bool = True, with_shapes: bool = False,
                    with_estimates: bool = False, pass_samples: int | None = None,
                    seed: int = 0, key: tuple | None = None):
    """Yield a :class:`TracedPass` per pass of ``spp`` samples in each pixel.

    ``pixels``: uint32 pixel indices, default every pixel of ``target``'s
    image in order. ``with_radiance``: trace the integrator (``PixelTracer.trace``),
    else only the first shape hit (``PixelTracer.first_shape``); ``with_shapes``:
    also reduce the first shape hit per pixel; ``with_estimates`` (whitted mode, with
    radiance and shapes): also the pixel's :class:`Estimates`. ``pass_samples``: lanes
    per pass (default :data:`PASS_SAMPLES`). A pass's sampler seed (path mode) is its number
    plus ``seed`` times an odd 32-bit constant (Fibonacci hashing), modulo 2³², so that
    renders of different seeds draw different samples (seed 0: the pass's number).
    ``key``: :func:`~mimarble.mitsuba.rendering.replay.scene_facts` of the target, when the caller
    has it (a render's several calls); else found here.

    A pixel split over passes is summed in float64 in pass order and handed
    back whole, by the pass that takes its last samples. A pass over a list of pixels
    traces a few more (the last one again, up to :func:`padded_count`) and keeps what it
    asked for, so that lists of many lengths replay a few recordings.
    """
    pass_samples = PASS_SAMPLES if pass_samples is None else int(pass_samples)
    count = target.width * target.height if pixels is None else len(pixels)
    key, inputs = scene_facts(target.scene, target.params) if key is None else key
    so_far = None                    # a split pixel's (sums, first, last, …) so far
    for index, (p0, q0, n_pixels, n_samples) in enumerate(_plan(count, spp, pass_samples)):
        numbers = PassNumbers(p0, q0, n_samples, spp, (seed * 0x9E3779B1 + index) & 0xFFFFFFFF,
                              target.mode == "whitted")
        subset, traced_pixels = None, n_pixels
        if pixels is not None:
            traced_pixels = padded_count(n_pixels, max(pass_samples // n_samples, 1))
            chunk = pixels[p0:p0 + n_pixels]
            padded = np.concatenate([chunk, np.full(traced_pixels - n_pixels, chunk[-1],
                                                    dtype=np.uint32)])
            # A Dr.Jit copy, not a view of NumPy's memory, whose alignment Dr.Jit's
            # recordings tell apart (a fresh buffer could record again).
            subset = mi.UInt32(padded) + dr.opaque(mi.UInt32, 0)
        lanes = traced_pixels * n_samples
        asked = n_pixels * n_samples                 # the samples it reports (not the padding)
        split = n_samples < spp                      # one pixel, over several passes
        stratified = stratify(target, n_samples, spp)
        values, first, last, estimates = _pass_function(target.scene)(
            (key, target.mode, lanes, n_samples, subset is None, with_radiance, with_shapes,
             with_estimates, split) + stratified_mark(stratified), target.scene, inputs,
            target.sampler, lanes, n_samples, numbers, subset, with_radiance, with_shapes,
            with_estimates, split, target.mode)
        # Views of the Dr.Jit arrays (no copy): means interleaved per pixel, or a split
        # pixel's sums as Color3d (3, 1); the first n_pixels of a padded list.
        traced = (None if values is None else
                  values.numpy().T.astype(np.float64) if split else
                  values.numpy().reshape(-1, 3)[:n_pixels],
                  None if first is None else first.numpy()[:n_pixels],
                  None if last is None else last.numpy()[:n_pixels])
        if estimates is not None and split:   # doubt sums, lows and highs, per colour
            traced += tuple(x.numpy().astype(np.float64) if k == 0 else x.numpy().T
                            for k, x in enumerate(estimates))
        elif estimates is not None:           # the pixels' mean doubt and spread
            traced += tuple(x.numpy()[:n_pixels] for x in estimates)
        if split:
            so_far = _accumulate(so_far if q0 else None, traced)
            n_pixels = int(q0 + n_samples == spp)     # none until its last samples are in
            traced = tuple(None if x is None else x[:n_pixels] for x in so_far)
            if traced[0] is not None:
                traced = ((traced[0] / spp).astype(np.float32),) + traced[1:]
            if estimates is not None:
                doubt_sums, low, high = traced[3:]
                traced = traced[:3] + ((doubt_sums / spp).astype(np.float32),
                                       (high - low).max(axis=-1).astype(np.float32))
        span = slice(p0, p0 + n_pixels)
        yield TracedPass(span if pixels is None else pixels[span], asked, *traced[:3],
                         Estimates(*traced[3:]) if estimates is not None else None)


def samples_pass_key(scene_key, mode: str, lanes: int, count: int) -> tuple:
    """The recording key of a pass of :func:`trace_samples` over ``lanes`` lanes of
    ``count`` samples a pixel: the radiance, summed per pixel (split), without shapes or
    estimates. The studio reads it to tell a replay from a new recording."""
    return (scene_key, mode, lanes, count, True, True, False, False, True)


def trace_samples(target: Target, spp: int, first_sample: int, count: int, *,
                  seed: int = 0, key: tuple | None = None) -> np.ndarray:
    """The radiance of samples ``first_sample … first_sample + count − 1`` of ``spp`` in
    every pixel of ``target``, summed per pixel: float64 (pixels, 3), not divided.

    What progressive refinement adds up (the studio, mimarble/studio/): a render of
    ``spp`` samples made a run of samples at a time, each run its own passes. Sample
    ``k`` is the one a render at ``spp`` takes there — whitted mode the centre of stratum
    ``k`` of the n×n grid, with the ray differentials of ``spp`` — so the runs'
    sums added up over ``0 … spp − 1`` and divided by ``spp`` are that render's image to
    float64 rounding of the per-run sums (the render sums all of a pixel's samples in
    one compensated float32 sum; each run here is one such sum, the runs added in
    float64). Path mode draws each run from the sampler seeded with ``seed`` (each run
    wants its own), per pass. Passes of whole pixels of at most :data:`PASS_SAMPLES`
    lanes, recorded and replayed as :func:`trace_in_passes`' (keys with ``split``: the
    sums come back undivided)."""
    if not (0 <= first_sample and count >= 1 and first_sample + count <= spp):
        raise ValueError(f"samples {first_sample}..{first_sample + count - 1} are not "
                         f"among a pixel's {spp}")
    pixels = target.width * target.height
    key, inputs = scene_facts(target.scene, target.params) if key is None else key
    sums = np.empty((pixels, 3), dtype=np.float64)
    step = max(PASS_SAMPLES // count, 1)
    for index, p0 in enumerate(range(0, pixels, step)):
        n_pixels = min(step, pixels - p0)
        numbers = PassNumbers(p0, first_sample, count, spp,
                              (seed * 0x9E3779B1 + index) & 0xFFFFFFFF, target.mode == "whitted")
        lanes = n_pixels * count
        stratified = stratify(target, count, spp)
        values = _pass_function(target.scene)(
            samples_pass_key(key, target.mode, lanes, count) + stratified_mark(stratified),
            target.scene,
            inputs, target.sampler, lanes, count, numbers, None, True, False, False, True,
            target.mode)[0]
        sums[p0:p0 + n_pixels] = values.numpy().T
    return sums


class PassSums(NamedTuple):
    """What one pass of :func:`trace_sums` traced, in Dr.Jit arrays of one lane per pixel
    (and the padding's: only the first ``count`` are the list's): ``start``, the index in
    the pixel list of its first pixel, ``count`` pixels of ``samples`` samples each;
    ``sums`` (Color3d), their samples' radiance summed (as
    :func:`compensated_block_sum` sums them); with estimates (else None) ``first``, ``last``
    (UInt32: the smallest and largest id of the first shape hit), ``doubt_sums``
    (Float64) and the least and largest radiance ``low``, ``high`` (Color3f). A pixel
    split over passes has a partial sum (and extremes) in each: sums add, extremes take
    their minimum and maximum."""
    start: int
    count: int
    samples: int
    sums: object
    first: object = None
    last: object = None
    doubt_sums: object = None
    low: object = None
    high: object = None


def trace_sums(target: Target, spp: int, pixels, count: int, *, with_estimates: bool,
               doubts: bool = True, parent_axis: int = 0, per_cell: int = 8,
               cell_offset: int = 0, pass_samples: int | None = None,
               key: tuple | None = None):
    """Yield a :class:`PassSums` per pass over ``count`` pixels (``pixels``: a Dr.Jit
    UInt32 list of whole-image indices, or None: every pixel in order), all on the device:
    the adaptive rounds' passes (mimarble/mitsuba/rendering/adaptive.py), which add or
    replace what a pixel holds without a copy to the host.

    ``spp`` = (3m)² with ``parent_axis`` = m > 0: the pixels' samples are on the 3m grid,
    each cell of the m grid holding its centre and ``cell_offset`` others, and ``per_cell``
    more of each cell's are traced (``nested_stratum``; a pixel list only); else ``spp``
    stratum centres.
    A pass over a list traces a few pixels more (its last one again, up to
    :func:`padded_count`), so that lists of many lengths replay a few recordings.
    ``doubts``: estimates with whitted's doubts (else ``doubt_sums`` is None and the
    kernel is the plain one's)."""
    pass_samples = PASS_SAMPLES if pass_samples is None else int(pass_samples)
    doubts = doubts and with_estimates
    key, inputs = scene_facts(target.scene, target.params) if key is None else key
    traced_spp = parent_axis ** 2 * per_cell if parent_axis else spp
    for index, (p0, q0, n_pixels, n_samples) in enumerate(_plan(count, traced_spp,
                                                                pass_samples)):
        numbers = PassNumbers(p0, q0, n_samples, spp, index, target.mode == "whitted",
                              cell_offset)
        nested = (parent_axis, per_cell) if parent_axis else None
        subset, traced_pixels = None, n_pixels
        if pixels is not None:
            traced_pixels = padded_count(n_pixels, max(pass_samples // n_samples, 1))
            # The list's pixels p0 … p0 + n − 1, the last one again up to the padded size;
            # offsets opaque: one small kernel for every round.
            at = dr.minimum(dr.arange(mi.UInt32, traced_pixels),
                            dr.opaque(mi.UInt32, n_pixels - 1)) + dr.opaque(mi.UInt32, p0)
            subset = dr.gather(mi.UInt32, pixels, at)
            dr.eval(subset)
        lanes = traced_pixels * n_samples
        stratified = stratify(target, 0 if nested else n_samples, spp)
        values, first, last, estimates = _pass_function(target.scene)(
            (key, target.mode, lanes, n_samples, subset is None, True, with_estimates,
             with_estimates, True, nested, doubts) + stratified_mark(stratified),
            target.scene, inputs,
            target.sampler, lanes, n_samples, numbers, subset, True, with_estimates,
            with_estimates, True, target.mode, nested, doubts)
        doubt_sums = low = high = None
        if estimates is not None:
            doubt_sums, low, high = estimates
        yield PassSums(p0, n_pixels, n_samples, values, first, last, doubt_sums, low, high)


def padded_count(count: int, most: int) -> int:
    """``count`` pixels rounded up to one of a few sizes — 16, then steps of a quarter
    octave (at most 19 % more) — but not above ``most`` (nor below ``count``): passes
    over pixel lists of any length replay one recording per size."""
    size = 16 if count <= 16 else math.ceil(2.0 ** (math.ceil(4.0 * math.log2(count)) / 4.0))
    return max(count, min(size, most))


def _trace_pass(key: tuple, scene, inputs: tuple, sampler, lanes: int, n_samples: int,
                numbers: PassNumbers, subset, with_radiance: bool, with_shapes: bool,
                with_estimates: bool, split: bool, mode: str, nested: tuple | None = None,
                doubts: bool = True):
    """One pass, in Dr.Jit: (values, first, last, estimates) of each run of ``n_samples``
    lanes of ``lanes`` — the radiance summed (:func:`compensated_block_sum`: float64 per
    pixel), then (unless ``split``: the pass
    holds only some of one pixel's samples) divided by ``n_samples`` and rounded to
    float32, the pixels' RGB interleaved in one Float (``split``: the sums, a Color3d); the
    smallest and largest id of the first shape hit (UInt32); with ``with_estimates``, the
    mean doubt (float32) and the spread (:class:`Estimates`; ``split``: the doubt's sum,
    the least and the largest radiance, Color3f); None where not asked for.
    Lane k is sample
    ``first_sample + k mod n`` of pixel ``first_pixel + ⌊k / n⌋`` (n = ``numbers.samples``),
    or of pixel ``subset[⌊k / n⌋]``; with ``nested`` = (m, per cell), an adaptive round
    that keeps the pixel's samples of the level before, sample index s is the s-th new
    stratum (:func:`~mimarble.mitsuba.rendering.pixel_tracer.nested_stratum`). Estimates without
    ``doubts`` leave the doubt out (None; the radiance's extremes and the shapes only),
    and the kernel is the plain one's.

    Recorded and replayed (:class:`~mimarble.mitsuba.rendering.replay.Recorded`): everything it
    reads is an argument — the scene, what it does not hold (``inputs``:
    :func:`~mimarble.mitsuba.rendering.replay.scene_facts`), the opaque ``numbers`` and ``subset``;
    ``key`` (the scene's key from :func:`~mimarble.mitsuba.rendering.replay.scene_facts`, with the
    mode, the widths and the switches) selects the recording. One kernel computes every lane, the same for every
    spp, then :func:`compensated_block_sum` makes the values per pixel — with estimates,
    the same loop finds the extremes too (``extremes_of``), without them Dr.Jit's
    ``block_reduce`` finds the shapes' — and a last kernel their means. The samples stay
    in float32 and are summed
    with Neumaier's compensation (:func:`compensated_block_sum`), their pair (sum,
    compensation) added and divided per pixel in float64: float64 arithmetic once per
    pixel, never per sample (a consumer GPU runs it at 1/32–1/64 of float32's rate), with
    a rounding far below float32's, as the float64 sums it replaced.
    """
    tracer = PixelTracer(scene, mode, None if sampler is None else sampler.clone())
    lane = dr.arange(mi.UInt32, lanes)
    pixel = numbers.first_pixel + lane // numbers.samples if subset is None else \
        dr.gather(mi.UInt32, subset, lane // numbers.samples)
    sub = numbers.first_sample + lane % numbers.samples
    if nested:      # n_samples a literal here (a key of its own): no scalar divisions
        pixel = dr.gather(mi.UInt32, subset, lane // n_samples)
        row = pixel // tracer.columns
        sub = nested_stratum(numbers.first_sample + (lane - (lane // n_samples) * n_samples),
                             *nested, numbers.cell_offset, row + (pixel - row * tracer.columns))
    doubt = colour = None
    if with_estimates and doubts:
        colour, shapes, doubt = tracer.trace_with_doubts(pixel, sub, numbers)
        colour = colour + dr.zeros(mi.Color3f, lanes)                   # constants: full width
        doubt = mi.Float(doubt) + dr.zeros(mi.Float, lanes)
        radiance = mi.Color3f(colour)
    elif with_estimates:
        colour, shapes = tracer.trace(pixel, sub, numbers, True)
        colour = mi.Color3f(colour) + dr.zeros(mi.Color3f, lanes)       # constants: full width
        radiance = mi.Color3f(colour)
    elif with_radiance:
        radiance, shapes = tracer.trace(pixel, sub, numbers, with_shapes)
        radiance = mi.Color3f(radiance) + dr.zeros(mi.Color3f, lanes)   # constants: full width
    else:
        radiance, shapes = None, tracer.first_shape(pixel, sub, numbers)
    dr.eval(*(x for x in (radiance, shapes, doubt, colour) if x is not None))  # one kernel
    extremes = None
    if with_estimates and n_samples > 1:
        # The shapes' and colours' extremes found by the sum's own loop: one kernel.
        radiance, extremes = compensated_block_sum(radiance, n_samples, numbers.samples,
                                                   extremes_of=(shapes, colour))
    elif radiance is not None:
        radiance = compensated_block_sum(radiance, n_samples, numbers.samples)  # Color3d
    if radiance is not None and not split:
        # A true division by an opaque count (not a product with its reciprocal), so the
        # mean is rounded as NumPy's float64 division and float32 cast round it.
        mean = mi.Color3f(radiance / mi.Float64(numbers.samples))
        radiance = dr.ravel(mean, order="F")          # r0 g0 b0 r1 …: NumPy's (pixels, 3)
    first = last = shapes
    if extremes is not None:
        first, last = extremes[0]
    elif shapes is not None and n_samples > 1:
        first = dr.block_reduce(dr.ReduceOp.Min, shapes, n_samples)
        last = dr.block_reduce(dr.ReduceOp.Max, shapes, n_samples)
    estimates = None
    if with_estimates:
        low, high = (colour, colour) if extremes is None else extremes[1]
        if doubt is not None:
            doubt = compensated_block_sum(doubt, n_samples, numbers.samples)   # Float64
        if split:        # summed and combined over the pixel's passes (NumPy, PixelState)
            estimates = (doubt, low, high)
        else:            # one mean doubt and one spread per pixel come back
            spread = high - low
            estimates = (mi.Float(doubt / mi.Float64(numbers.samples)),
                         largest_component(spread))
    return radiance, first, last, estimates


#: :func:`_trace_pass` recorded once per kernel key and replayed (:class:`Recorded`).
traced_pass = Recorded(_trace_pass)


def compensated_block_sum(values, block: int, opaque_block=None, extremes_of: tuple = ()):
    """The sum of each run of ``block`` consecutive lanes of ``values`` (a float32 Float or
    Color3f), as float64 (Float64 or Color3d, one lane per run): Neumaier's compensated
    summation in float32, in lane order — s ← s + x, c ← c + ((s_old − s) + x) where
    |s_old| ≥ |x|, else c ← c + ((x − s) + s_old) — whose pair s + c holds the sum to
    O(n·ε²)·Σ|x| (ε = 2⁻²⁴), then s + c in float64.

    The samples are summed scaled by 2⁻ᵉ, 2ᵉ ≥ ``block``, and the float64 pair scaled back
    by 2ᵉ: powers of two scale exactly, so the sum is the unscaled one's bits wherever
    neither underflows (|x| ≥ 2⁻¹²⁶⁺ᵉ), and the float32 total, at most max|x|, cannot
    overflow where float64 would not (the sum of finite samples up to float32's largest
    stays finite, as a float64 sum does). Where a sample is ±∞ or NaN the total is, and
    the compensation (∞ − ∞) is left out: the sum is what float64 gives.

    Dr.Jit's simplifications keep the compensation: its FastMath folds only products with
    literal zeros, and LLVM and PTX are given no reassociation. One kernel, a loop of
    ``block`` steps over the runs; ``opaque_block``: ``block`` as an opaque UInt32, which
    the kernel reads instead (and the scales as opaque values), so that every ``block``
    (the spp) runs the same compiled kernel.

    ``extremes_of``: arrays of the same lanes (UInt32 ids, Color3f colours) whose least
    and largest value in each run the same loop finds; then ``(sum, [(least, largest) for
    each array])`` is returned: one kernel, where ``dr.block_reduce`` launches one per
    reduction and per colour (an adaptive round's pass: eight, docs/design-decisions.md,
    "Adaptive samples: the pass's fixed cost"). The sum is the same either way."""
    wide = mi.Color3d if dr.depth_v(values) > 1 else mi.Float64
    if block == 1 and not extremes_of:
        # A run of one sample: the loop below would give 0 + x, widened — x itself, but
        # −0 made +0 (an opaque zero: Dr.Jit folds away the addition of a literal one).
        # No loop, so no kernel of its own: it joins whatever reads the sums next.
        return wide(values) + dr.opaque(mi.Float64, 0.0)
    kind = type(values)
    runs = dr.width(values) // block
    exponent = max(block - 1, 0).bit_length()            # 2^exponent ≥ block
    down, up = 2.0 ** -exponent, 2.0 ** exponent
    steps = block
    if opaque_block is not None:
        steps = opaque_block
        down, up = dr.opaque(mi.Float, down), dr.opaque(mi.Float64, up)
    start = dr.arange(mi.UInt32, runs) * steps
    k = dr.zeros(mi.UInt32, runs)
    total, compensation = dr.zeros(kind, runs), dr.zeros(kind, runs)

    # Each array's least and largest so far, from the ends of its type's range.
    bounds = [(dr.full(type(a), _most(type(a)), runs), dr.full(type(a), _least(type(a)), runs))
              for a in extremes_of]

    def add(k, total, compensation, *ranges):
        x = dr.gather(kind, values, start + k) * down
        new_total = total + x
        lost = dr.select(dr.abs(total) >= dr.abs(x), (total - new_total) + x,
                         (x - new_total) + total)
        widened = []
        for array, least, largest in zip(extremes_of, ranges[0::2], ranges[1::2]):
            y = dr.gather(type(array), array, start + k)
            # A NaN sample is skipped (a comparison with it is false), as Dr.Jit's block
            # reductions skip it on every back end; dr.minimum would carry it on LLVM.
            widened += [dr.select(y < least, y, least), dr.select(y > largest, y, largest)]
        return (k + 1, new_total, compensation + lost, *widened)

    state = (k, total, compensation, *(x for pair in bounds for x in pair))
    _, total, compensation, *ranges = dr.while_loop(state, lambda k, *_: k < steps, add)
    pair = dr.select(dr.isfinite(total), wide(total) + wide(compensation), wide(total))
    if not extremes_of:
        return pair * up
    return pair * up, list(zip(ranges[0::2], ranges[1::2]))


#: The ends of the ranges of the element types whose extremes a run's loop finds: where its
#: least and largest start (an adaptive pixel's state starts from the same values).
RANGE_ENDS = {dr.VarType.UInt32: (0, 0xFFFFFFFF), dr.VarType.Float32: (-dr.inf, dr.inf)}


def _most(kind):
    """The largest value of a Dr.Jit array type's elements (+∞ for float32)."""
    return _range_ends(kind)[1]


def _least(kind):
    """The least value of a Dr.Jit array type's elements (−∞ for float32)."""
    return _range_ends(kind)[0]


def _range_ends(kind):
    ends = RANGE_ENDS.get(dr.type_v(kind))
    if ends is None:
        raise TypeError(f"compensated_block_sum: no extremes of {kind.__name__} elements "
                        f"(UInt32 and float32 only)")
    return ends


def _pass_function(scene):
    """The recorded pass, or for a scene without shapes or without emitters the pass
    traced each time. Such a scene's pass still calls into shapes and emitters (rays
    meet nothing, the integrator asks for emitters), and Dr.Jit's recorder refuses a call
    whose instances are not among the inputs: a scene that has none of a kind finds in
    Dr.Jit's registry another loaded scene's ("record(): error encountered while
    recording a frozen function" after a scene that had them). Its image is the
    background, or its shapes unlit: nothing worth a recording."""
    return traced_pass if scene.shapes() and scene.emitters() else _trace_pass


def _accumulate(so_far, traced):
    """A split pixel's (sums, first, last[, doubt sums, low, high]) after one more pass's
    ``traced`` (the same, for that pass): sums added in pass order, from 0.0, in float64;
    shape ids and colours by min and max. ``so_far``: None at the pixel's first pass."""
    if so_far is None:
        so_far = (None if traced[0] is None else np.zeros_like(traced[0]),) + traced[1:]
        if len(traced) > 3:                             # estimates: doubt sums from 0.0
            so_far = so_far[:3] + (np.zeros_like(traced[3]),) + traced[4:]
    combines = (np.add, np.minimum, np.maximum, np.add, np.minimum, np.maximum)
    return tuple(None if old is None else combine(old, new)
                 for combine, old, new in zip(combines, so_far, traced))


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
