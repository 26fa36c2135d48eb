"""Rays against many triangles in float64: a bounding-volume hierarchy built and traversed in NumPy.

:class:`TriangleBVH` holds up to :data:`~mimarble.scene.limits.MAX_MESH_TRIANGLES` (2²⁰)
triangles, every mesh of a scene together: in float64, 72 bytes a triangle (a vertex and
two edges) and 48 a node's box (fewer nodes than triangles), 0.11 GB held at 2²⁰ and
0.24 GB at the build's peak (docs/benchmarks.md). Triangles that are byte-for-byte copies
of another (the same corners in the same order) are held once, under the lowest index: a
copy gives every ray the same t, b₁, b₂, and ties go to the lowest index, so no copy can be
the hit.

**Build** (object median split, level by level): the tree is complete, 2^D leaves at depth
D, the smallest depth whose leaves hold at most :data:`LEAF_SIZE` triangles. Node i of
level d holds the triangles at positions ⌊i·T/2^d⌋ … ⌊(i+1)·T/2^d⌋ − 1 of an ordering, so
that its children hold its two halves; level by level, each node's triangles are sorted
along the longest axis of its centroids' box (one argsort for all nodes of a level), which
puts the median at its split. Boxes are computed bottom-up and widened by
:data:`BOX_PAD` × (1 + the largest |coordinate|), so that rounding in the slab test cannot
lose a hit on a box's face (a flat box of triangles in one plane included).

**Traversal**, vectorised over a batch of rays: a frontier of (ray, node) pairs, level by
level (slab test; pairs whose box is missed, lies beyond the ray's interval or, once hits
are known, beyond its closest hit, are dropped; the rest expand to both children).

**Memory**: the frontier is bounded whatever the overlap. Overlapping triangles (a fan's
slivers all meeting at its centre, a face written many times) put every ray in many boxes
at once, so a frontier of every (ray, node) pair met would grow as rays × triangles
(docs/benchmarks.md, "Meshes of overlapping triangles"). It is walked depth first in
chunks: a chunk of at most :data:`FRONTIER` pairs goes down a level at a time and, past
FRONTIER, is halved, one half waiting on a stack; the stack holds at most one chunk a
level, so at most (depth + 1)·FRONTIER pairs wait, 16 bytes each — with depth ≤ 18 (2²⁰
triangles, LEAF_SIZE 4) and 2¹⁸ pairs, 80 MB — and the triangle tests take
:data:`LEAF_PAIRS` (ray, leaf) pairs at a time (4·2¹⁶ triangle tests, about 80 MB of
working arrays). Overlap then costs time (each ray tests every triangle whose box it
meets), never memory. A usual mesh's frontier stays under FRONTIER (a few tens of pairs a
ray at RAY_BATCH rays), so it goes down in one chunk, level by level, as before.

**Leaves**: each ray's leaves are tested nearest box first in rounds of 1, 2, 4, …
leaves, and after each round leaves farther than the ray's closest hit are dropped
(closest hit) or the blocked rays leave (any hit). The triangle test is Möller–Trumbore in
float64: with e₁ = v₁ − v₀, e₂ = v₂ − v₀, p = d × e₂, det = e₁·p, s = o − v₀, q = s × e₁:
b₁ = s·p/det, b₂ = d·q/det, t = e₂·q/det, a hit where det ≠ 0, b₁ ≥ 0, b₂ ≥ 0,
b₁ + b₂ ≤ 1 (edges inclusive), the point o + t·d = (1 − b₁ − b₂)·v₀ + b₁·v₁ + b₂·v₂.

* :meth:`TriangleBVH.closest`: the closest hit with t_min < t < t_max (ties: the lowest
  triangle index) -> (t, triangle index, b₁, b₂), t = inf and index −1 on a miss;
* :meth:`TriangleBVH.any_hit`: whether some triangle meets the ray at 0 < t < t_max.

Imports NumPy only.
"""

from __future__ import annotations

import numpy as np

__all__ = ["TriangleBVH", "LEAF_SIZE", "RAY_BATCH", "FRONTIER", "LEAF_PAIRS", "BOX_PAD",
           "intersect_triangles"]

#: The most triangles a leaf holds (leaves hold between half of it and it).
LEAF_SIZE = 4
#: Rays traversed together (a few tens of (ray, node) pairs a ray at most levels of a
#: usual mesh: the frontier stays below FRONTIER).
RAY_BATCH = 8192
#: The most (ray, node) pairs a chunk of the traversal holds; past it a level's chunk is
#: halved (module docstring, "Memory").
FRONTIER = 1 << 18
#: The most (ray, leaf) pairs whose triangles are tested at once (LEAF_SIZE triangles each).
LEAF_PAIRS = 1 << 16
#: Boxes are widened by BOX_PAD·(1 + max |coordinate|) on every side.
BOX_PAD = 1e-9


def _cross(a, b):
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                     a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def _dot(a, b):
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def intersect_triangles(o, d, v0, e1, e2):
    """Möller–Trumbore (module docstring) for rows of rays o, d and triangles v0, e1, e2
    (all (n, 3)): (t, b1, b2, inside) with inside False where the ray misses or lies in
    the triangle's plane."""
    p = _cross(d, e2)
    det = _dot(e1, p)
    s = o - v0
    q = _cross(s, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        b1 = _dot(s, p) * inv
        b2 = _dot(d, q) * inv
        t = _dot(e2, q) * inv
        inside = (det != 0.0) & (b1 >= 0.0) & (b2 >= 0.0) & (b1 + b2 <= 1.0)
    return t, b1, b2, inside


#: Odd 64-bit multipliers of a triangle's nine coordinates' bit patterns (any fixed odd numbers).
_MIX = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9, 0xD6E8FEB86659FD93,
                 0xFF51AFD7ED558CCD, 0xC4CEB9FE1A85EC53, 0x94D049BB133111EB, 0xBF58476D1CE4E5B9,
                 0x2545F4914F6CDD1D], dtype=np.uint64)


def _first_of_each_copy(v0, v1, v2):
    """The lowest index of each set of byte-identical triangles (the same corners in the
    same order), ascending, or None when no two are: copies give every ray the same t, b₁,
    b₂, and a tie goes to the lowest index, so the others can never be the hit."""
    rows = np.ascontiguousarray(np.concatenate([v0, v1, v2], axis=1))
    # A 64-bit mix of each row's words first: copies mix alike, so rows whose mixes all
    # differ have no copies (the common case, one sort of integers).
    words = rows.view(np.uint64)
    mixed = (words * _MIX).sum(axis=1, dtype=np.uint64)
    mixed.sort()
    if not np.any(mixed[1:] == mixed[:-1]):
        return None
    _, first = np.unique(rows.view(np.dtype((np.void, rows.shape[1] * 8))).reshape(-1),
                         return_index=True)
    return None if len(first) == len(rows) else np.sort(first)


class TriangleBVH:
    """The hierarchy over triangles (v0, v1, v2), each (T, 3) float64 (module docstring)."""

    def __init__(self, v0, v1, v2) -> None:
        v0, v1, v2 = (np.asarray(v, dtype=np.float64).reshape(-1, 3) for v in (v0, v1, v2))
        kept = _first_of_each_copy(v0, v1, v2)          # triangle numbers, or None: all
        if kept is not None:
            v0, v1, v2 = v0[kept], v1[kept], v2[kept]
        count = len(v0)
        depth = 0
        while (count + (1 << depth) - 1) >> depth > LEAF_SIZE:      # ⌈T / 2^D⌉ > LEAF_SIZE
            depth += 1
        self.count, self.depth = count, depth
        order = self._order((v0 + v1 + v2) / 3.0, depth)
        self.index = order if kept is None else kept[order]  # slot -> triangle index
        self.v0 = v0[order]
        self.e1 = v1[order] - self.v0
        self.e2 = v2[order] - self.v0
        #: leaf i holds slots leaf_start[i] … leaf_start[i + 1] − 1
        self.leaf_start = (np.arange((1 << depth) + 1, dtype=np.int64) * count) >> depth
        self.lo, self.hi = self._boxes(v0[order], v1[order], v2[order])

    @staticmethod
    def _order(centroids, depth):
        """The slot order: each node's triangles sorted along its centroids' longest axis,
        all nodes of a level by one argsort of node + (key − node's least)/(its extent·(1 +
        2⁻²⁰)), which lies in [node, node + 1)."""
        count = len(centroids)
        order = np.arange(count, dtype=np.int64)
        rows = np.arange(count)
        for d in range(depth):
            starts = (np.arange((1 << d) + 1, dtype=np.int64) * count) >> d
            node = np.repeat(np.arange(1 << d), np.diff(starts))
            c = centroids[order]
            least = np.minimum.reduceat(c, starts[:-1], axis=0)
            extent = np.maximum.reduceat(c, starts[:-1], axis=0) - least
            axis = np.argmax(extent, axis=1)
            span = extent[np.arange(1 << d), axis] * (1.0 + 2.0 ** -20)
            span[span == 0.0] = 1.0                          # all centroids equal
            per = axis[node]
            key = node + (c[rows, per] - least[node, per]) / span[node]
            order = order[np.argsort(key)]
        return order

    def _boxes(self, a, b, c):
        """(lo, hi) of every node, heap order (node k's children 2k + 1, 2k + 2; level d
        from 2^d − 1), each widened by the pad."""
        if self.count == 0:
            return (np.zeros(1),) * 3, (np.zeros(1),) * 3
        lo = np.minimum.reduceat(np.minimum(np.minimum(a, b), c), self.leaf_start[:-1], axis=0)
        hi = np.maximum.reduceat(np.maximum(np.maximum(a, b), c), self.leaf_start[:-1], axis=0)
        levels_lo, levels_hi = [lo], [hi]
        while len(lo) > 1:
            lo = np.minimum(lo[0::2], lo[1::2])
            hi = np.maximum(hi[0::2], hi[1::2])
            levels_lo.append(lo)
            levels_hi.append(hi)
        pad = BOX_PAD * (1.0 + max(np.max(np.abs(levels_lo[-1])), np.max(np.abs(levels_hi[-1]))))
        lo = np.concatenate(levels_lo[::-1]) - pad
        hi = np.concatenate(levels_hi[::-1]) + pad
        return tuple(lo.T.copy()), tuple(hi.T.copy())     # per axis: the slab test's gathers

    # -- queries -------------------------------------------------------------

    def closest(self, o, d, t_min, t_max=np.inf):
        """Closest hit with t_min < t < t_max of rays o ((3,) or (N, 3)), d (N, 3):
        (t (N,), triangle (N,) int64, b1 (N,), b2 (N,)); a miss has t = inf, triangle −1."""
        return self._queries(o, d, t_min, t_max, any_hit=False)

    def any_hit(self, o, d, t_max):
        """Whether some triangle meets each ray at 0 < t < t_max: bool (N,)."""
        return self._queries(o, d, 0.0, t_max, any_hit=True)

    def _queries(self, o, d, t_lo, t_hi, any_hit):
        d = np.asarray(d, dtype=np.float64).reshape(-1, 3)
        n = len(d)
        o = np.broadcast_to(np.asarray(o, dtype=np.float64), (n, 3))
        t_lo = np.broadcast_to(np.asarray(t_lo, dtype=np.float64), (n,))
        t_hi = np.broadcast_to(np.asarray(t_hi, dtype=np.float64), (n,))
        t = np.array(t_hi, dtype=np.float64)
        tri = np.full(n, -1, dtype=np.int64)
        b1, b2 = np.zeros(n), np.zeros(n)
        if self.count:
            for s in range(0, n, RAY_BATCH):
                e = min(n, s + RAY_BATCH)
                self._batch(o[s:e], d[s:e], (t_lo[s:e], t_hi[s:e]), t[s:e], tri[s:e], b1[s:e],
                            b2[s:e], any_hit)
        if any_hit:
            return tri >= 0
        t[tri < 0] = np.inf
        return t, tri, b1, b2

    def _batch(self, o, d, bounds, best, tri, b1, b2, any_hit):
        """One batch, t in the open interval ``bounds`` (t_lo, t_hi); writes the hits into
        best, tri, b1, b2 (views of the caller's; best starts at t_hi).

        Depth first over chunks of (ray, node) pairs (module docstring, "Memory"): a chunk
        of at most :data:`FRONTIER` pairs goes down a level at a time; past FRONTIER it is
        halved and one half waits on a stack, one per level at most, so that overlapping
        triangles, whose boxes every ray meets, cost time but never more than
        (depth + 1)·FRONTIER pairs."""
        t_lo = bounds[0]
        with np.errstate(divide="ignore"):
            inv = 1.0 / d                      # ±inf along an axis the ray does not move on
        origin, slope = tuple(o.T.copy()), tuple(inv.T.copy())
        waiting = [(0, np.arange(len(d)), np.zeros(len(d), dtype=np.int64))]
        while waiting:
            level, ray, node = waiting.pop()
            while True:
                near, far = self._slab(origin, slope, ray, node)
                keep = (near <= far) & (far > t_lo[ray]) & (near < best[ray])
                if any_hit:
                    keep &= tri[ray] < 0                     # a blocked ray is done
                ray, node, near = ray[keep], node[keep], near[keep]
                if level == self.depth or not len(ray):
                    break
                ray = np.repeat(ray, 2)
                node = (2 * node[:, None] + np.array([1, 2])).reshape(-1)
                level += 1
                if len(ray) > FRONTIER:
                    half = len(ray) // 2
                    waiting.append((level, ray[half:], node[half:]))
                    ray, node = ray[:half], node[:half]
            if len(ray):
                self._leaf_rounds(o, d, bounds, best, tri, b1, b2, ray, node, near, any_hit)

    def _leaf_rounds(self, o, d, bounds, best, tri, b1, b2, ray, node, near, any_hit):
        """The leaves of (ray, leaf node) pairs, each ray's nearest box first, in rounds of
        1, 2, 4, … leaves a ray; after each round, leaves farther than the ray's closest
        hit are dropped (closest hit) or the blocked rays leave (any hit)."""
        leaf = node - ((1 << self.depth) - 1)
        order = np.lexsort((near, ray))          # rank 0, 1, … within each ray
        ray, leaf, near = ray[order], leaf[order], near[order]
        first = np.flatnonzero(np.r_[True, ray[1:] != ray[:-1]])
        rank = np.arange(len(ray)) - np.repeat(first, np.diff(np.r_[first, len(ray)]))
        low, width = 0, 1
        while len(ray):
            now = rank < low + width
            ray_now, leaf_now = ray[now], leaf[now]
            for s in range(0, len(ray_now), LEAF_PAIRS):        # bounded triangle tests
                self._leaves(o, d, bounds, best, tri, b1, b2, ray_now[s:s + LEAF_PAIRS],
                             leaf_now[s:s + LEAF_PAIRS], any_hit)
            low += width
            width *= 2
            left = ~now & (near <= best[ray]) if not any_hit else ~now & (tri[ray] < 0)
            ray, leaf, near, rank = ray[left], leaf[left], near[left], rank[left]

    def _slab(self, origin, slope, ray, node):
        """(near, far) of the rays' intervals in the nodes' boxes, per axis k
        (lo_k − o_k)/d_k and (hi_k − o_k)/d_k (NaN where a ray lies in a box face's plane:
        the pair is dropped, the box being padded past its triangles)."""
        near = far = None
        with np.errstate(invalid="ignore"):
            for k in range(3):
                o_k, s_k = origin[k][ray], slope[k][ray]
                a = self.lo[k][node]
                a -= o_k
                a *= s_k
                b = self.hi[k][node]
                b -= o_k
                b *= s_k
                if near is None:
                    near, far = np.minimum(a, b), np.maximum(a, b)
                else:
                    np.maximum(near, np.minimum(a, b), out=near)
                    np.minimum(far, np.maximum(a, b), out=far)
        return near, far

    def _leaves(self, o, d, bounds, best, tri, b1, b2, ray, leaf, any_hit):
        """Test the triangles of (ray, leaf) pairs; keep each ray's closest (or any) hit:
        t_lo < t < t_hi and t ≤ best, the lowest index among equal t."""
        t_lo, t_hi = bounds
        start, stop = self.leaf_start[leaf], self.leaf_start[leaf + 1]
        size = stop - start
        pair = np.repeat(np.arange(len(ray)), size)
        slot = start[pair] + np.arange(len(pair)) - np.repeat(np.cumsum(size) - size, size)
        r = ray[pair]
        t, u, v, inside = intersect_triangles(o[r], d[r], self.v0[slot], self.e1[slot],
                                              self.e2[slot])
        hit = inside & (t > t_lo[r]) & (t < t_hi[r]) & (t <= best[r])
        if not hit.any():
            return
        r, t, u, v, index = r[hit], t[hit], u[hit], v[hit], self.index[slot[hit]]
        order = np.lexsort((index, t, r))            # per ray: closest, then lowest index
        r, t, u, v, index = r[order], t[order], u[order], v[order], index[order]
        firsts = np.r_[True, r[1:] != r[:-1]]
        r, t, u, v, index = r[firsts], t[firsts], u[firsts], v[firsts], index[firsts]
        if any_hit:
            tri[r] = index
            return
        # t ≤ best[r] held (best = t_hi > t before the first hit): an equal t replaces an
        # earlier round's hit when its index is lower
        better = (t < best[r]) | (index < tri[r])
        r, t, u, v, index = r[better], t[better], u[better], v[better], index[better]
        best[r], tri[r], b1[r], b2[r] = t, index, u, v
