"""Where rays meet the prepared scene: the closest hit, shadow rays, and the hit record with its channel colours.

Spheres by the numerically stable quadratic, planes within their disks, boxes by the
slab test in object space, meshes by :mod:`.triangles`' hierarchy; hits count from
t > T_MIN_REL·(1 + max_k |o_k|) (:mod:`mimarble.contract`). :class:`HitRecord` is the
paper's "passing back": where and what was hit, and the material's channel colours at
the hit point, each distinct channel evaluated once per batch and only where used.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mimarble.contract import T_MIN_REL

from .channels import channel_color, needs_uv, sphere_uv
from .preparation import SLOTS, PreparedScene, as_prepared
from .shapes import REFERENCE_SHAPES, normalize_rows
from .vertex_normals import interpolated_normals


# ---------------------------------------------------------------------------
# Intersection

def sphere_roots(o, d, center, radius):
    """Both roots t_near ≤ t_far of |o + t d − c| = r for unit d (NaN where none).

    Stable form: b = (o−c)·d, disc = r² − |(o−c) − b d|² (no cancellation in
    b² − c), c' = (|o−c| − r)(|o−c| + r), q = −(b + sign(b)√disc), roots q and c'/q.
    """
    oc = o - center
    b = np.einsum("...k,...k->...", oc, d)
    e = oc - b[..., None] * d
    disc = radius * radius - np.einsum("...k,...k->...", e, e)
    lo = np.sqrt(np.einsum("...k,...k->...", oc, oc))
    c = (lo - radius) * (lo + radius)
    with np.errstate(invalid="ignore", divide="ignore"):
        sq = np.sqrt(disc)                       # NaN where the ray misses
        q = -(b + np.copysign(sq, b))
        t1 = q
        t2 = np.where(q != 0.0, c / q, -b)       # q == 0 only for a tangent ray at b = 0
    return np.minimum(t1, t2), np.maximum(t1, t2)


def intersect_spheres(centers, radii, o, d, t_min):
    """Closest hit over all spheres with t > t_min: (t (N,), sphere index (N,), -1 / inf on a miss)."""
    d = np.asarray(d, dtype=np.float64)
    n = d.shape[0]
    best_t = np.full(n, np.inf)
    best_i = np.full(n, -1, dtype=np.int64)
    t_min = np.broadcast_to(np.asarray(t_min, dtype=np.float64), (n,))
    for s in range(len(radii)):
        tn, tf = sphere_roots(o, d, centers[s], radii[s])
        t = np.where(tn > t_min, tn, np.where(tf > t_min, tf, np.inf))   # NaN compares False
        closer = t < best_t
        best_t = np.where(closer, t, best_t)
        best_i = np.where(closer, s, best_i)
    return best_t, best_i


def shadow_hit(centers, radii, o, d, t_max):
    """The paper's ``shadowHit``: does any sphere meet the ray at t in (0, t_max)?

    o, d: (N, 3) origins and unit directions; t_max: (N,). Any hit, early out:
    once a ray is blocked, the remaining spheres are not tested for it.
    Returns a bool (N,).
    """
    o = np.asarray(o, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    t_max = np.asarray(t_max, dtype=np.float64)
    blocked = np.zeros(d.shape[0], dtype=bool)
    live = np.arange(d.shape[0])
    for s in range(len(radii)):
        if live.size == 0:
            break
        tn, tf = sphere_roots(o[live], d[live], centers[s], radii[s])
        tm = t_max[live]
        hit_s = ((tn > 0.0) & (tn < tm)) | ((tf > 0.0) & (tf < tm))
        blocked[live[hit_s]] = True
        live = live[~hit_s]
    return blocked


def occluded(prep: PreparedScene, o, d, t_max):
    """``shadowHit`` over every shape: does any shape meet the ray at t in (0, t_max)?
    Spheres first (:func:`shadow_hit`), then the other kinds in the scene's order (planes,
    boxes: their closest hit in (0, t_max)) and the meshes (any hit), each testing only
    the rays no earlier shape blocked. Returns a bool (N,)."""
    blocked = shadow_hit(prep.centers, prep.radii, o, d, t_max)
    if prep.spheres_only:
        return blocked
    o, d = np.asarray(o, dtype=np.float64), np.asarray(d, dtype=np.float64)
    t_max = np.asarray(t_max, dtype=np.float64)
    live = np.flatnonzero(~blocked)
    tests = [lambda oo, dd, tm, closest=REFERENCE_SHAPES[keyword].closest, arrays=arrays:
             closest(arrays, oo, dd, 0.0, tm)[1] >= 0 for keyword, _, _, arrays in prep.kinds]
    if prep.meshes is not None:
        tests.append(prep.meshes.bvh.any_hit)
    for test in tests:
        if live.size == 0:
            break
        hit_s = test(o[live], d[live], t_max[live])
        blocked[live[hit_s]] = True
        live = live[~hit_s]
    return blocked


@dataclass
class HitRecord:
    """What :func:`hit` passes back for a batch of rays (the paper's hit record).

    Arrays over the rays that hit (``index`` gives their positions in the
    batch): distance ``t``, point ``p``, unit normal ``n`` facing the viewer
    (two-sided), view vector ``v`` = −d, the shape hit (``shape``: its index in
    ``scene.shapes()`` order; ``sphere``: the sphere's index, −1 for other shapes;
    ``triangle``: a mesh's triangle in the scene's hierarchy, −1 for other shapes, with
    ``bary`` its barycentrics (b₁, b₂) of vertices 1 and 2), the material hit, and, once
    :func:`fill_channels` has run, the channel colours ``colors[slot]``
    ((k, 3), or None when no hit material has that component). On a smooth mesh ``n``
    is the shading normal (its vertex normals interpolated: vertex_normals.py) and
    ``ng`` the geometric normal, both turned to the viewer's side of the geometric
    normal, shadow rays leaving along ``ng``; ``ng`` None: ``n`` is both.
    """

    count: int                      # rays in the batch
    index: np.ndarray               # (k,) positions of the hitting rays
    t: np.ndarray                   # (k,)
    p: np.ndarray                   # (k, 3)
    n: np.ndarray                   # (k, 3)
    v: np.ndarray                   # (k, 3)
    sphere: np.ndarray              # (k,)
    material: np.ndarray            # (k,)
    shape: np.ndarray | None = None     # (k,) global shape index
    triangle: np.ndarray | None = None  # (k,) −1 off meshes
    bary: np.ndarray | None = None      # (k, 2)
    colors: dict = field(default_factory=dict)
    ng: np.ndarray | None = None        # (k, 3) geometric normal where n is a shading one


def closest_hit(prep: PreparedScene, o, d) -> HitRecord:
    """Geometry of the closest hit of each ray over every shape (no colours yet)."""
    o = np.asarray(o, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    t_min = T_MIN_REL * (1.0 + np.max(np.abs(o), axis=-1))
    t, s = intersect_spheres(prep.centers, prep.radii, o, d, t_min)
    if not prep.spheres_only:
        return _closest_of_all(prep, o, d, t_min, t, s)
    idx = np.nonzero(s >= 0)[0]
    t, s = t[idx], s[idx]
    dd = d[idx]
    oo = o[idx] if o.ndim == 2 else o
    p = oo + t[:, None] * dd
    n = (p - prep.centers[s]) / prep.radii[s][:, None]
    v = -dd
    flip = np.einsum("ij,ij->i", n, v) < 0.0
    n[flip] = -n[flip]
    return HitRecord(count=d.shape[0], index=idx, t=t, p=p, n=n, v=v, sphere=s,
                     material=prep.sphere_material[s], shape=s,
                     triangle=np.full(len(s), -1, dtype=np.int64), bary=np.zeros((len(s), 2)))


def _closest_of_all(prep: PreparedScene, o, d, t_min, t, s) -> HitRecord:
    """closest_hit past the spheres (their t, s given): the other kinds in the scene's order
    (planes, boxes: reference/shapes.py), then the meshes; the point p = o + t·d and each
    kind's normal as in the spheres-only path."""
    n_rays = d.shape[0]
    shape = s.copy()                                  # global index; spheres' are theirs
    extras = []                                       # each kind's extra (a box's face axis)
    tri = np.full(n_rays, -1, dtype=np.int64)
    bary = np.zeros((n_rays, 2))
    for keyword, first, _, arrays in prep.kinds:
        tk, ik, ek = REFERENCE_SHAPES[keyword].closest(arrays, o, d, t_min, t)
        closer = ik >= 0
        t, shape = np.where(closer, tk, t), np.where(closer, first + ik, shape)
        extras.append(None if ek is None else np.where(closer, ek, 0))
    if prep.meshes is not None:
        tm, it, b1, b2 = prep.meshes.bvh.closest(o, d, t_min, t)
        closer = it >= 0
        t = np.where(closer, tm, t)
        shape = np.where(closer, prep.meshes.triangle_shape[np.maximum(it, 0)], shape)
        tri = np.where(closer, it, -1)
        bary = np.where(closer[:, None], np.stack([b1, b2], axis=1), 0.0)
    idx = np.nonzero(shape >= 0)[0]
    t, shape, tri, bary = t[idx], shape[idx], tri[idx], bary[idx]
    dd = d[idx]
    oo = o[idx] if o.ndim == 2 else o
    p = oo + t[:, None] * dd
    n = np.empty_like(p)
    sphere = np.where(shape < len(prep.radii), shape, -1)       # spheres come first
    on = sphere >= 0
    n[on] = (p[on] - prep.centers[sphere[on]]) / prep.radii[sphere[on]][:, None]
    for (keyword, first, count, arrays), extra in zip(prep.kinds, extras):
        on = (shape >= first) & (shape < first + count)
        n[on] = REFERENCE_SHAPES[keyword].normal(
            arrays, shape[on] - first, None if extra is None else extra[idx][on], p[on])
    on = tri >= 0
    if on.any():
        corners = prep.meshes.positions[prep.meshes.triangles[tri[on]]]     # (k, 3, 3)
        n[on] = normalize_rows(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
    v = -dd
    flip = np.einsum("ij,ij->i", n, v) < 0.0
    n[flip] = -n[flip]
    ng = None
    if prep.meshes is not None and prep.meshes.smooth is not None:
        smooth = on.copy()
        smooth[on] = prep.meshes.smooth[tri[on]]
        if smooth.any():            # the shading normal, on the geometric normal's side
            ng = n.copy()
            shading = interpolated_normals(prep.meshes.normals,
                                           prep.meshes.triangles[tri[smooth]],
                                           bary[smooth, 0], bary[smooth, 1])
            n[smooth] = np.where(flip[smooth, None], -shading, shading)
    return HitRecord(count=n_rays, index=idx, t=t, p=p, n=n, v=v, sphere=sphere,
                     material=prep.shape_material[shape], shape=shape, triangle=tri, bary=bary,
                     ng=ng)


def hit_uv(prep: PreparedScene, rec: HitRecord) -> np.ndarray:
    """(u, v) of every hit (k, 2): a sphere's Mitsuba sphere (u, v) from its centre and
    radius; a mesh's vertex texture coordinates interpolated, (1 − b₁ − b₂)·uv₀ + b₁·uv₁ +
    b₂·uv₂ (as Mitsuba's mesh interpolates them); NaN for shapes without (u, v)
    (prepare refuses image maps on them)."""
    if prep.spheres_only:
        return sphere_uv(rec.p, prep.centers[rec.sphere], prep.radii[rec.sphere])
    uv = np.full((rec.index.size, 2), np.nan)
    on = rec.sphere >= 0
    uv[on] = sphere_uv(rec.p[on], prep.centers[rec.sphere[on]], prep.radii[rec.sphere[on]])
    on = rec.triangle >= 0
    if on.any() and prep.meshes.uv is not None:
        corner = prep.meshes.uv[prep.meshes.triangles[rec.triangle[on]]]     # (k, 3, 2)
        b1, b2 = rec.bary[on, 0:1], rec.bary[on, 1:2]
        uv[on] = (1.0 - b1 - b2) * corner[:, 0] + b1 * corner[:, 1] + b2 * corner[:, 2]
    return uv


def object_points(prep: PreparedScene, rec: HitRecord) -> np.ndarray:
    """Every hit point in the object space of the shape hit, object_to_world(shape)⁻¹·p
    (k, 3), float64 (needs ``prep.from_world``: a scene with an object-space marble)."""
    m = prep.from_world[rec.shape]                                           # (k, 3, 4)
    return np.einsum("kij,kj->ki", m[:, :, :3], rec.p) + m[:, :, 3]


def fill_channels(prep: PreparedScene, rec: HitRecord, needed: dict) -> HitRecord:
    """Evaluate the channel colours into ``rec.colors`` ("passing back").

    ``needed[slot]`` is a bool (k,) mask of the hits where that component's
    value is used (elsewhere it is left 0). Each distinct channel is evaluated
    once, on the union of the points where any slot of any material uses it;
    image maps read the hit shape's (u, v) (:func:`hit_uv`), ``space object`` marbles
    the hit point in the hit shape's object space (:func:`object_points`).
    """
    k = rec.index.size
    slot_ch = prep.slot_channel[rec.material] if k else np.empty((0, 3), dtype=np.int64)
    want = {}                                   # channel index -> bool mask (k,)
    for s, slot in enumerate(SLOTS):
        mask = needed.get(slot)
        if mask is None:
            continue
        for c in np.unique(slot_ch[mask, s]):
            if c < 0:
                continue
            m = mask & (slot_ch[:, s] == c)
            want[c] = want[c] | m if c in want else m
    uv = hit_uv(prep, rec) if any(needs_uv(prep.channels[c]) for c in want) else None
    local = object_points(prep, rec) if prep.from_world is not None else None
    values = {}
    for c, m in want.items():
        full = np.zeros((k, 3))
        full[m] = channel_color(prep.channels[c], rec.p[m], None if uv is None else uv[m],
                                None if local is None else local[m])
        values[c] = full
    for s, slot in enumerate(SLOTS):
        mask = needed.get(slot)
        if mask is None or not any(c in values for c in np.unique(slot_ch[mask, s])):
            rec.colors[slot] = None
            continue
        out = np.zeros((k, 3))
        for c in np.unique(slot_ch[mask, s]):
            if c >= 0:
                m = mask & (slot_ch[:, s] == c)
                out[m] = values[c][m]
        rec.colors[slot] = out
    return rec


def hit(prep: PreparedScene, o, d) -> HitRecord:
    """Closest hit with every present channel's colour at every hit point."""
    prep = as_prepared(prep)
    rec = closest_hit(prep, o, d)
    everywhere = np.ones(rec.index.size, dtype=bool)
    return fill_channels(prep, rec, {slot: everywhere for slot in SLOTS})
