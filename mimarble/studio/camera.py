"""The studio's camera moves: orbit about the look-at point, and zoom.

The orbit moves only the eye (one edit of the key ``camera.eye``, what Save writes back),
the zoom only the fov (``camera.fov``). The orbit turns the eye's offset
from the look-at point about the camera's ``up`` axis (``dx`` degrees: a drag across)
and about the right-hand axis (``dy`` degrees: a drag up or down), the elevation kept
at least :data:`POLE_MARGIN` degrees from ``up`` and from its opposite, where the view
would turn about its own axis (a camera looking along ``up`` is refused by the model).
"""

from __future__ import annotations

import math

#: Degrees the eye's offset keeps from the up axis and its opposite.
POLE_MARGIN = 1.0
#: The largest zoom factor of one call, and the smallest.
ZOOM_LIMITS = (1e-3, 1e3)


def _sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def _add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def _scale(a, s):
    return tuple(x * s for x in a)


def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _norm(a):
    return math.sqrt(_dot(a, a))


def _rotate(v, axis, degrees):
    """``v`` turned by ``degrees`` about the unit ``axis`` (Rodrigues' formula)."""
    angle = math.radians(degrees)
    c, s = math.cos(angle), math.sin(angle)
    k_x_v = _cross(axis, v)
    k_dot_v = _dot(axis, v)
    return tuple(v[i] * c + k_x_v[i] * s + axis[i] * k_dot_v * (1.0 - c) for i in range(3))


def orbited_eye(camera, dx: float, dy: float) -> tuple[float, float, float]:
    """The eye of ``camera`` (a scene model Camera) turned ``dx`` degrees about its up
    axis through the look-at point, then ``dy`` degrees towards its up axis, the angle
    to ``up`` kept within [POLE_MARGIN, 180 − POLE_MARGIN]. ValueError for a number
    that is not finite."""
    for name, value in (("dx", dx), ("dy", dy)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value):
            raise ValueError(f"orbit: {name} must be a finite number of degrees, "
                             f"found {value!r:.40}")
    up = _scale(camera.up, 1.0 / _norm(camera.up))
    offset = _sub(camera.eye, camera.lookat)
    distance = _norm(offset)
    offset = _rotate(offset, up, -float(dx))
    # Elevation: the angle from up, moved by −dy (a drag up raises the eye), clamped.
    polar = math.degrees(math.acos(max(-1.0, min(1.0, _dot(offset, up) / distance))))
    wanted = min(max(polar - float(dy), POLE_MARGIN), 180.0 - POLE_MARGIN)
    right = _cross(offset, up)
    if _norm(right) > 0.0:
        offset = _rotate(offset, _scale(right, 1.0 / _norm(right)), polar - wanted)
    return _add(camera.lookat, offset)


def zoomed_fov(camera, factor: float) -> float:
    """The fov of ``camera`` zoomed by ``factor`` (> 1: closer), as a lens zooms: the
    image's half-height on the view plane, tan(fov/2), divided by ``factor``. The eye
    stays, so the clip planes do (moving the eye towards the look-at point would move
    them: literals of the traced code, a new kernel at every step). ValueError outside
    :data:`ZOOM_LIMITS`; the registry refuses a fov that is not in (0, 180)."""
    lo, hi = ZOOM_LIMITS
    if isinstance(factor, bool) or not isinstance(factor, (int, float)) \
            or not lo <= factor <= hi:
        raise ValueError(f"zoom: factor must be a number in {lo:g}..{hi:g}, "
                         f"found {factor!r:.40}")
    half = math.tan(math.radians(camera.fov) / 2.0) / float(factor)
    return math.degrees(2.0 * math.atan(half))
