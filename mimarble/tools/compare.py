"""Image metrics for comparing a render against the reference (NumPy only).

* :func:`image_metrics` — RMSE, PSNR, max abs error and the fraction of pixels
  off by more than 1/255, all on linear RGB as given (no clamping, no tone map).
* :func:`error_map` — a false-colour picture of the per-pixel error.
* :func:`error_map_with_legend` — that picture over its legend (``compare --diff``): a
  colour bar with the log scale's decades labelled, drawn into the image.

* :func:`compare_with_reference` — ``mimarble compare``'s workflow: a scene rendered
  through Mitsuba and by the reference tracer, and the metrics of the one against the
  other (:func:`reference_differs`: whether the options render otherwise than it).

This module imports NumPy and the standard library only (no Mitsuba), so the
metrics can be used on any pair of arrays; the legend's labels are drawn with
matplotlib, imported when a legend is asked for, and the renderers are imported by
:func:`compare_with_reference` when it is called.
"""

from __future__ import annotations

import math

import numpy as np

from mimarble.runtime.extras import require_extra

__all__ = ["image_metrics", "compare_with_reference", "reference_differs", "error_map", "ERROR_MAP_RANGE", "ERROR_MAP_COLORS", "colormap",
           "ROWS_PER_CHUNK", "error_map_legend", "error_map_with_legend", "error_map_scale",
           "LEGEND_HEIGHT", "LEGEND_MIN_WIDTH", "LEGEND_BAR_ROWS", "legend_bar_columns"]

#: Default error range of :func:`error_map` (log scale): 1e-6 … 1e-1.
ERROR_MAP_RANGE = (1e-6, 1e-1)

#: The error-map colour ramp, low to high error: black, blue, magenta, yellow,
#: white, at evenly spaced keys (perceptually ordered: luminance increases
#: monotonically along it).
ERROR_MAP_COLORS = np.array([
    (0.0, 0.0, 0.0),     # black
    (0.0, 0.0, 1.0),     # blue
    (1.0, 0.0, 1.0),     # magenta
    (1.0, 1.0, 0.0),     # yellow
    (1.0, 1.0, 1.0),     # white
])


#: Rows compared at a time: the metrics and the error map need no full-size temporaries.
ROWS_PER_CHUNK = 256


def _pair(test, reference):
    """Both images as (H, W, C) arrays (views where possible, no float64 copies yet)."""
    a = np.asarray(test)
    b = np.asarray(reference)
    if a.shape != b.shape:
        raise ValueError(f"images differ in shape: {a.shape} vs {b.shape}")
    if a.ndim == 2:
        a, b = a[..., None], b[..., None]
    if a.ndim != 3:
        raise ValueError(f"expected (H, W, C) or (H, W) images, got shape {a.shape}")
    return a, b


def _row_chunks(a, b, rows=ROWS_PER_CHUNK):
    """(first row, float64 difference test − reference) of each band of rows."""
    for y0 in range(0, a.shape[0], rows):
        yield y0, (np.asarray(a[y0:y0 + rows], dtype=np.float64)
                   - np.asarray(b[y0:y0 + rows], dtype=np.float64))


def image_metrics(test, reference) -> dict:
    """Error of ``test`` against ``reference`` ((H, W, C) arrays, same shape).

    Returns a dict:

    * ``rmse`` — sqrt(mean over all pixels and channels of (test − reference)²);
    * ``psnr`` — 20·log10(1 / rmse) in dB (peak 1.0), ``inf`` when identical, ``-inf``
      when the error is infinite;
    * ``max_abs`` — the largest |test − reference| over pixels and channels;
    * ``frac_over_1_255`` — the fraction of pixels whose largest channel
      |difference| exceeds 1/255.

    Non-finite values propagate (a NaN in either image gives NaN metrics).
    Computed in float64, :data:`ROWS_PER_CHUNK` rows at a time (memory stays
    bounded whatever the image size).
    """
    a, b = _pair(test, reference)
    if a.size == 0:
        raise ValueError("empty images")
    squares, maxima, over = 0.0, [], 0
    for _, diff in _row_chunks(a, b):
        squares += float(np.sum(diff * diff))
        per_pixel = np.max(np.abs(diff), axis=-1)
        maxima.append(np.max(per_pixel))
        over += int(np.count_nonzero(per_pixel > 1.0 / 255.0))
    rmse = math.sqrt(squares / a.size)
    if rmse == 0.0:
        psnr = math.inf
    elif math.isnan(rmse):
        psnr = math.nan
    elif math.isinf(rmse):           # an infinite difference (a light of 3.4e38): no signal
        psnr = -math.inf
    else:
        psnr = float(20.0 * math.log10(1.0 / rmse))
    return {
        "rmse": rmse,
        "psnr": psnr,
        "max_abs": float(np.max(maxima)),
        "frac_over_1_255": over / (a.shape[0] * a.shape[1]),
    }


def colormap(x) -> np.ndarray:
    """Map x in [0, 1] (clamped) through :data:`ERROR_MAP_COLORS` -> float (…, 3)."""
    c = ERROR_MAP_COLORS
    s = np.clip(np.nan_to_num(np.asarray(x, dtype=np.float64), nan=1.0), 0.0, 1.0) * (len(c) - 1)
    k = np.minimum(np.floor(s), len(c) - 2).astype(np.int64)
    f = (s - k)[..., None]
    return c[k] * (1.0 - f) + c[k + 1] * f


def error_map(test, reference, vmax=None, vmin=None) -> np.ndarray:
    """False-colour map of the per-pixel error -> uint8 (H, W, 3).

    The per-pixel error is the largest channel |test − reference|. It is placed
    on a log scale from ``vmin`` (default 1e-6) to ``vmax`` (default 1e-1) and
    coloured black → blue → magenta → yellow → white; errors at or below vmin
    (including exact zeros) are black, at or above vmax white; NaN is white.
    """
    lo = ERROR_MAP_RANGE[0] if vmin is None else float(vmin)
    hi = ERROR_MAP_RANGE[1] if vmax is None else float(vmax)
    if not (0.0 < lo < hi):
        raise ValueError(f"need 0 < vmin < vmax, got vmin={lo}, vmax={hi}")
    a, b = _pair(test, reference)
    out = np.empty(a.shape[:2] + (3,), dtype=np.uint8)
    for y0, diff in _row_chunks(a, b):
        err = np.max(np.abs(diff), axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            x = (np.log10(np.maximum(err, lo)) - math.log10(lo)) / (math.log10(hi) - math.log10(lo))
        x = np.where(np.isnan(err), 1.0, x)
        out[y0:y0 + err.shape[0]] = np.round(colormap(x) * 255.0)
    return out


# ---------------------------------------------------------------------------
# The legend: a strip under the map, its colour bar and the scale's decades

#: Rows of the legend strip under the map.
LEGEND_HEIGHT = 48
#: The least width of the legend (a narrower map is padded on the right with the
#: legend's grey, a colour the map never takes).
LEGEND_MIN_WIDTH = 320
#: The rows of the strip that hold the colour bar (the rest: ticks, labels, caption).
LEGEND_BAR_ROWS = (4, 18)
_MARGIN = 20                        # columns left and right of the bar, for the end labels
_BACKGROUND = (128, 128, 128)       # mid grey: on no point of the map's ramp
_INK = (0, 0, 0)


def _range(vmin, vmax):
    lo = ERROR_MAP_RANGE[0] if vmin is None else float(vmin)
    hi = ERROR_MAP_RANGE[1] if vmax is None else float(vmax)
    if not (0.0 < lo < hi and math.isfinite(hi)):
        raise ValueError(f"need 0 < vmin < vmax, got vmin={lo}, vmax={hi}")
    return lo, hi


def legend_bar_columns(width: int) -> tuple[int, int]:
    """The columns [x0, x1) of the colour bar in a legend ``width`` wide: column x shows
    the colour of the error at fraction (x − x0 + ½)/(x1 − x0) of the log scale."""
    return _MARGIN, max(width, LEGEND_MIN_WIDTH) - _MARGIN


def _label(value: float) -> str:
    exponent = math.log10(value)
    if abs(exponent - round(exponent)) < 1e-9:
        return f"1e{round(exponent)}"
    return f"{value:.2g}"


def error_map_scale(vmin=None, vmax=None) -> str:
    """The error map's scale in words (``compare --diff`` prints it)."""
    lo, hi = _range(vmin, vmax)
    return (f"per-pixel max channel |render - reference| on a log scale: black <= {_label(lo)}, "
            f"blue, magenta, yellow, white >= {_label(hi)} (and NaN)")


def error_map_legend(width: int, vmin=None, vmax=None) -> np.ndarray:
    """The legend strip of an error map ``width`` columns wide (at least
    :data:`LEGEND_MIN_WIDTH`) -> uint8 (:data:`LEGEND_HEIGHT`, width', 3): the colour bar
    (rows :data:`LEGEND_BAR_ROWS`, columns :func:`legend_bar_columns`, the exact colours of
    :func:`error_map`), a tick under it at each power of ten in [vmin, vmax] and at both
    ends, labelled (``1e-6``), and a caption: "max channel |error| per pixel, log scale; NaN is
    white"."""
    lo, hi = _range(vmin, vmax)
    require_extra("compare --diff")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    width = max(int(width), LEGEND_MIN_WIDTH)
    dpi = 72                                        # a point is a pixel
    figure = Figure(figsize=(width / dpi, LEGEND_HEIGHT / dpi), dpi=dpi,
                    facecolor=tuple(c / 255 for c in _BACKGROUND))
    canvas = FigureCanvasAgg(figure)
    x0, x1 = legend_bar_columns(width)
    top, bottom = LEGEND_BAR_ROWS
    span = math.log10(hi) - math.log10(lo)
    ticks = [lo] + [10.0 ** k for k in range(math.ceil(math.log10(lo)), math.floor(math.log10(hi)) + 1)
                    if lo < 10.0 ** k < hi] + [hi]
    ink = tuple(c / 255 for c in _INK)
    columns = []
    for value in ticks:
        x = min(x0 + round((math.log10(value) - math.log10(lo)) / span * (x1 - x0)), x1 - 1)
        columns.append(x)
        # Text in pixels from the bottom left (matplotlib's display coordinates).
        figure.text(x + 0.5, LEGEND_HEIGHT - bottom - 16, _label(value), transform=None,
                    ha="center", va="baseline", fontsize=9, color=ink)
    figure.text(width / 2, 4, "max channel |error| per pixel, log scale; NaN is white",
                transform=None, ha="center", va="baseline", fontsize=9, color=ink)
    canvas.draw()
    strip = np.array(canvas.buffer_rgba(), dtype=np.uint8)[..., :3]
    strip = strip[:LEGEND_HEIGHT, :width].copy()
    fractions = (np.arange(x0, x1) - x0 + 0.5) / (x1 - x0)
    strip[top:bottom, x0:x1] = np.round(colormap(fractions) * 255.0)
    for x in columns:
        strip[bottom:bottom + 4, x] = _INK
    return strip


def error_map_with_legend(test, reference, vmax=None, vmin=None) -> np.ndarray:
    """:func:`error_map` with :func:`error_map_legend` under it -> uint8
    (H + LEGEND_HEIGHT, max(W, LEGEND_MIN_WIDTH), 3); the map is the top-left H×W,
    unchanged."""
    picture = error_map(test, reference, vmax=vmax, vmin=vmin)
    height, width = picture.shape[:2]
    legend = error_map_legend(width, vmin=vmin, vmax=vmax)
    out = np.empty((height + LEGEND_HEIGHT, legend.shape[1], 3), dtype=np.uint8)
    out[:height] = _BACKGROUND
    out[:height, :width] = picture
    out[height:] = legend
    return out


def reference_differs(scene, filter=None, edge_spp=None, adaptive=None) -> bool:
    """Whether ``mimarble.render`` with these options renders otherwise than the reference
    tracer's plain supersampling (the ground truth): a marble's pixel filter (``filter``,
    else each marble's own), edge samples or adaptive sampling differ from it by what
    they filter or sample otherwise."""
    from mimarble.scene import walk
    filters = {filter} if filter else {
        getattr(inner, "filter", "none") for material in scene.materials.values()
        for channel in material.channels().values() for inner in walk(channel)}
    return bool(filters - {"none"} or edge_spp or adaptive)


def compare_with_reference(scene, spp: int, *, tolerance=None, filter=None, edge_spp=None,
                           adaptive=None, max_spp=None, name=None, progress=False):
    """Render ``scene`` through Mitsuba in whitted mode (``mimarble.render`` with these
    options) and with the float64 reference tracer; → ``(metrics, ours, reference)``.

    ``metrics``: :func:`image_metrics` of ours against the reference, with ``scene``
    (``name``, else the scene's file), ``spp``, ``variant`` and each renderer's seconds;
    an adaptive render (``adaptive``, a threshold) is compared with the reference at its
    most samples per pixel, ``max_spp`` (given with ``adaptive``), and its metrics say so
    (``adaptive``, ``max_spp``, ``reference_spp``). Mitsuba must be started
    (``mimarble.start``)."""
    if adaptive is not None and max_spp is None:
        raise ValueError("compare_with_reference: give max_spp with adaptive (the reference "
                         "renders at it)")
    import time

    import mimarble
    from mimarble import reference
    start = time.perf_counter()
    ours = mimarble.render(scene, spp=spp, progress=progress, tolerance=tolerance,
                           filter=filter, edge_spp=edge_spp, adaptive=adaptive, max_spp=max_spp)
    mitsuba_seconds = time.perf_counter() - start
    reference_spp = spp if adaptive is None else max_spp
    start = time.perf_counter()
    ref = reference.render(scene, spp=reference_spp, progress=progress)
    reference_seconds = time.perf_counter() - start
    metrics = image_metrics(ours, ref)
    metrics.update(scene=str(name if name is not None else scene.source), spp=spp,
                   variant=mimarble.mi.variant(), mitsuba_seconds=mitsuba_seconds,
                   reference_seconds=reference_seconds)
    if adaptive is not None:
        metrics.update(adaptive=adaptive, max_spp=reference_spp, reference_spp=reference_spp)
    return metrics, ours, ref
