"""Image metrics for comparing a render against the reference (NumPy only).

* :func:`image_metrics` — RMSE, PSNR, max abs error and the fraction of pixels
  off by more than 1/255, all on linear RGB as given (no clamping, no tone map).
* :func:`error_map` — a false-colour picture of the per-pixel error.

This module imports NumPy and the standard library only (no Mitsuba), so the
metrics can be used on any pair of arrays.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["image_metrics", "error_map", "ERROR_MAP_RANGE", "ERROR_MAP_COLORS", "colormap",
           "ROWS_PER_CHUNK"]

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
