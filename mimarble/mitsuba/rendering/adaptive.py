"""Adaptive sampling in whitted mode: samples where the error is.

A first pass renders every pixel with ``spp`` = m² stratum centres, as a plain render
does. Then rounds: every pixel of the last round whose estimated error E exceeds
``threshold`` · n^BAR_POWER (n² its samples) goes one level up a ladder that keeps its
samples (:func:`ladder`): the centre of stratum (i, j) of an m×m grid is the centre of
stratum (3i + 1, 3j + 1) of the 3m×3m one — an odd refinement holds every old centre — so
a round traces only the 8 new strata of each cell of the m grid (9m² samples: the whole 3m
grid, the plain render's strata) and adds them to the pixel's sum. With :data:`THIRDS` a
round goes a third of the way first (2 per cell: the cell's centre and a pair symmetric
about it, the diagonals alternating from cell to cell, 3m² samples), then the other 6 —
more rounds, each dearer per sample than the plain render's (docs/design-decisions.md,
"Adaptive samples at the price of plain ones": the 1, 9, 81 ladder reached plain 16's RMSE
sooner on every scene measured). A ``max_spp`` off the ladder is a last level of its own
grid, which replaces the pixel's samples. Only the pixels a round refined are candidates
in the next. Deterministic, like the rest of whitted mode.

**The jump to 16.** 9 and 81 straddle 16: where every pixel of an object needs about 16
samples (fine veins) the ladder takes many to 81. So the first round sends a pixel whose
estimate says the 3m grid will not do and the 4m grid will (:data:`JUMP`) straight to
the 4m grid, 16m² stratum centres that replace its m² (the 4m grid does not hold the
pixel's centre); from there it goes on as the ladder does from 16m² (the 12m grid keeps
the 4m one's centres; under ``max_spp`` 81, the 9×9 grid, replacing: :func:`jump_ladder`),
over a bar :data:`JUMPED_BAR` times the ladder's.
The rounds then trace one pass per group of pixels at the same step of the same ladder.

**What a pixel is at the end.** At 9^k·m² or 16·9^k·m² samples (and at ``max_spp``) a
pixel holds the stratum centres of the plain render's grid, one per stratum, summed as a
plain render sums them (in float32
with compensation, the partial sums added in float64), so for point-sampled marbles its
mean is the plain render's at that spp up to the rounding of that sum's order (a float32
ulp at most; none in the tests). At 3·9^k·m² it holds, in each of the 9^k·m² strata of
the grid below, that stratum's centre and two points symmetric about it: a stratified
estimate with equal weight per stratum, exact for an integrand linear across each
stratum, as the midpoint rule is. A filtered marble (``bandlimit``, ``prefilter``)
averages each sample over its footprint, 1/n of the pixel for a grid of n per axis: the
samples a pixel keeps from a coarser grid keep their wider footprints
(tests/test_adaptive.py checks each of these).

Everything between rounds stays on the device (Dr.Jit): the pixels' sums, sample counts,
first-hit shapes, doubts and sample ranges, the estimate, and the next round's pixel list
(``dr.compress``); only its length comes back to size the passes. The scatters into the
pixels' arrays are queued together and run as one kernel (:meth:`PixelState.add`). A
pixel's mean and first shape are kept in one packet of four float32, read with one packet
gather a neighbour and made again only where a round traced
(:meth:`PixelState.neighbourhood`); the image is read from them. The
lists are in Morton order (:func:`morton_order`), so that a pass's neighbouring lanes are
neighbouring pixels.
The first pass is the plain kernel, and a pixel's doubt is read from its image (the
second difference, :func:`refine`), except in scenes with a
prefiltered marble, where the first pass traces the marbles' doubts
(:func:`traces_doubts`); the rounds trace the plain kernel, and read the first pass's doubt.

Why a bar that grows with n: a round costs a pixel more than its samples, so the error
it removes per sample falls as n grows; ``threshold`` · n^:data:`BAR_POWER` leaves deeper
rounds to fewer pixels, and was measured best on this ladder with the image's doubt
(docs/design-decisions.md, "Adaptive samples at the price of plain ones" and "Adaptive
samples: the bar and the jump against the oracle"). At 1 spp the threshold is the
estimated error in colour units.

The estimate of a pixel of n² samples, in linear colour units (the largest of the
three colours):

    E = DOUBT_WEIGHT · doubt / n²                                   every pixel
    E = max(E, SPREAD_WEIGHT · spread / n²)                         n² ≥ SPREAD_SAMPLES
    E = max(E, CONTRAST_WEIGHT · contrast / n^1.5)                  on a silhouette

``doubt`` is either read from the first image — the pixel's second difference (the
pixel against its 3×3 neighbourhood's mean: large where the image is curved or a vein
finer than the pixel aliases) or, where larger, :data:`DEVIATION_SHARE` of its largest
step to a neighbour (a vein across the pixel and one neighbour, which the sum over all
eight can cancel) — or, in scenes with a prefiltered marble, the mean over the
pixel's first-pass samples of whitted's doubt (``Whitted.shade``; the rounds do not
trace it):
the marbles' own estimate of how wrong one sample of them can be there — |the filter's
colour − its other view of the footprint| (mimarble/texture/filters.py), large where the
colour changes across the footprint, 0 where it is smooth. It says where a sample can be
wrong, not whether the prefilter is: inside fine veins a prefiltered pixel is refined as a
point-sampled one is, and only a marble without noise (linear phase, where the prefilter is
exact) gives a prefiltered pixel no doubt. ``spread`` is the range (high − low, the
largest colour's) of the pixel's own samples: once it has ``SPREAD_SAMPLES`` of them it
covers what no doubt sees — a highlight of a constant specular colour, a colour without
a marble. A silhouette pixel is one whose 3×3 neighbourhood sees more than one first-hit
shape (the edge samples' test, mimarble/mitsuba/rendering/silhouettes.py); its
``contrast`` is what its own samples and its neighbours disagree on — the larger of its
``spread`` and the range of its 3×3 neighbourhood's means (POV-Ray's ``+A`` compares a
pixel with its neighbours): a sliver of a sphere between the stratum centres shows in the
neighbours only. The powers are those of the error of n×n stratum centres: 1/n² for a
smooth integrand (the midpoint rule), about n^−1.5 for an edge across the pixel (n of the
n² cells cut, errors of random sign). The weights were chosen by measurement
(docs/benchmarks.md, "Adaptive sampling" and "Adaptive samples at the price of plain
ones").

Textures without a second estimate (``rgb``, ``bitmap``) have doubt 0: their pixels are
refined on silhouettes and by their spread only.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from mimarble.runtime import environment
from mimarble.runtime.progress import report
from mimarble.scene.model import samples_per_axis
from mimarble.contract import DEFAULT_MAX_SPP
from mimarble.mitsuba.plugins.registration import largest_component
from .loaded_scenes import LOADED
from .passes import RANGE_ENDS, Target, trace_sums
from .replay import scene_facts
from mimarble.mitsuba.plugins.whitted import Whitted
from mimarble.mitsuba.plugins.material import CHANNELS
from mimarble.mitsuba.plugins.shared_evaluations import textures_within
from mimarble.texture.filters import Prefilter
from .window import Window

dr, mi = environment.import_drjit_and_mitsuba()

#: Where a pixel's least and largest shape id and colour start (passes' range ends).
_UINT_ENDS, _FLOAT_ENDS = RANGE_ENDS[dr.VarType.UInt32], RANGE_ENDS[dr.VarType.Float32]

#: The estimate's weights (module docstring), chosen by measurement.
DOUBT_WEIGHT = 0.5
CONTRAST_WEIGHT = 0.25
SPREAD_WEIGHT = 0.02
#: The bar a pixel of n² samples is refined over: ``threshold`` · n^BAR_POWER. 2.25, not
#: 3: from one sample a pixel, the first round's bar is ``threshold`` at any power, the
#: 9 → 81 round's 3^BAR_POWER times it; a lower power sends more of the worst pixels to
#: 81 at a given threshold, so the RMSE is reached at a higher one, which leaves more of
#: the least doubtful at 1 (docs/design-decisions.md, "Adaptive samples: the bar and the
#: jump against the oracle").
BAR_POWER = 2.25
#: Samples a pixel has before its own spread is read (fewer say little: a range of
#: one or two samples).
SPREAD_SAMPLES = 3
#: Whether the first pass traces the marbles' doubts in every scene (a kernel of its own:
#: for a point-sampled marble about the plain one's cost again, docs/benchmarks.md), or
#: only in scenes with a prefiltered marble (:func:`traces_doubts`); else it is the plain
#: kernel and a pixel's doubt is read from the first image
#: (:func:`refine`, weighed by ``CURVATURE_WEIGHT``).
DOUBT_KERNEL = False
CURVATURE_WEIGHT = 0.125
#: The image's doubt of a pixel (:func:`refine`) is the larger of its second difference / 8
#: and this share of its largest step to a neighbour's mean (docs/design-decisions.md,
#: "Adaptive samples: the neighbour's step"). 0: the second difference alone.
DEVIATION_SHARE = 0.25
#: Whether the ladder goes a third of the way (3m² samples) before each 9m² (issue 43's
#: first ladder, 1, 3, 9, 27, 81), or straight to 9m² (1, 9, 81): fewer rounds, each
#: cheaper per sample (module docstring).
THIRDS = False
#: The first round's jump: a pixel of m² samples whose estimate E over its bar
#: ``threshold``·m^BAR_POWER is in (JUMP[0], JUMP[1]] goes straight to the 4m grid (16m²
#: samples, replacing its m²) instead of the 3m one (9m², keeping them). Under the 1/n²
#: law of the estimate, n² samples pass their bar once E·m²/n² ≤ threshold·n^BAR_POWER, i.e.
#: (n/m)^q ≥ E/bar with q = 2 + BAR_POWER: the band starts where the 3m grid would leave
#: the pixel over its bar, 3^q, and ends at twice 4^q, where the 4m grid would leave it
#: over its bar by 2 (measured: samples a pixel to plain 16 spp's RMSE on the fine veins
#: are fewest with the end at 2–3 × 4^q; a pixel above goes to 9, then 81). Such a
#: pixel ends at 17 samples traced where the ladder takes it to 81 (docs/design-decisions.md,
#: "Adaptive samples: the jump to 16 and fewer kernels", "… the bar and the jump against
#: the oracle"). None: no jump.
JUMP = (3.0 ** (2 + BAR_POWER), 2 * 4.0 ** (2 + BAR_POWER))
#: Fewer pixels than this that the band sends to 16m² go to 9m² with the others: a pass
#: has fixed costs (a replay's host work, its small kernels: about a millisecond, what
#: ~20 000 lanes of a sphere cost), which a few pixels' gain does not pay.
JUMP_LEAST = 1024
#: A jumped pixel's bar in the rounds after the jump, as a multiple of ``threshold`` ·
#: n^BAR_POWER. The jump's 16 replaced the pixel's samples and its first-pass doubt
#: (:meth:`PixelState.clear`), so its spread or a silhouette's contrast sends it on: 16
#: samples across a fine vein are far apart, and at the ladder's bar (1) that sent jumped
#: pixels to 81 where fewer samples reach plain 16 spp's RMSE at 4 (docs/design-decisions.md,
#: "Adaptive samples: the bar and the jump against the oracle").
JUMPED_BAR = 4.0


class AdaptiveRender(NamedTuple):
    """An adaptive render: ``image`` (H, W, 3) float32, as ``render_in_passes`` returns
    it; ``samples`` (H, W), each pixel's samples at the end; ``traced``, every sample
    traced for a pixel (the samples a round replaces included: the cost; not the few a
    pass over a pixel list pads itself with,
    :func:`~mimarble.mitsuba.rendering.passes.padded_count`); ``rounds``, the rounds
    after the first pass (a round is a pass over each group's pixel list)."""
    image: np.ndarray
    samples: np.ndarray
    traced: int
    rounds: int


class Level(NamedTuple):
    """One step of the ladder (:func:`ladder`): a pixel there has ``spp`` samples on the
    ``grid``×``grid`` stratum centres. A round into it from the level before traces, in each
    cell of the ``parent``×``parent`` grid (``grid`` = 3·``parent``), ``per_cell`` more of
    the cell's strata from its ``offset``-th (``pixel_tracer.nested_stratum``) and keeps the
    rest; ``parent`` 0: the first pass, or a level that replaces the pixel's samples."""
    spp: int
    grid: int
    parent: int = 0
    per_cell: int = 0
    offset: int = 0

    @property
    def traced(self) -> int:
        """Samples a round into this level traces per pixel."""
        return self.parent ** 2 * self.per_cell if self.parent else self.spp


def ladder(spp: int, max_spp: int) -> list[Level]:
    """The levels of a render from ``spp`` = m² to ``max_spp`` (perfect squares, ``spp`` ≤
    ``max_spp``): m², then per cell of the m grid its 8 other strata of the 3m grid (9m²,
    the whole 3m grid: the plain render's strata), then 81m², … while they fit — with
    :data:`THIRDS`, 2 of the 8 first (3m²), then the other 6 —; then ``max_spp``'s own
    grid, replacing, if it is not on that ladder (after one third-way level if that is at
    most half of ``max_spp``)."""
    m, most = samples_per_axis(spp), samples_per_axis(max_spp)
    levels = [Level(spp, m)]
    while 3 * m <= most:
        if THIRDS:
            levels += [Level(3 * m * m, 3 * m, m, 2, 0), Level(9 * m * m, 3 * m, m, 6, 2)]
        else:
            levels += [Level(9 * m * m, 3 * m, m, 8, 0)]
        m *= 3
    if m < most:
        if 3 * m * m <= max_spp // 2:      # a third of the way, if the last step doubles
            levels.append(Level(3 * m * m, 3 * m, m, 2, 0))
        levels.append(Level(max_spp, most))
    return levels


def jump_ladder(spp: int, max_spp: int) -> list[Level] | None:
    """The levels of a pixel the first round sends from ``spp`` = m² straight to the 4m
    grid (16m² samples, a level that replaces, :data:`JUMP`), and on from there as
    :func:`ladder` goes (the 12m grid keeps the 4m one's centres, as any odd refinement
    does; else ``max_spp``'s own grid, replacing). None when 16m² is above ``max_spp``
    or :data:`JUMP` is None."""
    m = samples_per_axis(spp)
    if JUMP is None or 16 * m * m > max_spp:
        return None
    return [Level(spp, m), Level(16 * m * m, 4 * m)] + ladder(16 * m * m, max_spp)[1:]


def sample_levels(spp: int, max_spp: int) -> list[int]:
    """The spp of the first pass and of each round (:func:`ladder`)."""
    return [level.spp for level in ladder(spp, max_spp)]


def estimated_errors(axis: float, doubt, spread, contrast, on_silhouette):
    """E of pixels of ``axis``² samples (module docstring), from their mean doubt,
    their samples' spread, contrast and silhouette flags (Dr.Jit Float64 and Bool)."""
    errors = (DOUBT_WEIGHT / axis ** 2) * doubt
    if axis * axis >= SPREAD_SAMPLES:
        errors = dr.maximum(errors, (SPREAD_WEIGHT / axis ** 2) * spread)
    silhouette = (CONTRAST_WEIGHT / axis ** 1.5) * contrast
    return dr.select(on_silhouette, dr.maximum(errors, silhouette), errors)


@lru_cache(maxsize=8)
def morton_order(width: int, height: int) -> np.ndarray:
    """The pixels of a width × height image (row-major indices, uint32) in Morton (Z)
    order: the bits of x and y interleaved, so that nearby list positions are nearby
    pixels (a round's lanes read nearby noise and texture data)."""
    # uint32 throughout: a side is at most 2¹⁴ pixels (the image limit), so a code has at
    # most 28 bits, and the arrays take 4 bytes a pixel each.
    y, x = np.divmod(np.arange(width * height, dtype=np.uint32), np.uint32(width))
    code = np.zeros_like(x)
    one = np.uint32(1)
    for bit in range(16):
        code |= ((x >> np.uint32(bit)) & one) << np.uint32(2 * bit)
        code |= ((y >> np.uint32(bit)) & one) << np.uint32(2 * bit + 1)
    return np.argsort(code, kind="stable").astype(np.uint32)


class PixelState:
    """What the rounds know of each pixel of the traced window, in Dr.Jit arrays of one
    lane per pixel (local indices, row-major): the radiance ``sums`` (Color3d), the
    ``samples`` they hold, the least and largest id of the first shape hit
    (``first``, ``last``), the ``doubt_sums`` (Float64) and how many samples they sum
    (``doubted``: the first pass's), and the least and largest sample radiance (``low``,
    ``high``)."""

    def __init__(self, count: int):
        self.count = count
        self.packed = None          # neighbourhood()'s packets
        self.sums = dr.zeros(mi.Color3d, count)
        self.samples = dr.zeros(mi.UInt32, count)
        self.first = dr.full(mi.UInt32, _UINT_ENDS[1], count)
        self.last = dr.full(mi.UInt32, _UINT_ENDS[0], count)
        self.doubt_sums = dr.zeros(mi.Float64, count)
        self.doubted = dr.zeros(mi.UInt32, count)
        self.low = dr.full(mi.Color3f, _FLOAT_ENDS[1], count)
        self.high = dr.full(mi.Color3f, _FLOAT_ENDS[0], count)

    def clear(self, pixels) -> None:
        """Forget what ``pixels`` (UInt32 local indices) hold: a level that replaces them."""
        self._settle()
        for name, value in (("sums", 0.0), ("doubt_sums", 0.0), ("samples", 0), ("doubted", 0),
                            ("first", _UINT_ENDS[1]), ("last", _UINT_ENDS[0]),
                            ("low", _FLOAT_ENDS[1]), ("high", _FLOAT_ENDS[0])):
            array = getattr(self, name)
            dr.scatter(array, type(array)(value), pixels)
        self._settle()

    def add(self, traced, pixels, active, samples: int) -> None:
        """Add a pass's :class:`~mimarble.mitsuba.rendering.passes.PassSums` ``traced`` at
        ``pixels`` (its lanes' local indices) where ``active`` (the padding is not), of
        ``samples`` samples a pixel: sums and counts added, extremes kept. Gathered,
        combined and scattered (a pixel is once in a pass): no atomic scatter."""
        self._settle()             # the arrays evaluated before the scatters are queued
        add, least, most = (lambda a, b: a + b), dr.minimum, dr.maximum
        parts = [("sums", add, traced.sums)]
        if traced.doubt_sums is not None:
            parts += [("doubt_sums", add, traced.doubt_sums),
                      ("doubted", add, dr.opaque(mi.UInt32, samples))]
        if traced.first is not None:
            parts += [("first", least, traced.first), ("last", most, traced.last),
                      ("low", least, traced.low), ("high", most, traced.high)]
        # The combined values evaluated (one kernel) before the scatters: a scatter into an
        # array that a pending gather still reads copies the whole array first.
        combined = [combine(dr.gather(type(getattr(self, name)), getattr(self, name), pixels,
                                      active), value) for name, combine, value in parts]
        dr.eval(*combined)
        for (name, _, _), value in zip(parts, combined):
            dr.scatter(getattr(self, name), value, pixels, active)
        self._settle()

    NAMES = ("sums", "samples", "first", "last", "doubt_sums", "doubted", "low", "high")

    def _settle(self) -> None:
        """Evaluate every array: the scatters queued into them run as one kernel. (A
        scatter into an array not yet evaluated — a literal ``dr.zeros``, a lazy gather —
        evaluates it first, which runs the scatters queued so far: a kernel per array.)"""
        dr.eval(*(getattr(self, name) for name in self.NAMES))

    def take(self, traced, samples: int) -> None:
        """What a first pass over every pixel in order (one pass, ``traced``) found: its
        arrays are the state (nothing to add them to)."""
        self.sums = traced.sums
        if traced.doubt_sums is not None:
            self.doubt_sums = traced.doubt_sums
            self.doubted = dr.full(mi.UInt32, samples, self.count)
        if traced.first is not None:
            # Arrays of their own: a pass of one sample traced without replay hands back one
            # object as least and largest, which the scatters into each would both change
            # (a new wrapper shares the values; Dr.Jit copies them at the first scatter).
            self.first, self.last = traced.first, mi.UInt32(traced.last)
            self.low, self.high = traced.low, mi.Color3f(traced.high)

    def means(self, pixels=None):
        """Each pixel's mean (Color3f), or those of ``pixels`` (UInt32): its sum divided by
        its samples in float64 (a true division, as a plain render's), rounded once."""
        sums, samples = (self.sums, self.samples) if pixels is None else \
            (dr.gather(mi.Color3d, self.sums, pixels), dr.gather(mi.UInt32, self.samples, pixels))
        return mi.Color3f(sums / mi.Float64(dr.maximum(samples, 1)))

    def neighbourhood(self, changed: list | None = None, one_sample: bool = False):
        """What a pixel's neighbours are read for (:func:`refine`), one packet of four
        float32 a pixel: its mean's three colours (:meth:`means`) and the bits of its least
        first-shape id (a flat Float, evaluated, kept as ``packed``). One packet gather a
        neighbour reads them — on the LLVM back end about half the time of four gathers
        (docs/benchmarks.md, "Adaptive samples: the fixed costs of a render").

        ``changed``: the pixel lists (UInt32) traced since the packets were last made:
        only theirs are made again (a mean is a float64 division, the dearest part of
        the kernel), None: every pixel's. ``one_sample``: every pixel holds one sample,
        whose mean is its sum (x / 1 is x: the same bits, without the division)."""
        if changed is None or self.packed is None:
            mean = mi.Color3f(self.sums) if one_sample else self.means()
            self.packed = dr.ravel(mi.Array4f(mean.x, mean.y, mean.z,
                                              dr.reinterpret_array(mi.Float, self.first)),
                                   order="F")
        else:
            for pixels in changed:
                mean = self.means(pixels)
                first = dr.reinterpret_array(mi.Float, dr.gather(mi.UInt32, self.first, pixels))
                dr.scatter(self.packed, mi.Array4f(mean.x, mean.y, mean.z, first), pixels)
        dr.eval(self.packed)
        return self.packed

    def image(self) -> np.ndarray:
        """Every pixel's mean, (count, 3) float32, from the packets (:meth:`neighbourhood`,
        brought up to date by the caller)."""
        return self.packed.numpy().reshape(-1, 4)[:, :3]


def _neighbours(pixels, width: int, height: int):
    """The 3×3 neighbourhood of each of ``pixels`` (UInt32 local indices of a width ×
    height window), clipped at the border (an edge pixel's own row or column again)."""
    row, column = mi.Int32(pixels // width), mi.Int32(pixels % width)
    w, h = dr.opaque(mi.Int32, width), dr.opaque(mi.Int32, height)
    # The three rows' starts and three columns, each clipped once (a pixel is inside).
    starts = (dr.maximum(row - 1, 0) * w, row * w, dr.minimum(row + 1, h - 1) * w)
    columns = (dr.maximum(column - 1, 0), column, dr.minimum(column + 1, w - 1))
    for start in starts:
        for x in columns:
            yield mi.UInt32(start + x)


def _read_neighbour(packed, pixels):
    """The mean (Color3f) and least first-shape id (UInt32) of ``pixels`` from
    :meth:`PixelState.neighbourhood`'s packets."""
    value = dr.gather(mi.Array4f, packed, pixels)
    return mi.Color3f(value.x, value.y, value.z), dr.reinterpret_array(mi.UInt32, value.w)


def refine(state: PixelState, packed, pixels, axis: float, threshold: float, width: int,
           height: int, doubt_from_image: bool = False, jump: tuple | None = None):
    """The pixels of ``pixels`` (UInt32 local indices, each of ``axis``² samples) whose
    estimated error is above ``threshold`` · axis^:data:`BAR_POWER` (module docstring), in
    their order:
    computed on the device, the list made there (``dr.compress``).

    ``doubt_from_image`` (after a first pass without the doubt kernel, ``pixels`` every
    pixel): each pixel's doubt is first set from the image, in the same kernel — the
    second difference |Σ₃ₓ₃ mean − 9·mean| / 8 (the pixel against its 8 neighbours' mean,
    the largest colour) or, where larger, :data:`DEVIATION_SHARE` · max |neighbour's mean −
    mean| (the largest colour), scaled so that the estimate weighs it by
    :data:`CURVATURE_WEIGHT`. For a smooth image it is (3/8)·h²·|f_xx + f_yy| to leading
    order, 9× the midpoint rule's error of a 1-spp pixel, h²·|f_xx + f_yy|/24; where veins
    finer than a pixel alias, neighbours disagree at random and it is large. Held as the
    doubt of one sample, it falls as 1/n² as the kernel's doubt does.

    ``jump`` (lo, hi): two lists, in their order — the pixels over the bar whose E / bar is
    not in (lo, hi], and those whose is (:data:`JUMP`)."""
    least = most = None
    low_mean = high_mean = total = None
    # A pixel of one sample has one first shape (its least and largest id are one) and no
    # spread (its least and largest radiance are one): gathers the kernel need not make.
    single = axis * axis == 1
    for around in _neighbours(pixels, width, height):
        mean, first = _read_neighbour(packed, around)
        last = first if single else dr.gather(mi.UInt32, state.last, around)
        if least is None:
            least, most, low_mean, high_mean, total = first, last, mean, mean, mean
        else:
            least, most = dr.minimum(least, first), dr.maximum(most, last)
            low_mean, high_mean = dr.minimum(low_mean, mean), dr.maximum(high_mean, mean)
            total = total + mean
    if doubt_from_image:
        # The pixel's curvature (its second difference / 8) or, where larger, a share of
        # its largest step to a neighbour: the step sees a vein that crosses the pixel
        # and one neighbour, which the sum over all eight can cancel (DEVIATION_SHARE).
        # max |mean − centre| over the neighbours is max(high − centre, centre − low),
        # rounding being monotone: the same bits, without a subtraction a neighbour.
        centre, _ = _read_neighbour(packed, pixels)
        deviation = dr.maximum(high_mean - centre, centre - low_mean)
        second = dr.maximum(0.125 * largest_component(dr.abs(total - 9.0 * centre)),
                            DEVIATION_SHARE * largest_component(deviation))
        image_doubt = mi.Float64(second) * (CURVATURE_WEIGHT / DOUBT_WEIGHT)
        state.doubt_sums = dr.zeros(mi.Float64, state.count)
        dr.scatter(state.doubt_sums, image_doubt, pixels)        # kept for the rounds
        state.doubted = dr.full(mi.UInt32, 1, state.count)
    on_silhouette = least != most
    spread = 0.0 if single else largest_component(dr.gather(mi.Color3f, state.high, pixels)
                                                  - dr.gather(mi.Color3f, state.low, pixels))
    contrast = dr.maximum(spread, largest_component(high_mean - low_mean))
    if doubt_from_image:
        doubt = image_doubt
    else:
        doubted = dr.gather(mi.UInt32, state.doubted, pixels)
        doubt = dr.gather(mi.Float64, state.doubt_sums, pixels) / mi.Float64(dr.maximum(doubted, 1))
    errors = estimated_errors(axis, doubt, mi.Float64(spread), mi.Float64(contrast),
                              on_silhouette)
    bar = dr.opaque(mi.Float64, threshold * axis ** BAR_POWER)
    keep = errors > bar
    if jump is None:
        return dr.gather(mi.UInt32, pixels, dr.compress(keep))
    jumps = keep & (errors > bar * jump[0]) & (errors <= bar * jump[1])
    stays = keep & ~jumps
    dr.eval(stays, jumps)             # one kernel for both lists (else each compress's own)
    return (dr.gather(mi.UInt32, pixels, dr.compress(stays)),
            dr.gather(mi.UInt32, pixels, dr.compress(jumps)))


def render_adaptive(mitsuba_scene, spp: int, threshold: float,
                    max_spp: int = DEFAULT_MAX_SPP, progress=False, crop=None,
                    pass_samples: int | None = None, rounds: int | None = None,
                    jump: str = "estimate") -> AdaptiveRender:
    """Render a loaded whitted scene (JIT variants) adaptively: a first pass of ``spp``
    stratum centres, then rounds that refine every pixel whose estimated error is above
    ``threshold`` (linear colour units) up to ``max_spp`` (module docstring).

    ``crop`` ``(x0, y0, x1, y1)`` (checked by the caller): that window is traced with a
    ring of one pixel around it, so that its pixels' neighbourhoods are the image's in
    the first pass; a round's estimates at the window's border then see the ring's
    pixels only, so they can be refined otherwise than in the whole image. ``progress``:
    as ``mimarble.render`` takes it (the total grows with each round). ``rounds``: stop
    after that many rounds (the benchmark's oracle, mimarble/bench/oracle.py, takes every
    pixel to each level with a threshold below 0). ``jump``: which pixels the first round
    sends to 16m² samples (:func:`jump_ladder`) — ``"estimate"`` those whose estimate says
    so (:data:`JUMP`), ``"never"``, or ``"always"`` (every pixel it refines)."""
    if not isinstance(mitsuba_scene.integrator(), Whitted):
        raise ValueError(f"render_adaptive: the scene's integrator is "
                         f"{type(mitsuba_scene.integrator()).__name__}; adaptive sampling "
                         f"needs mimarble's 'whitted' (its stratum centres and doubts)")
    target = Target.of(mitsuba_scene, "whitted", LOADED.parameters_of(mitsuba_scene))
    doubts = traces_doubts(mitsuba_scene)
    if doubts:
        Whitted.prepare_doubts(mitsuba_scene)
    facts = scene_facts(target.scene, target.params)
    window = Window.of(target, crop, ring=1)
    width, height = window.width, window.height
    count = width * height
    state = PixelState(count)
    done = report(progress, "render")
    traced, total = 0, count * spp
    done(0, total + 1)                         # open until the last round has said its size
    main, jumped = ladder(spp, max_spp), jump_ladder(spp, max_spp)
    if jump == "never" or (jump == "always" and jumped is None):
        jumped = None
    # Each group: the pixels (local indices, a Dr.Jit list) at the same step of the same
    # ladder, traced in one pass a round. The first pass: every pixel, row by row.
    groups = [(main, 0, dr.arange(mi.UInt32, count), count)]
    taken = 0
    unpacked = []                  # the pixel lists traced since the packets were made
    while groups:
        for levels, number, pixels, listed in groups:
            level = levels[number]
            last = number + 1 == len(levels) or rounds == taken   # no estimates after it
            if number > 0 and not level.parent:
                state.clear(pixels)
            whole = number == 0 and window.whole
            for part in trace_sums(target, level.grid ** 2,
                                   None if whole else _global(window, pixels), listed,
                                   with_estimates=not last, doubts=doubts and number == 0,
                                   parent_axis=level.parent, per_cell=level.per_cell,
                                   cell_offset=level.offset, pass_samples=pass_samples,
                                   key=facts):
                lanes = dr.width(part.sums)
                if whole and part.count == count == lanes and part.samples == level.spp:
                    state.take(part, level.spp)          # the whole image in one pass
                else:
                    at = dr.arange(mi.UInt32, lanes)
                    active = at < dr.opaque(mi.UInt32, part.count)
                    state.add(part, dr.gather(mi.UInt32, pixels,
                                              at + dr.opaque(mi.UInt32, part.start), active),
                              active, part.samples)
                done(traced + (part.start + part.count) * level.traced, total + 1)
            dr.scatter(state.samples, mi.UInt32(level.spp), pixels)
            traced += listed * level.traced
            unpacked.append(pixels)
        if rounds == taken:
            break
        packed = state.neighbourhood(unpacked, one_sample=spp == 1)
        unpacked = []
        following = []
        for levels, number, pixels, listed in groups:
            if number + 1 == len(levels):
                continue
            axis = math.sqrt(levels[number].spp)
            if number == 0:
                # The first round's candidates: every pixel (local indices) in Morton
                # order, made only when a round follows.
                candidates = mi.UInt32(morton_order(width, height))
                split = jumped is not None and jump == "estimate"
                found = refine(state, packed, candidates, axis, threshold, width, height,
                               doubt_from_image=not doubts, jump=JUMP if split else None)
                if split:
                    dr.eval(*found)
                    if dr.width(found[1]) < JUMP_LEAST:   # not worth a pass of its own
                        following.append((levels, 1, _joined(*found)))
                    else:
                        following += [(levels, 1, found[0]), (jumped, 1, found[1])]
                else:
                    following.append((levels if jumped is None else jumped, 1, found))
            else:
                # A jumped pixel goes on over a bar of its own (JUMPED_BAR).
                bar = threshold * (JUMPED_BAR if levels is jumped else 1.0)
                following.append((levels, number + 1,
                                  refine(state, packed, pixels, axis, bar, width, height)))
        dr.eval(*(pixels for _, _, pixels in following))
        groups = [(levels, number, pixels, dr.width(pixels))
                  for levels, number, pixels in following if dr.width(pixels)]
        total = traced + sum(listed * levels[number].traced
                             for levels, number, _, listed in groups)
        taken += bool(groups)
    done(traced, traced)
    if unpacked:
        state.neighbourhood(unpacked, one_sample=spp == 1)
    image = state.image().reshape(height, width, 3)
    samples = state.samples.numpy().astype(np.int64).reshape(height, width)
    return AdaptiveRender(window.window_of(image), window.window_of(samples[..., None])[..., 0],
                          traced, taken)


def traces_doubts(mitsuba_scene) -> bool:
    """Whether the first pass over ``mitsuba_scene`` traces whitted's doubts: with
    :data:`DOUBT_KERNEL`, or when a marble of the scene is prefiltered. A prefiltered
    marble's second estimate (the colour at the point) costs little beside the prefilter,
    which computes the noise over the footprint anyway, and its doubt knows where the
    prefilter is exact (linear phase: no doubt) — the image cannot tell a resolved stripe
    from one that needs samples. A point-sampled marble's second estimate is a prefilter
    of its own: there the image's second difference does its work."""
    if DOUBT_KERNEL:
        return True
    return any(isinstance(getattr(texture, "pixel_filter", None), Prefilter)
               for material in Whitted.scene_materials(mitsuba_scene)
               for name in CHANNELS
               for texture in textures_within(getattr(material, name)))


def _joined(first, second):
    """Two UInt32 lists, one after the other (Dr.Jit's ``concat`` refuses an empty one)."""
    return first if dr.width(second) == 0 else second if dr.width(first) == 0 else \
        dr.concat((first, second))


def _global(window: Window, pixels):
    """Local indices of ``window``'s traced pixels (UInt32) → the whole image's."""
    if window.whole:
        return pixels
    row, column = pixels // window.width, pixels % window.width
    u32 = lambda v: dr.opaque(mi.UInt32, v)
    return (row + u32(window.y0)) * u32(window.columns) + column + u32(window.x0)
