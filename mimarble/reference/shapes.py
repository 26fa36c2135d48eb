"""Each kind of shape as the reference tracer sees it: its arrays, its closest hit, its normal.

:data:`REFERENCE_SHAPES` holds one :class:`ReferenceShape` per kind of
:data:`~mimarble.scene.shapes.SHAPE_KINDS`, by keyword. Planes (within the disks
they are rendered as) and boxes (the slab test in object space) are intersected here;
spheres (:mod:`.intersection`: the paper's stable quadratic, its fast path) and meshes
(one triangle hierarchy over all of them, :mod:`.triangles`) are the tracer's own, their
entries empty. :mod:`.preparation` builds each kind's arrays in the scene's order and
:mod:`.intersection` walks them, each kind testing against the nearest hit so far.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mimarble.scene import geometry

__all__ = ["ReferenceShape", "REFERENCE_SHAPES", "PlaneArrays", "BoxArrays", "intersect_planes",
           "intersect_boxes", "normalize_rows", "from_world_rows"]


def normalize_rows(v):
    """v/|v| along the last axis: each row of ``v`` (…, 3) scaled to unit length."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)



@dataclass(frozen=True)
class PlaneArrays:
    """Planes: a point, the unit normal, and the disk they are rendered as (centre, radius:
    geometry.plane_disk)."""

    point: np.ndarray              # (P, 3)
    normal: np.ndarray             # (P, 3)
    centre: np.ndarray             # (P, 3)
    radius: np.ndarray             # (P,)


@dataclass(frozen=True)
class BoxArrays:
    """Boxes: corners in object space, and world → object (M⁻¹, float64: rows 3×4)."""

    lo: np.ndarray                 # (B, 3)
    hi: np.ndarray                 # (B, 3)
    from_world: np.ndarray         # (B, 3, 4)


def from_world_rows(shapes) -> np.ndarray:
    """object_to_world(shape)⁻¹ of each shape (:func:`mimarble.scene.geometry.object_to_world`),
    inverted in float64, as rows 3×4: (n, 3, 4)."""
    if not shapes:
        return np.zeros((0, 3, 4))
    placed = np.array([geometry.object_to_world(shape) for shape in shapes], dtype=np.float64)
    return np.linalg.inv(placed)[:, :3, :]


def _plane_arrays(scene, planes) -> PlaneArrays:
    disks = [geometry.plane_disk(scene, plane) for plane in planes]
    normal = np.array([pl.normal for pl in planes], dtype=np.float64)
    return PlaneArrays(point=np.array([pl.point for pl in planes], dtype=np.float64),
                       normal=normalize_rows(normal),
                       centre=np.array([c for c, _ in disks], dtype=np.float64),
                       radius=np.array([r for _, r in disks], dtype=np.float64))


def _box_arrays(scene, boxes) -> BoxArrays:
    return BoxArrays(lo=np.array([b.min for b in boxes], dtype=np.float64),
                     hi=np.array([b.max for b in boxes], dtype=np.float64),
                     from_world=from_world_rows(boxes))


def intersect_planes(planes: PlaneArrays, o, d, t_lo, t_hi):
    """Closest plane hit with t_lo < t < t_hi within each plane's disk: (t (N,), plane index
    (N,)), inf / −1 on a miss. t = n·(p₀ − o)/(n·d) (inf or NaN, so missed, where the ray
    runs along the plane); kept where |o + t·d − centre| ≤ radius."""
    d = np.asarray(d, dtype=np.float64)
    o = np.broadcast_to(np.asarray(o, dtype=np.float64), d.shape)
    best_t = np.array(np.broadcast_to(t_hi, (d.shape[0],)), dtype=np.float64)
    best_i = np.full(d.shape[0], -1, dtype=np.int64)
    for k in range(len(planes.radius)):
        n = planes.normal[k]
        with np.errstate(invalid="ignore", divide="ignore"):
            t = ((planes.point[k] - o) @ n) / (d @ n)
        rel = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - planes.centre[k]
        inside = np.einsum("ij,ij->i", rel, rel) <= planes.radius[k] ** 2
        better = inside & (t > t_lo) & (t < best_t)
        best_t = np.where(better, t, best_t)
        best_i = np.where(better, k, best_i)
    best_t[best_i < 0] = np.inf
    return best_t, best_i


def intersect_boxes(boxes: BoxArrays, o, d, t_lo, t_hi):
    """Closest box hit with t_lo < t < t_hi: (t (N,), box index (N,), axis (N,) of the face
    hit in object space), inf / −1 on a miss. In the box's object space, o' = M⁻¹·(o, 1),
    d' = M⁻¹·(d, 0) (not unit: the same t); per axis the slab (lo_k − o'_k)/d'_k …
    (hi_k − o'_k)/d'_k, near = the largest entry, far = the smallest exit; the hit is near
    when it is past t_lo, else far (a ray from inside sees the inside), on the face of the
    axis that set it."""
    d = np.asarray(d, dtype=np.float64)
    o = np.broadcast_to(np.asarray(o, dtype=np.float64), d.shape)
    best_t = np.array(np.broadcast_to(t_hi, (d.shape[0],)), dtype=np.float64)
    best_i = np.full(d.shape[0], -1, dtype=np.int64)
    best_axis = np.zeros(d.shape[0], dtype=np.int64)
    for k in range(len(boxes.lo)):
        m = boxes.from_world[k]
        ob = o @ m[:, :3].T + m[:, 3]
        db = d @ m[:, :3].T
        with np.errstate(invalid="ignore", divide="ignore"):
            t0 = (boxes.lo[k] - ob) / db
            t1 = (boxes.hi[k] - ob) / db
        enter, leave = np.minimum(t0, t1), np.maximum(t0, t1)
        near, far = enter.max(axis=1), leave.min(axis=1)
        from_near = near > t_lo
        t = np.where(from_near, near, far)
        axis = np.where(from_near, enter.argmax(axis=1), leave.argmin(axis=1))
        better = (near <= far) & (t > t_lo) & (t < best_t)      # NaN compares False
        best_t = np.where(better, t, best_t)
        best_i = np.where(better, k, best_i)
        best_axis = np.where(better, axis, best_axis)
    best_t[best_i < 0] = np.inf
    return best_t, best_i, best_axis


def _plane_closest(planes: PlaneArrays, o, d, t_lo, t_hi):
    t, k = intersect_planes(planes, o, d, t_lo, t_hi)
    return t, k, None


def _plane_normal(planes: PlaneArrays, k, extra, p):
    return planes.normal[k]


def _box_normal(boxes: BoxArrays, k, axis, p):
    # The face's object normal ±e_k to the world by (M⁻¹)ᵀ: row k of M⁻¹'s linear part.
    return normalize_rows(boxes.from_world[k, axis, :3])


@dataclass(frozen=True)
class ReferenceShape:
    """A kind of shape in the reference tracer. ``arrays`` (scene, its shapes of this kind)
    -> what the other three read; ``closest`` (arrays, o, d, t_lo, t_hi) -> (t (N,), index
    among the kind's shapes (N,), extra (N,) or None), inf / −1 where no shape of the kind
    is hit in (t_lo, t_hi); ``normal`` (arrays, index (k,), extra (k,), p (k, 3)) -> the
    world normal at those hits (unit; the tracer turns it to the viewer). Shadow rays use
    ``closest`` over (0, t_max). All None: the tracer's own kind (spheres, meshes)."""

    arrays: Callable | None = None
    closest: Callable | None = None
    normal: Callable | None = None


#: Each kind of shape, by keyword (tests/test_shape_kinds.py checks every kind has its entry).
REFERENCE_SHAPES: dict[str, ReferenceShape] = {
    "sphere": ReferenceShape(),            # intersection.intersect_spheres, the fast path
    "plane": ReferenceShape(_plane_arrays, _plane_closest, _plane_normal),
    "box": ReferenceShape(_box_arrays, intersect_boxes, _box_normal),
    "mesh": ReferenceShape(),              # preparation's one triangle hierarchy
}
