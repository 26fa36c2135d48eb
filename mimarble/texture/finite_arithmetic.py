"""Products and sums of finite float32 terms that stay finite.

A huge but finite scale, period or distortion can make ``a·b`` or ``a + b`` overflow
to ±inf, and the marble's colour would then be NaN. Such a result is taken as 0 —
like any angle past float32's resolution, meaningless but finite and deterministic —
so finite input always gives a finite colour; NaN and ±inf input still give NaN.
"""

from __future__ import annotations

from mimarble.runtime import environment

dr, mi = environment.import_drjit_and_mitsuba()


def _overflowed(result, a, b):
    """``result`` of finite ``a`` and ``b`` that overflowed to ±inf → 0; else as it is."""
    return dr.select(dr.isinf(result) & dr.isfinite(a) & dr.isfinite(b), 0.0, result)


def finite_product(a, b):
    """a·b, 0 where finite a and b overflow."""
    return _overflowed(a * b, a, b)


def finite_sum(a, b):
    """a + b, 0 where finite a and b overflow."""
    return _overflowed(a + b, a, b)
