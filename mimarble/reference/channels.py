"""Every channel of the scene model, evaluated in float64 NumPy at surface points.

A channel gives a colour at each point of a surface (the paper's class Channel)::

    ColorChannel(rgb)        the constant rgb
    MarbleChannel(...)       the marble at the world-space point (:mod:`.marble`), or, with
                             space "object", at the point in the shaded shape's object space
    ImageChannel(file)       the image at the shape's (u, v) (:mod:`.image_map`)
    Add(c1, c2, …)           c1 + c2 + …              componentwise, left to right
    Multiply(c1, c2, …)      c1 · c2 · …              componentwise, left to right
    Mix(a, b, weight)        a·(1 − w) + b·w          w: the weight channel's colour
                                                      (componentwise) or the number

(u, v) are those of Mitsuba 3's ``sphere`` shape, for a sphere of centre c and
radius r (:func:`sphere_uv`): with local = (p − c)/r,
φ = atan2(local_y, local_x) (+ 2π where negative), u = φ/2π, θ the angle between
local and +z, v = θ/π. So u runs around the z axis from +x (u = 0) through +y
(u = ¼), and v from the +z pole (v = 0, the image's top row) to −z (v = 1).

Imports NumPy, the standard library, :mod:`mimarble.scene` and this package's
marble and image maps.
"""

from __future__ import annotations

import math

import numpy as np

from mimarble.scene.model import (
    Add,
    ColorChannel,
    ImageChannel,
    MarbleChannel,
    Mix,
    Multiply,
    walk,
)

from .image_map import bilinear, load_image
from .marble import marble_color

__all__ = ["channel_color", "sphere_uv", "needs_uv"]


def sphere_uv(points, centers, radii) -> np.ndarray:
    """(u, v) of Mitsuba's ``sphere`` at (k, 3) points on spheres of centres (k, 3) or (3,)
    and radii (k,) or scalar -> (k, 2) float64.

    local = (p − c)/r; u = φ/2π with φ = atan2(local_y, local_x) in [0, 2π);
    v = θ/π with θ the angle from +z: atan2(√(x² + y²), z), which equals
    arccos(z) on the unit sphere and stays accurate near the poles.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    c = np.asarray(centers, dtype=np.float64)
    r = np.asarray(radii, dtype=np.float64)
    local = (p - c) / r[..., None]
    x, y, z = local[:, 0], local[:, 1], local[:, 2]
    phi = np.arctan2(y, x)
    phi = np.where(phi < 0.0, phi + 2.0 * math.pi, phi)
    theta = np.arctan2(np.hypot(x, y), z)
    return np.stack([phi / (2.0 * math.pi), theta / math.pi], axis=-1)


def needs_uv(channel) -> bool:
    """Whether the channel (or any channel inside it) reads texture coordinates."""
    return any(isinstance(c, ImageChannel) for c in walk(channel))


def channel_color(channel, points, uv=None, object_points=None) -> np.ndarray:
    """A channel's colour at (k, 3) world-space points with (k, 2) texture coordinates and
    (k, 3) object-space points -> (k, 3).

    ``uv`` is needed only when the channel contains an image map (see
    :func:`sphere_uv`), ``object_points`` (the points in the object space of the shape
    they lie on) only when it contains a marble with space "object". Equal sub-channels
    of one expression are evaluated once.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if uv is not None:
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        if uv.shape[0] != points.shape[0]:
            raise ValueError(f"channel_color: {uv.shape[0]} texture coordinates "
                             f"for {points.shape[0]} points")
    if object_points is not None:
        object_points = np.asarray(object_points, dtype=np.float64).reshape(-1, 3)
        if object_points.shape[0] != points.shape[0]:
            raise ValueError(f"channel_color: {object_points.shape[0]} object-space points "
                             f"for {points.shape[0]} points")
    return _color(channel, (points, object_points), uv, {})


def _color(channel, points, uv, memo) -> np.ndarray:
    """The colour, evaluated once per distinct channel (``memo``); callers must not write to it.
    ``points``: (world, object space or None)."""
    hit = memo.get(channel)
    if hit is not None:
        return hit
    k = points[0].shape[0]
    if isinstance(channel, ColorChannel):
        out = np.broadcast_to(np.array(channel.rgb, dtype=np.float64), (k, 3)).copy()
    elif isinstance(channel, MarbleChannel):
        at = points[1] if channel.space == "object" else points[0]
        if at is None:
            raise ValueError("a marble in object space needs the object-space points "
                             "(object_points)")
        out = marble_color(at, channel)
    elif isinstance(channel, ImageChannel):
        if uv is None:
            raise ValueError(f"the image map {channel.location!r} needs texture coordinates (uv)")
        out = bilinear(load_image(channel.location), uv)
    elif isinstance(channel, Add):
        out = _color(channel.operands[0], points, uv, memo).copy()
        for c in channel.operands[1:]:
            out += _color(c, points, uv, memo)
    elif isinstance(channel, Multiply):
        out = _color(channel.operands[0], points, uv, memo).copy()
        for c in channel.operands[1:]:
            out *= _color(c, points, uv, memo)
    elif isinstance(channel, Mix):
        a = _color(channel.a, points, uv, memo)
        b = _color(channel.b, points, uv, memo)
        w = channel.weight if isinstance(channel.weight, float) \
            else _color(channel.weight, points, uv, memo)
        out = a * (1.0 - w) + b * w
    else:
        raise TypeError(f"unknown channel type {type(channel).__name__}")
    memo[channel] = out
    return out
