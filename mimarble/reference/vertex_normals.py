"""A smooth mesh's vertex normals in float64: the file's placed in the world, or computed as Mitsuba computes them; and their interpolation at a hit.

A mesh shaded smooth (``Mesh.is_smooth``, issue 42) is shaded, in both renderers, with

    n_s = normalize(b₀·n₀ + b₁·n₁ + b₂·n₂),   b₀ = 1 − b₁ − b₂,

its triangle's vertex normals n₀, n₁, n₂ weighted by the hit's barycentrics — Mitsuba
3.9.1's ``Mesh::compute_surface_interaction`` (src/render/mesh.cpp), which sets
``si.sh_frame.n`` so. The vertex normals are, as Mitsuba's loaders make them
(src/shapes/ply.cpp, obj.cpp, ``Mesh::recompute_vertex_normals``):

* **the file's** (PLY ``nx ny nz``, OBJ ``vn``): n = normalize(M⁻ᵀ·n_file), M the mesh's
  object-to-world matrix — a normal is carried by the inverse transpose, so that it stays
  perpendicular to the surface under a non-uniform scale;
* **computed**, where the file has none: Thürmer and Wüthrich's angle-weighted sum
  ("Computing Vertex Normals from Polygonal Facets", JGT 3(1), 1998) over the world
  triangles: each triangle of non-zero area adds its unit face normal
  (v₁ − v₀) × (v₂ − v₀)/|…| times its angle at the vertex, θᵢ = acos(d₀·d₁) between its
  two unit edges from that vertex; the sum is normalised, and a vertex whose sum is zero
  (no triangle of non-zero area) gets (1, 0, 0), Mitsuba's stand-in.

A vertex here is Mitsuba's: a PLY vertex record, an OBJ (v, vt, vn) triple
(mimarble/meshes/arrays.py), so a seam where texture coordinates split the vertices
splits the computed normals as it splits Mitsuba's. Written from the formulas above, not
from Mitsuba's code; NumPy only.
"""

from __future__ import annotations

import numpy as np

__all__ = ["placed_normals", "angle_weighted_normals", "interpolated_normals"]


def _unit_rows(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def placed_normals(normals: np.ndarray, to_world: np.ndarray) -> np.ndarray:
    """The file's normals (V, 3) in the world: normalize(M⁻ᵀ·n), M the linear part of the
    4×4 ``to_world``; unit rows (V, 3) float64."""
    linear = np.asarray(to_world, dtype=np.float64)[:3, :3]
    inverse_transpose = np.linalg.inv(linear).T
    return _unit_rows(np.asarray(normals, dtype=np.float64) @ inverse_transpose.T)


def angle_weighted_normals(positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Unit vertex normals (V, 3) of world ``positions`` (V, 3) and ``triangles`` (T, 3):
    Σ over a vertex's triangles of non-zero area of θ·n̂_face, normalised; (1, 0, 0)
    where the sum is zero (module docstring)."""
    positions = np.asarray(positions, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64)
    corners = positions[triangles]                                    # (T, 3, 3)
    face = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area2 = np.einsum("ij,ij->i", face, face)
    valid = area2 > 0.0
    corners, triangles = corners[valid], triangles[valid]
    face = face[valid] / np.sqrt(area2[valid])[:, None]
    total = np.zeros((len(positions), 3))
    for i in range(3):
        d0 = _unit_rows(corners[:, (i + 1) % 3] - corners[:, i])
        d1 = _unit_rows(corners[:, (i + 2) % 3] - corners[:, i])
        angle = np.arccos(np.clip(np.einsum("ij,ij->i", d0, d1), -1.0, 1.0))
        weighted = face * angle[:, None]
        for k in range(3):
            total[:, k] += np.bincount(triangles[:, i], weights=weighted[:, k],
                                       minlength=len(positions))
    length = np.linalg.norm(total, axis=1)
    out = np.tile([1.0, 0.0, 0.0], (len(positions), 1))
    some = length > 0.0
    out[some] = total[some] / length[some, None]
    return out


def interpolated_normals(normals: np.ndarray, triangles: np.ndarray, b1: np.ndarray,
                         b2: np.ndarray) -> np.ndarray:
    """The shading normal at hits on ``triangles`` (k, 3) with barycentrics ``b1``, ``b2``
    (k,) of vertices 1 and 2: normalize((1 − b₁ − b₂)·n₀ + b₁·n₁ + b₂·n₂), (k, 3)."""
    n = np.asarray(normals)[triangles]                                 # (k, 3, 3)
    b1, b2 = np.asarray(b1)[:, None], np.asarray(b2)[:, None]
    return _unit_rows((1.0 - b1 - b2) * n[:, 0] + b1 * n[:, 1] + b2 * n[:, 2])
