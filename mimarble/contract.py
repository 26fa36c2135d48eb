"""Numbers the renderers and the scene language share: float32's limits.

The Mitsuba path is single precision; the scene language refuses what it cannot hold and
the reference tracer (float64) is told the same bounds. Standard library only, importing
nothing of mimarble, so every part of the package may read it without an import circle.
"""

from __future__ import annotations

__all__ = ["FLT_MAX", "FLT_MIN_NORMAL"]

#: The largest float32: the Mitsuba path is single precision, so every number of a scene
#: must be at most this in magnitude.
FLT_MAX = 3.4028234663852886e38

#: The smallest normal float32, 2⁻¹²⁶: a smaller nonzero number is 0 to the renderer (its
#: JIT flushes subnormals to zero), so a size or an angle that must not be zero must be
#: at least this. Messages print it, as FLT_MAX, with every digit of its double (repr):
#: rounded, "3.4e38" reads as if 3.4028235e38 (FLT_MAX to 8 digits, past it) were within.
FLT_MIN_NORMAL = 2.0 ** -126
