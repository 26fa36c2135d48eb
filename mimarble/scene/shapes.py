"""The shapes of a scene: sphere, plane, box and mesh, each checked as the parser checks it."""

from __future__ import annotations

from dataclasses import dataclass

from . import rules
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


#: Every kind of shape, in the order a scene lists them (and Mitsuba's ids number them).
SHAPE_TYPES = (Sphere, Plane, Box, Mesh)
