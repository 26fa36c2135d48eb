"""The shapes of a scene: sphere, plane, box and mesh, each checked as the parser checks it, and one record per kind.

Each answers the shape protocol the renderers and tools read: ``object_to_world()`` (its
object space, as 4×4 rows: geometry.py's docstring says each kind's), ``corners()`` (its
eight world corners, None where unbounded or unknown) and ``bounds()`` ((centre, radius)
of a sphere around it, None where unbounded).

Every list of shape kinds reads :data:`SHAPE_KINDS`, one :class:`ShapeKind` record per
kind — the scene's fields and ids, the language's statements, block keys and grammar
rules, the parser's counts and readers, the limits, the renderers' tables
(mimarble/mitsuba/translate/shapes.py, mimarble/reference/shapes.py, keyed by
``keyword``) — so that a new kind is one class and one record here, its field on the
Scene, its limit and an entry in each renderer's table.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from . import geometry, rules, transforms
from .channels import transform_steps
from .limits import BY_KEY, Limit
from .nodes import (Pos, Vec3, checked_number, pos_field, refuse, shown, store_checked,
                    checked_vector)


@dataclass(frozen=True)
class Sphere:
    """``sphere { center <> radius R material "name" }``."""

    material: str
    center: Vec3 = (0.0, 0.0, 0.0)
    radius: float = 1.0
    pos: Pos | None = pos_field()

    def __post_init__(self) -> None:
        if not isinstance(self.material, str):
            raise TypeError(f"a sphere's material is a material's name, found "
                            f"{shown(self.material)}")
        radius = checked_number(self.radius, "radius")
        refuse(rules.radius_problem(radius), self.radius)
        store_checked(self, center=checked_vector(self.center, "center"), radius=radius)

    def object_to_world(self) -> geometry.Matrix:
        """The unit sphere at the origin, placed by translate(center)·scale(radius)."""
        r = self.radius
        return geometry.frame_matrix(((r, 0.0, 0.0), (0.0, r, 0.0), (0.0, 0.0, r)), self.center)

    def corners(self) -> list:
        """The corners of the cube around the sphere, in world space."""
        return [tuple(c + s * self.radius for c, s in zip(self.center, (x, y, z)))
                for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)]

    def bounds(self):
        return self.center, self.radius


def _material_name(shape) -> None:
    if not isinstance(shape.material, str):
        raise TypeError(f"a {type(shape).__name__.lower()}'s material is a material's name, "
                        f"found {shown(shape.material)}")


@dataclass(frozen=True)
class Plane:
    """``plane { point <> normal <> material "name" }``: the infinite plane through
    ``point`` perpendicular to ``normal`` (not zero; stored as given, the renderers
    normalise it). Rendered as a disk reaching far past the scene
    (mimarble/scene/geometry.py, ``plane_disk``); shaded with its normal facing the viewer,
    as every surface."""

    material: str
    point: Vec3 = (0.0, 0.0, 0.0)
    normal: Vec3 = (0.0, 1.0, 0.0)
    pos: Pos | None = pos_field()

    def __post_init__(self) -> None:
        _material_name(self)
        normal = checked_vector(self.normal, "normal")
        problem = rules.normal_problem(normal)
        if problem:
            raise ValueError(f"{problem}, found {shown(self.normal)}")
        store_checked(self, point=checked_vector(self.point, "point"), normal=normal)

    def object_to_world(self) -> geometry.Matrix:
        """The plane y = 0, normal +y, placed by geometry.plane_frame then translate(point)."""
        return geometry.frame_matrix(geometry.plane_frame(self.normal), self.point)

    def corners(self) -> None:
        return None                  # unbounded

    def bounds(self) -> None:
        return None                  # unbounded


@dataclass(frozen=True)
class Box:
    """``box { min <> max <> transform { … } material "name" }``: the box between the
    corners ``min`` and ``max`` (each coordinate of ``min`` below that of ``max``), in
    its object space, placed in the world by ``transform`` (steps as a marble's:
    mimarble/scene/transforms.py)."""

    material: str
    min: Vec3 = (-1.0, -1.0, -1.0)
    max: Vec3 = (1.0, 1.0, 1.0)
    transform: tuple = ()
    pos: Pos | None = pos_field()

    def __post_init__(self) -> None:
        _material_name(self)
        lo, hi = checked_vector(self.min, "min"), checked_vector(self.max, "max")
        problem = rules.box_problem(lo, hi)
        if problem:
            raise ValueError(f"{problem}, found min {shown(lo)} max {shown(hi)}")
        store_checked(self, min=lo, max=hi, transform=transform_steps(self.transform, "Box"))

    def object_to_world(self) -> geometry.Matrix:
        return transforms.compose(self.transform)

    def corners(self) -> list:
        return geometry.box_corners(self)

    def bounds(self):
        """Around its eight world corners."""
        return geometry.bounding_sphere(geometry.box_corners(self))


#: The mesh file formats, by file name ending.
MESH_FORMATS: tuple[str, ...] = (".ply", ".obj")


@dataclass(frozen=True)
class Mesh:
    """``mesh { file "vase.ply" transform { … } smooth true material "name" }``: the
    triangles of a PLY or OBJ file (polygons split into fans), in its coordinates, placed
    in the world by ``transform``. ``smooth``: shaded with vertex normals interpolated
    across each triangle (the file's, else computed as Mitsuba computes them: angle-
    weighted face normals) when true, flat (each triangle's own normal) when false; None
    (not written): smooth exactly when the file has vertex normals (:meth:`is_smooth`).
    Either way the normal faces the viewer; its texture coordinates, when the file has them, are the (u, v) of image maps and of
    ``mimarble bake``. ``file`` is as written, ``path`` where the parser found it
    (relative to the scene file; built in Python without ``path``, ``file`` is taken
    from the working directory); ``pos`` is the file string's, where errors about the
    file point. ``digest``: the SHA-256 of the file's bytes as the parser read them
    (``MeshFacts.digest``; None built in Python), so that two parses of a file rewritten
    in between are two models, for every cache keyed by the model (the loaded scenes'
    translations, a sweep's resume check, the bench's reference images)."""

    material: str
    file: str
    path: str | None = None
    transform: tuple = ()
    pos: Pos | None = pos_field()
    digest: str | None = None
    smooth: bool | None = None

    def __post_init__(self) -> None:
        _material_name(self)
        if self.smooth is not None and not isinstance(self.smooth, bool):
            raise TypeError(f"a mesh's smooth is True, False or None (the file's normals "
                            f"decide), found {shown(self.smooth)}")
        if not isinstance(self.file, str) or not self.file:
            raise ValueError(f"Mesh: file={self.file!r:.60} must be a non-empty path")
        if not self.file.lower().endswith(MESH_FORMATS):
            raise ValueError(rules.mesh_format_problem(self.file))
        store_checked(self, transform=transform_steps(self.transform, "Mesh"))

    def is_smooth(self, has_normals: bool) -> bool:
        """Whether the mesh is shaded smooth, its file having vertex normals or not
        (``MeshFacts.has_normals``): ``smooth`` as written, else the file decides."""
        return has_normals if self.smooth is None else self.smooth

    @property
    def location(self) -> str:
        """The file to read: ``path`` when the parser found it, else ``file``."""
        return self.path or self.file

    def object_to_world(self) -> geometry.Matrix:
        return transforms.compose(self.transform)

    def corners(self) -> list | None:
        """geometry.mesh_corners: None where the file cannot be read."""
        return geometry.mesh_corners(self)

    def bounds(self):
        """Around its eight world corners; a mesh whose file cannot be read, the
        translation of its transform, radius 0 (the one point known without it; the
        parser refuses such a scene)."""
        corners = geometry.mesh_corners(self)
        if corners is not None:
            return geometry.bounding_sphere(corners)
        m = transforms.compose(self.transform)
        return (m[0][3], m[1][3], m[2][3]), 0.0


# ---------------------------------------------------------------------------
# The kinds

@dataclass(frozen=True)
class ShapeKey:
    """One key of a shape's block: its ``name``, its ``syntax`` (``vector``, ``number``,
    ``transform``, ``file`` or ``boolean``) and, for a vector or a number, the rule its value must pass
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
    (ShapeKey("file", "file"), ShapeKey("transform", "transform"),
     ShapeKey("smooth", "boolean")),
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
