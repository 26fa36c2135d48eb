"""A translucent material's single-scattering albedo on a grid: the random walk's lookup
(issue 40).

The walk asks for the albedo α(p) at every real collision — hundreds a path —, and a
marble costs its octaves of noise, its ramp and the reflectance's inversion each time.
Light travels ~ one mean free path ℓ between collisions and a pixel averages α over many
collisions of many walks, so α finer than ℓ is averaged out anyway (mimarble/scene/
band_limit.py keeps only the marble's octaves coarser than ℓ). So the walk reads α from
a grid of nodes made once per render (and after each edit of the colour): the trilinear
interpolation between the eight nodes around each collision, in expectation (the Mitsuba
walk draws one corner with its weight, the float64 walk interpolates):

    node (i, j, k) at  x = origin + h·(i, j, k),   0 ≤ i < n_x, …,    h = ℓ/2
    α(p) ≈ Σ over the cell's corners of α(node) · Π_axis (1 − |u − i|),   u = (p − origin)/h

over the axis-aligned box around the corners of the shapes that hold the medium (the
nodes reach past its far faces by less than h). A stated bias, measured against the
walk without the grid in docs/rendering-model.md ("The albedo grid"); both the Mitsuba walk
(``marble_medium``'s ``grid_*``, mimarble/mitsuba/translate/media.py) and the float64
reference walk (mimarble/reference/volume_scene.py) apply this rule, each with its own
code, so that their agreement tests still hold.

No grid (α evaluated at each collision, as before) for: a subsurface written with
``grid false`` (the exact walk, its only cost time), a colour with no marble (a
constant: nothing to save, and the grid would only round it), a subsurface with a
``density`` (as band_limit: its local mean free path ℓ/d may be shorter than h), a
medium whose shapes are not all bounded (a plane), and a grid of more than
``contract.MAX_GRID_NODES`` nodes (a small ℓ in a large object), decided here from the
counts before anything is allocated. Standard library only (the scene package).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mimarble.contract import MAX_GRID_NODES

from . import geometry
from .channels import MarbleChannel, walk

__all__ = ["AlbedoGrid", "albedo_grid", "medium_holders", "GRID_SPACING_PER_MEAN_FREE_PATH"]

#: h / ℓ: the spacing's trade of bias against time, measured on fig11a-translucent (a sphere
#: of radius 2, ℓ = 0.05: at ½, 161³ nodes, 33 MiB of half floats), is the table of
#: docs/rendering-model.md, "The albedo grid" (the error of trilinear interpolation falls
#: as h²).
GRID_SPACING_PER_MEAN_FREE_PATH = 0.5


@dataclass(frozen=True)
class AlbedoGrid:
    """The nodes' layout: node (i, j, k) at ``origin`` + ``spacing``·(i, j, k), for
    0 ≤ i < counts[0], 0 ≤ j < counts[1], 0 ≤ k < counts[2] (each count ≥ 2)."""

    origin: tuple
    spacing: float
    counts: tuple

    @property
    def nodes(self) -> int:
        return self.counts[0] * self.counts[1] * self.counts[2]


def albedo_grid(subsurface, shapes) -> AlbedoGrid | None:
    """The grid of the subsurface's α over the box around the world corners of ``shapes``
    (every shape that holds its medium: their ``corners()``, None for an unbounded one),
    or None where the walk evaluates α at each collision (module docstring)."""
    colour = subsurface.reflectance if subsurface.reflectance is not None \
        else subsurface.albedo
    if not subsurface.grid or subsurface.density is not None or colour is None \
            or not any(isinstance(c, MarbleChannel) for c in walk(colour)):
        return None
    corners = [shape.corners() for shape in shapes]
    if not corners or any(c is None for c in corners):
        return None
    corners = [corner for listed in corners for corner in listed]
    spacing = GRID_SPACING_PER_MEAN_FREE_PATH * subsurface.mean_free_path
    lo = tuple(min(c[axis] for c in corners) for axis in range(3))
    hi = tuple(max(c[axis] for c in corners) for axis in range(3))
    if not all(math.isfinite(v) for v in lo + hi):
        return None
    counts = []
    for axis in range(3):
        cells = (hi[axis] - lo[axis]) / spacing
        if not cells <= MAX_GRID_NODES:          # (also NaN) past any grid: no count made
            return None
        counts.append(max(2, math.ceil(cells) + 1))
    grid = AlbedoGrid(lo, spacing, tuple(counts))
    return grid if grid.nodes <= MAX_GRID_NODES else None


def medium_holders(shapes, material: str, placement=None) -> list:
    """The shapes of ``shapes`` that hold one medium of ``material``, the grid's extent: all
    the material's shapes, or with ``placement`` (the object-to-world matrix of a
    subsurface with object-space marbles, one medium a placement) those placed by it."""
    return [shape for shape in shapes if shape.material == material
            and (placement is None or geometry.object_to_world(shape) == placement)]
