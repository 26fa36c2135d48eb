"""What a mesh file holds, read from its header (PLY) or its lines (OBJ), within the limits.

STUB (interface only; the full module replaces it): ``mesh_facts(path)`` returns
:class:`MeshFacts` or raises :class:`MeshFileError` with one sentence.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["MeshFacts", "MeshFileError", "mesh_facts"]


class MeshFileError(ValueError):
    """A mesh file that cannot be used, in one sentence (no file name, no position)."""


@dataclass(frozen=True)
class MeshFacts:
    """``format`` "ply" or "obj"; ``vertices``; ``triangles`` (polygons split into fans);
    ``has_uv``: texture coordinates on every vertex."""

    format: str
    vertices: int
    triangles: int
    has_uv: bool


def mesh_facts(path: str) -> MeshFacts:
    raise MeshFileError("mesh files are not read yet (stub)")
