"""One record per kind of shape: its class, keyword, keys, limit, boundedness and (u, v).

Every list of shape kinds reads :data:`SHAPE_KINDS` — the scene's fields and ids, the
language's statements and block keys, the parser's counts and readers, the limits, the
renderers' tables (mimarble/mitsuba/translate/shapes.py, mimarble/reference/shapes.py,
keyed by ``keyword``) — so that a new kind is one class, one record and one entry in each
renderer's table. Standard library only (the scene package's rule).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from . import rules
from .limits import BY_KEY, Limit
from .shapes import Box, Mesh, Plane, Sphere

__all__ = ["ShapeKey", "ShapeKind", "SHAPE_KINDS", "SHAPE_TYPES", "BY_KEYWORD", "kind_of", "count_problem",
           "SPHERE", "PLANE", "BOX", "MESH"]


@dataclass(frozen=True)
class ShapeKey:
    """One key of a shape's block: its ``name``, its ``syntax`` (``vector``, ``number``,
    ``transform`` or ``file``) and, for a vector or a number, the rule its value must pass
    (rules.py: value -> problem | None), refused at the value."""

    name: str
    syntax: str
    problem: Callable | None = None


@dataclass(frozen=True)
class ShapeKind:
    """A kind of shape.

    ``cls`` its class (mimarble/scene/shapes.py); ``keyword`` its statement, its block's
    rule, the prefix of its ids (``sphere_0``) and its key in the renderers' tables;
    ``plural`` its :class:`~mimarble.scene.model.Scene` field (``Scene.spheres``) and the
    word of "too many spheres"; ``keys`` its block's keys in documentation order
    (``material`` follows); ``limit`` the most a scene holds (its record in limits.py, where
    the docs' row is written from) and ``count_reason`` the clause of the refusal;
    ``bounded``: False for an unbounded kind (the class answers the shape protocol:
    ``object_to_world()``, ``corners()``, ``bounds()``, shapes.py); ``without_uv`` None when it has (u, v), else how the image-map refusal names it
    (a mesh: "this mesh's file", whose texture coordinates decide); ``example`` one block
    of the language."""

    cls: type
    keyword: str
    plural: str
    keys: tuple[ShapeKey, ...]
    limit: Limit
    count_reason: str
    bounded: bool
    without_uv: str | None
    example: str

    def count_problem(self, count: int) -> str | None:
        """``count`` shapes of this kind are within the limit."""
        return rules.too_many(self.plural, count, self.limit.value, self.count_reason)


SPHERE = ShapeKind(
    Sphere, "sphere", "spheres",
    (ShapeKey("center", "vector"), ShapeKey("radius", "number", rules.radius_problem)),
    BY_KEY["max_spheres"], "the renderers' memory and time grow with them",
    bounded=True, without_uv=None,
    example='sphere { center < 0 0 0 > radius 1 material "m" }')

PLANE = ShapeKind(
    Plane, "plane", "planes",
    (ShapeKey("point", "vector"), ShapeKey("normal", "vector", rules.normal_problem)),
    BY_KEY["max_planes"], "every ray is tested against every plane",
    bounded=False, without_uv="a plane",
    example='plane { point < 0 -1 0 > normal < 0 1 0 > material "m" }')

BOX = ShapeKind(
    Box, "box", "boxes",
    (ShapeKey("min", "vector"), ShapeKey("max", "vector"), ShapeKey("transform", "transform")),
    BY_KEY["max_boxes"], "the renderers' memory and time grow with them",
    bounded=True, without_uv="a box",
    example='box { min < -1 -1 -1 > max < 1 1 1 > transform { rotate < 0 30 0 > } '
            'material "m" }')

MESH = ShapeKind(
    Mesh, "mesh", "meshes",
    (ShapeKey("file", "file"), ShapeKey("transform", "transform")),
    BY_KEY["max_meshes"], "each is a file read and a shape of its own",
    bounded=True, without_uv="this mesh's file",
    example='mesh { file "models/vase.ply" material "m" }')

#: Every kind, in the order of a scene's ids, its fields and the language's statements.
SHAPE_KINDS: tuple[ShapeKind, ...] = (SPHERE, PLANE, BOX, MESH)

#: Every kind's class, in the same order.
SHAPE_TYPES: tuple[type, ...] = tuple(kind.cls for kind in SHAPE_KINDS)

#: The kinds by keyword.
BY_KEYWORD: dict[str, ShapeKind] = {kind.keyword: kind for kind in SHAPE_KINDS}

_BY_CLASS = {kind.cls: kind for kind in SHAPE_KINDS}


def kind_of(shape) -> ShapeKind:
    """The kind of ``shape``; TypeError if it is not a shape."""
    kind = _BY_CLASS.get(type(shape))
    if kind is None:
        raise TypeError(f"{shape!r:.60} is not a shape")
    return kind


def count_problem(keyword: str, count: int) -> str | None:
    """Lights, shapes and named textures per scene within their limits, by keyword
    (a shape's from its kind, the others' from rules.count_problem)."""
    kind = BY_KEYWORD.get(keyword)
    return kind.count_problem(count) if kind else rules.count_problem(keyword, count)
