"""The paper's marble channel (ChannelMarble) in float64 NumPy, on the reference noise.

For a world-space point p and a :class:`mimarble.scene.MarbleChannel` ``m``
(docs/design.md, "The marble model")::

    v = m.scale · p
    F = Σ_{i<octaves} N(2^i v) / 2^i                 (|N| when m.turbulence)
    abs_sine: t = |sin(π · (period · v_a + distortion · F))|
    sine:     t = ½ · (sin(period · v_a + distortion · F) + 1)
    cosine:   t = ½ · (cos(v_a + distortion · F) + 1)         (period unused)

``v_a`` is the coordinate of ``v`` that ``m.axis`` names. When ``distortion``
is 0 the noise is not evaluated at all (the phase is exactly 0). The colour is
the ramp at t: K colours at keys k/(K−1), piecewise linear, t clamped to
[0, 1]; K = 1 is a constant colour.

Imports NumPy and :mod:`mimarble.reference.noise` only.
"""

from __future__ import annotations

import math

import numpy as np

from .noise import fractal

__all__ = ["stripe", "stripe_of_phase", "ramp", "marble_color"]

_AXES = {"x": 0, "y": 1, "z": 2}


def stripe(points, channel):
    """The marble's scalar t in [0, 1] at an (N, 3) array of world-space points -> (N,)."""
    p = np.asarray(points, dtype=np.float64)
    v = p * float(channel.scale)
    distortion = float(channel.distortion)
    if distortion != 0.0 and int(channel.octaves) > 0:
        phase = distortion * fractal(v[..., 0], v[..., 1], v[..., 2], channel.octaves,
                                     bool(channel.turbulence))
    else:
        phase = 0.0
    a = v[..., _AXES[channel.axis]]
    if channel.function == "cosine":
        return stripe_of_phase(a + phase, "cosine")
    return stripe_of_phase(float(channel.period) * a + phase, channel.function)


def stripe_of_phase(phase, function):
    """t(φ): |sin πφ| (abs_sine), ½(sin φ + 1) (sine) or ½(cos φ + 1) (cosine)."""
    if function == "abs_sine":
        return np.abs(np.sin(math.pi * phase))
    if function == "sine":
        return 0.5 * (np.sin(phase) + 1.0)
    if function == "cosine":
        return 0.5 * (np.cos(phase) + 1.0)
    raise ValueError(f"unknown marble function {function!r}; expected abs_sine, sine or cosine")


def ramp(t, colours):
    """Piecewise-linear ramp: K colours at keys k/(K−1), t clamped to [0, 1] -> (N, 3)."""
    c = np.asarray(colours, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(t, dtype=np.float64)
    K = len(c)
    if K == 0:
        raise ValueError("a ramp needs at least one colour")
    if K == 1:
        return np.broadcast_to(c[0], t.shape + (3,)).copy()
    s = np.clip(t, 0.0, 1.0) * (K - 1)
    k = np.minimum(np.floor(s), K - 2).astype(np.int64)
    f = (s - k)[..., None]
    return c[k] * (1.0 - f) + c[k + 1] * f


def marble_color(points, channel):
    """The marble channel's colour at an (N, 3) array of world-space points -> (N, 3)."""
    return ramp(stripe(points, channel), channel.ramp)
