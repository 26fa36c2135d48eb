"""A translucent material's marbles band-limited to its mean free path (issue 40).

Inside a scattering volume light travels ~ one mean free path ℓ between collisions, and a
pixel's radiance is an average of the albedo over the many collisions of many walks, each
spread over many ℓ: a marble's octaves whose noise lattice is finer than ℓ are averaged
out, yet each costs as much to evaluate as a coarse one, at every collision. So the
random walk evaluates a subsurface's world-space marbles with the octaves

    K = max(1, #{ i < octaves : s · λ^i · ℓ ≤ 1 })

where octave i's lattice spacing in the world is 1 / (s · λ^i): λ the marble's
lacunarity, s = scale · σ_max(M⁻¹) the marble's largest stretch of a world length (its
``scale`` times the largest singular value of its transform's inverse, linear part), and
ℓ = ``mean_free_path`` (the mean free path where the density is 1). At least one octave
is kept: the veins' own shape. A stated bias, measured in docs/rendering-model.md
("Band-limited marble inside the walk"); both the Mitsuba walk (mimarble/mitsuba/translate/
media.py) and the float64 reference walk (mimarble/reference/volume_scene.py) apply it,
each evaluating the marble with its own code, so that their agreement tests still hold.

Left as they are: a subsurface with a ``density`` (its local mean free path ℓ/d is shorter
than ℓ where d > 1), and ``space object`` marbles (their stretch in the world depends on
each shape's placement, which the translator gives a medium of its own and this rule, given
the subsurface alone, does not see). The fast preview (the walk's limit
ℓ → 0) and surfaces keep every octave. Standard library only (the scene package).
"""

from __future__ import annotations

import dataclasses
import math

from .channels import MarbleChannel, map_marbles

__all__ = ["largest_stretch", "octaves_resolved", "band_limited"]


def largest_stretch(matrix) -> float:
    """σ_max(A⁻¹) = 1/σ_min(A) for A the 3×3 linear part of the 4×4 ``matrix`` (rows):
    how much M⁻¹ lengthens a world vector at most. σ_min(A)² is the smallest eigenvalue
    of the symmetric AᵀA, from the closed form of a 3×3 symmetric eigenproblem (Smith
    1961: the three roots of the characteristic cubic as cosines)."""
    a = [[float(matrix[r][c]) for c in range(3)] for r in range(3)]
    g = [[sum(a[k][i] * a[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    q = (g[0][0] + g[1][1] + g[2][2]) / 3.0
    off = g[0][1] ** 2 + g[0][2] ** 2 + g[1][2] ** 2
    p = math.sqrt(((g[0][0] - q) ** 2 + (g[1][1] - q) ** 2 + (g[2][2] - q) ** 2
                   + 2.0 * off) / 6.0)
    if p <= 1e-15 * max(q, 1e-300):                      # a multiple of the identity
        smallest = q
    else:
        b = [[(g[i][j] - (q if i == j else 0.0)) / p for j in range(3)] for i in range(3)]
        det = (b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1])
               - b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0])
               + b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]))
        phi = math.acos(max(-1.0, min(1.0, det / 2.0))) / 3.0
        smallest = q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
    return 1.0 / math.sqrt(max(smallest, 1e-300))


def octaves_resolved(marble: MarbleChannel, length: float) -> int:
    """K (module docstring): the marble's octaves whose lattice spacing in the world is at
    least ``length``, at least 1 (or its ``octaves`` if fewer) and at most its ``octaves``."""
    stretch = marble.scale * largest_stretch(marble.to_world)
    kept = min(1, marble.octaves)
    while kept < marble.octaves and stretch * marble.lacunarity ** kept * length <= 1.0:
        kept += 1
    return kept


def band_limited(subsurface):
    """The subsurface as the random walk evaluates it: its albedo (or reflectance) channel's
    world-space marbles with :func:`octaves_resolved` octaves for its ``mean_free_path``;
    unchanged with a density (module docstring)."""
    if subsurface.density is not None:
        return subsurface

    def limited(marble: MarbleChannel) -> MarbleChannel:
        if marble.space != "world":
            return marble
        kept = octaves_resolved(marble, subsurface.mean_free_path)
        return marble if kept == marble.octaves else dataclasses.replace(marble, octaves=kept)

    kind = "albedo" if subsurface.albedo is not None else "reflectance"
    return dataclasses.replace(subsurface, **{kind: map_marbles(getattr(subsurface, kind),
                                                                limited)})
