"""The paper's marble channel (ChannelMarble) in float64 NumPy, on the reference noise.

For a world-space point p and a :class:`mimarble.scene.MarbleChannel` ``m``
(docs/design.md, "The marble model")::

    v = m.scale · M⁻¹ · p                            (M: the pattern's transform)
    F = Σ_{i<octaves} N(2^i v) / 2^i                 (|N| when m.turbulence)
        = Σ_{i<octaves} ω^i N(λ^i v)                 (ω = m.gain, λ = m.lacunarity)
    abs_sine: t = |sin(π · (period · v_a + distortion · F))|
    triangle: t = 2·s for s < ½, else 2·(1 − s),  s = φ − ⌊φ⌋   (POV-Ray's triangle_wave)
    sawtooth: t = φ − ⌊φ⌋                                       (POV-Ray's ramp_wave)
              (both with φ = period · v_a + distortion · F)
    sine:     t = ½ · (sin(period · v_a + distortion · F) + 1)
    cosine:   t = ½ · (cos(v_a + distortion · F) + 1)         (period unused)

``v_a`` is the coordinate of ``v`` that ``m.axis`` names. When ``distortion``
is 0 the noise is not evaluated at all (the phase is exactly 0). The colour is
the ramp at t: K colours at keys k/(K−1), piecewise linear, t clamped to
[0, 1]; K = 1 is a constant colour. With ``m.ramp_positions`` p_0 ≤ … ≤ p_{K−1} the
keys are those: below p_0 the first colour, from p_{K−1} on the last, between
p_k ≤ t < p_{k+1} the linear blend of c_k and c_{k+1}; equal positions make a step
whose upper colour holds from the position on (found by ``np.searchsorted``).

M is the marble's ``transform`` (the language's ``transform { translate rotate scale }``),
composed here from its steps, independently of the scene package's composition that the
Mitsuba path takes (:func:`pattern_matrix`): each step moves the pattern in world space in
the order written, M = Sₙ ⋯ S₁; ``translate t`` is p + t, ``scale s`` is diag(s),
``rotate < a b c >`` is R_z(c)·R_y(b)·R_x(a), each R the right-handed rotation by that many
degrees (counter-clockwise seen from the axis' positive end). M⁻¹·p is solved in float64.

Imports NumPy and :mod:`mimarble.reference.noise` only.
"""

from __future__ import annotations

import math

import numpy as np

from .noise import fractal

__all__ = ["stripe", "stripe_of_phase", "ramp", "marble_color", "pattern_matrix", "pattern_points"]

_AXES = {"x": 0, "y": 1, "z": 2}


def _rotation(axis: int, degrees: float) -> np.ndarray:
    """R about coordinate ``axis``: Rodrigues' formula, R = I + sin θ·K + (1 − cos θ)·K²,
    K the cross-product matrix of the unit axis (so R·a = a and R turns counter-clockwise
    seen from the axis' tip)."""
    theta = np.radians(float(degrees))
    k = np.zeros((3, 3))
    a, b = [(1, 2), (2, 0), (0, 1)][axis]          # K·e_a = e_b for the axis e_axis
    k[b, a], k[a, b] = 1.0, -1.0
    return np.eye(3) + np.sin(theta) * k + (1.0 - np.cos(theta)) * (k @ k)


def pattern_matrix(steps) -> np.ndarray:
    """The 4×4 M of a marble's transform steps ``(kind, (x, y, z))`` (module docstring)."""
    m = np.eye(4)
    for kind, vector in steps:
        step = np.eye(4)
        x, y, z = (float(c) for c in vector)
        if kind == "translate":
            step[:3, 3] = (x, y, z)
        elif kind == "scale":
            step[:3, :3] = np.diag((x, y, z))
        elif kind == "rotate":
            step[:3, :3] = _rotation(2, z) @ _rotation(1, y) @ _rotation(0, x)
        else:
            raise ValueError(f"unknown transform step {kind!r}; expected translate, rotate or scale")
        m = step @ m
    return m


def pattern_points(points, channel) -> np.ndarray:
    """M⁻¹·p for an (N, 3) array of world-space points: where the untransformed pattern is
    looked up (the points themselves when the marble has no transform)."""
    p = np.asarray(points, dtype=np.float64)
    steps = getattr(channel, "transform", ())
    if not steps:
        return p
    m = pattern_matrix(steps)
    return np.linalg.solve(m[:3, :3], (p - m[:3, 3]).reshape(-1, 3).T).T.reshape(p.shape)


def stripe(points, channel):
    """The marble's scalar t in [0, 1] at an (N, 3) array of world-space points -> (N,)."""
    p = pattern_points(points, channel)
    v = p * float(channel.scale)
    distortion = float(channel.distortion)
    if distortion != 0.0 and int(channel.octaves) > 0:
        phase = distortion * fractal(v[..., 0], v[..., 1], v[..., 2], channel.octaves,
                                     bool(channel.turbulence), getattr(channel, "gain", 0.5),
                                     getattr(channel, "lacunarity", 2.0))
    else:
        phase = 0.0
    a = v[..., _AXES[channel.axis]]
    if channel.function == "cosine":
        return stripe_of_phase(a + phase, "cosine")
    return stripe_of_phase(float(channel.period) * a + phase, channel.function)


def stripe_of_phase(phase, function):
    """t(φ): |sin πφ| (abs_sine), ½(sin φ + 1) (sine), ½(cos φ + 1) (cosine), the
    triangle wave 2s / 2(1 − s) or the sawtooth s, s = φ − ⌊φ⌋."""
    if function == "abs_sine":
        return np.abs(np.sin(math.pi * phase))
    if function in ("triangle", "sawtooth"):
        s = np.asarray(phase, dtype=np.float64) - np.floor(phase)
        if function == "sawtooth":
            return s
        return np.where(s < 0.5, 2.0 * s, 2.0 * (1.0 - s))
    if function == "sine":
        return 0.5 * (np.sin(phase) + 1.0)
    if function == "cosine":
        return 0.5 * (np.cos(phase) + 1.0)
    raise ValueError(f"unknown marble function {function!r}; expected abs_sine, sine, "
                     f"cosine, triangle or sawtooth")


def ramp(t, colours, positions=None):
    """Piecewise-linear ramp: K colours at keys k/(K−1) (or at ``positions``, see the
    module docstring), t clamped to [0, 1] -> (N, 3)."""
    c = np.asarray(colours, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(t, dtype=np.float64)
    K = len(c)
    if K == 0:
        raise ValueError("a ramp needs at least one colour")
    if K == 1:
        return np.broadcast_to(c[0], t.shape + (3,)).copy()
    if positions is not None:
        return _positioned_ramp(np.clip(t, 0.0, 1.0), c, np.asarray(positions, np.float64))
    s = np.clip(t, 0.0, 1.0) * (K - 1)
    k = np.minimum(np.floor(s), K - 2).astype(np.int64)
    f = (s - k)[..., None]
    return c[k] * (1.0 - f) + c[k + 1] * f


def _positioned_ramp(t, c, p):
    """The ramp at positions ``p`` (K, non-decreasing, in [0, 1]) of colours ``c``."""
    if len(p) != len(c):
        raise ValueError(f"{len(p)} positions for {len(c)} colours")
    k = np.searchsorted(p, t, side="right") - 1          # the last p_k ≤ t, −1 below p_0
    below, above = k < 0, k >= len(p) - 1
    k = np.clip(k, 0, len(p) - 2)
    width = p[k + 1] - p[k]
    f = np.where(width > 0.0, (t - p[k]) / np.where(width > 0.0, width, 1.0), 1.0)
    f = np.where(below, 0.0, np.where(above, 1.0, np.clip(f, 0.0, 1.0)))[..., None]
    return c[k] * (1.0 - f) + c[k + 1] * f


def marble_color(points, channel):
    """The marble channel's colour at an (N, 3) array of world-space points -> (N, 3)."""
    return ramp(stripe(points, channel), channel.ramp, getattr(channel, "ramp_positions", None))
