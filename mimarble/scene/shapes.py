"""The shapes of a scene: sphere, plane, box and mesh, each checked as the parser checks it.

Each answers the shape protocol the renderers and tools read: ``object_to_world()`` (its
object space, as 4×4 rows: geometry.py's docstring says each kind's), ``corners()`` (its
eight world corners, None where unbounded or unknown) and ``bounds()`` ((centre, radius)
of a sphere around it, None where unbounded). Its kind's record is in shape_kinds.py.
"""

from __future__ import annotations

from dataclasses import dataclass

from . import geometry, rules, transforms
from .channels import _transform_steps
from .nodes import Pos, Vec3, _number, _pos, _refuse, _shown, _store, _vector


@dataclass(frozen=True)
class Sphere:
    """``sphere { center <> radius R material "name" }``."""

    material: str
    center: Vec3 = (0.0, 0.0, 0.0)
    radius: float = 1.0
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        if not isinstance(self.material, str):
            raise TypeError(f"a sphere's material is a material's name, found "
                            f"{_shown(self.material)}")
        radius = _number(self.radius, "radius")
        _refuse(rules.radius_problem(radius), self.radius)
        _store(self, center=_vector(self.center, "center"), radius=radius)

    def object_to_world(self) -> geometry.Matrix:
        """The unit sphere at the origin, placed by translate(center)·scale(radius)."""
        r = self.radius
        return geometry._placed(((r, 0.0, 0.0), (0.0, r, 0.0), (0.0, 0.0, r)), self.center)

    def corners(self) -> list:
        """The corners of the cube around the sphere, in world space."""
        return [tuple(c + s * self.radius for c, s in zip(self.center, (x, y, z)))
                for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)]

    def bounds(self):
        return self.center, self.radius


def _material_name(shape) -> None:
    if not isinstance(shape.material, str):
        raise TypeError(f"a {type(shape).__name__.lower()}'s material is a material's name, "
                        f"found {_shown(shape.material)}")


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
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        _material_name(self)
        normal = _vector(self.normal, "normal")
        problem = rules.normal_problem(normal)
        if problem:
            raise ValueError(f"{problem}, found {_shown(self.normal)}")
        _store(self, point=_vector(self.point, "point"), normal=normal)

    def object_to_world(self) -> geometry.Matrix:
        """The plane y = 0, normal +y, placed by geometry.plane_frame then translate(point)."""
        return geometry._placed(geometry.plane_frame(self.normal), self.point)

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
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        _material_name(self)
        lo, hi = _vector(self.min, "min"), _vector(self.max, "max")
        problem = rules.box_problem(lo, hi)
        if problem:
            raise ValueError(f"{problem}, found min {_shown(lo)} max {_shown(hi)}")
        _store(self, min=lo, max=hi, transform=_transform_steps(self.transform, "Box"))

    def object_to_world(self) -> geometry.Matrix:
        return transforms.compose(self.transform)

    def corners(self) -> list:
        return geometry.box_corners(self)

    def bounds(self):
        """Around its eight world corners."""
        return geometry._around(geometry.box_corners(self))


#: The mesh file formats, by file name ending.
MESH_FORMATS: tuple[str, ...] = (".ply", ".obj")


@dataclass(frozen=True)
class Mesh:
    """``mesh { file "vase.ply" transform { … } material "name" }``: the triangles of a
    PLY or OBJ file (polygons split into fans), in its coordinates, placed in the world
    by ``transform``. Shaded flat (each triangle's own normal, facing the viewer); its
    texture coordinates, when the file has them, are the (u, v) of image maps and of
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
    pos: Pos | None = _pos()
    digest: str | None = None

    def __post_init__(self) -> None:
        _material_name(self)
        if not isinstance(self.file, str) or not self.file:
            raise ValueError(f"Mesh: file={self.file!r:.60} must be a non-empty path")
        if not self.file.lower().endswith(MESH_FORMATS):
            raise ValueError(rules.mesh_format_problem(self.file))
        _store(self, transform=_transform_steps(self.transform, "Mesh"))

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
            return geometry._around(corners)
        m = transforms.compose(self.transform)
        return (m[0][3], m[1][3], m[2][3]), 0.0
