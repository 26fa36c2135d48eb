"""The scene model: immutable, typed, dependency-free.

The scene model (this module, with nodes.py, channels.py and shapes.py, whose names it
re-exports) is the only thing the rest of mimarble consumes from the scene language
(the Mitsuba translator and the NumPy reference tracer both read it). Every
class is a frozen dataclass, compared and hashed by value. Vectors and colours
are tuples of three Python floats; counts are ints.

Each node may carry ``pos``, the :class:`Pos` (1-based line and column) of the
keyword that introduced it in the source file, so that later stages can point
at it in their own messages. ``pos`` takes no part in equality, hashing or
``repr``: two scenes that differ only in layout or comments are equal. The image,
camera, lights and marbles also carry ``source`` (:class:`~mimarble.scene.nodes.Source`):
where their values' text stands, for rewriting a file in place (rewrite.py); it takes
no part in equality either.

The defaults of the constructors are the language's defaults (see
docs/scene-language.md), so ``MarbleChannel()`` is the marble of a
``marble { }`` block and ``Scene()`` is an empty file.

Constructors check what the parser checks, by the same rules (rules.py) and in the
same words, without a file position: a value it cannot take is a ValueError
(``radius must be > 0, found -1``), a value of the wrong type a TypeError. Numbers are
finite and within float32's range, colours ≥ 0, the image within its size and sample
limits, the camera's fov in (0, 180) with eye ≠ lookat and ``up`` not parallel to the
view, a sphere's radius > 0, an area light's samples (n², at most 1024), radius and
axes, a material's name and shininess, channels nested at most 64
deep, a scene's lights and spheres within their limits (limits.py), each material under
its own name and every sphere's material one of its materials. Vectors and colours are
stored as tuples of three floats, sizes as ints. ``MarbleChannel`` alone keeps what it is
given: the marble's parameter table checks its values where they are read (the parser,
the ``marble`` plugin). :func:`mimarble.scene.parse` checks the same, with file positions.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field

from . import rules
from .channels import (CHANNEL_TYPES, EXPRESSIONS, SPACES, Add, Channel, ColorChannel, ImageChannel,
                       MarbleChannel, Mix, Multiply, depth, in_object_space, replace_marbles, size,
                       walk)
from .limits import MAX_IMAGE_SAMPLES
from .nodes import (AXES, FIG5_RAMP, MARBLE_FILTERS, MARBLE_FUNCTIONS, RGB, Axis, FrozenMap,
                    MarbleFunction, Pos, Source, Vec3, checked_colour, checked_instances,
                    checked_integer, checked_number, pos_field, refuse, shown, source_field,
                    store_checked, checked_vector)
from .shapes import MESH_FORMATS, SHAPE_KINDS, SHAPE_TYPES, Box, Mesh, Plane, Sphere
from .transforms import compose

__all__ = [
    "Vec3",
    "RGB",
    "Pos",
    "Source",
    "Image",
    "Camera",
    "Light",
    "RectangleArea",
    "SphereArea",
    "AREA_SAMPLES",
    "ColorChannel",
    "MarbleChannel",
    "Channel",
    "Material",
    "Subsurface",
    "Environment",
    "Sphere",
    "Plane",
    "Box",
    "Mesh",
    "SHAPE_TYPES",
    "MESH_FORMATS",
    "SPACES",
    "Scene",
    "FrozenMap",
    "ImageChannel",
    "Add",
    "Multiply",
    "Mix",
    "EXPRESSIONS",
    "CHANNEL_TYPES",
    "walk",
    "in_object_space",
    "replace_marbles",
    "depth",
    "size",
    "MarbleFunction",
    "Axis",
    "FIG5_RAMP",
    "MARBLE_FUNCTIONS",
    "MARBLE_FILTERS",
    "AXES",
]

def samples_per_axis(spp) -> int:
    """n for spp = n² samples per pixel (an n×n grid of stratum centres).

    Raises ValueError when spp is not a perfect square ≥ 1 (the one rule that
    the scene language, the Mitsuba translator and the reference tracer share).
    """
    n = math.isqrt(spp) if isinstance(spp, int) and not isinstance(spp, bool) and spp >= 1 else 0
    if n < 1 or n * n != spp:
        raise ValueError(f"spp={spp!r} must be a perfect square n·n ≥ 1 (1, 4, 9, 16, …): "
                         f"pixels are sampled on an n×n grid")
    return n


@dataclass(frozen=True)
class Image:
    """``image { width W height H samples S background <r g b> }``.

    ``samples`` is the number of samples per pixel. Whitted mode and the
    reference tracer need a perfect square n*n: pixels are sampled at the
    centres of an n x n stratified grid (the pixel centre when ``samples == 1``),
    ``samples_per_axis`` is n; path mode takes any count.
    """

    width: int = 500
    height: int = 500
    samples: int = 1
    background: RGB = (0.0, 0.0, 0.0)
    pos: Pos | None = pos_field()
    source: Source | None = source_field()

    def __post_init__(self) -> None:
        lo, hi = rules.IMAGE_SIZE
        width = checked_integer(self.width, "width", lo, hi)
        height = checked_integer(self.height, "height", lo, hi)
        samples = checked_integer(self.samples, "samples", 1, MAX_IMAGE_SAMPLES)
        problem = rules.image_samples_problem(width, height, samples)
        if problem:
            raise ValueError(problem)
        store_checked(self, width=width, height=height, samples=samples,
               background=checked_colour(self.background, "background"))

    @property
    def samples_per_axis(self) -> int:
        return math.isqrt(self.samples)

    @property
    def aspect(self) -> float:
        """width / height."""
        return self.width / self.height


@dataclass(frozen=True)
class Camera:
    """``camera { eye <> lookat <> up <> fov F }``, a pinhole camera.

    ``fov`` is the full *vertical* field of view in degrees (Mitsuba:
    ``fov_axis = "y"``); the horizontal one follows from the image aspect.
    ``up`` need not be perpendicular to the view direction, only not parallel.
    """

    eye: Vec3 = (0.0, 0.0, 10.0)
    lookat: Vec3 = (0.0, 0.0, 0.0)
    up: Vec3 = (0.0, 1.0, 0.0)
    fov: float = 30.0
    pos: Pos | None = pos_field()
    source: Source | None = source_field()

    def __post_init__(self) -> None:
        eye, lookat, up = (checked_vector(getattr(self, name), name) for name in ("eye", "lookat", "up"))
        fov = checked_number(self.fov, "fov")
        refuse(rules.fov_problem(fov), self.fov)
        for problem in (rules.view_problem(eye, lookat), rules.up_problem(eye, lookat, up)):
            if problem:
                raise ValueError(problem)
        store_checked(self, eye=eye, lookat=lookat, up=up, fov=fov)


#: An area light's samples when its block says none (a 4×4 grid).
AREA_SAMPLES = 16


def _light_samples(value) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"samples must be an integer, found {shown(value)}")
    if not isinstance(value, numbers.Integral) and not math.isfinite(value):
        raise ValueError(f"samples must be an integer, found {shown(value)}")
    refuse(rules.light_samples_problem(value), value)
    return int(value)


@dataclass(frozen=True)
class RectangleArea:
    """``area { axis1 <> axis2 <> samples N }``: a light's parallelogram, centred on its
    position, with edges ``axis1`` and ``axis2`` (full lengths, as POV-Ray's
    ``area_light``), sampled at the centres of an n×n grid (N = n²)."""

    axis1: Vec3
    axis2: Vec3
    samples: int = AREA_SAMPLES
    pos: Pos | None = pos_field()

    def __post_init__(self) -> None:
        axis1, axis2 = checked_vector(self.axis1, "axis1"), checked_vector(self.axis2, "axis2")
        problem = rules.area_axes_problem(axis1, axis2)
        if problem:
            raise ValueError(problem)
        store_checked(self, axis1=axis1, axis2=axis2, samples=_light_samples(self.samples))


@dataclass(frozen=True)
class SphereArea:
    """``area { radius R samples N }``: a spherical light of radius R around its
    position, seen from each shaded point as a disk facing it, sampled at N = n²
    stratum centres mapped onto the disk (docs/rendering-model.md, "Area lights")."""

    radius: float
    samples: int = AREA_SAMPLES
    pos: Pos | None = pos_field()

    def __post_init__(self) -> None:
        radius = checked_number(self.radius, "radius")
        refuse(rules.area_radius_problem(radius), self.radius)
        store_checked(self, radius=radius, samples=_light_samples(self.samples))


@dataclass(frozen=True)
class Light:
    """``light { position <> color <> area { … } }``: a point light without distance
    falloff, or with ``area`` (a :class:`RectangleArea` or :class:`SphereArea`) an area
    light: its ``color`` is the total, split evenly over its samples, each a point light
    of the same model."""

    position: Vec3
    color: RGB = (1.0, 1.0, 1.0)
    area: RectangleArea | SphereArea | None = None
    pos: Pos | None = pos_field()
    source: Source | None = source_field()

    def __post_init__(self) -> None:
        if self.area is not None and not isinstance(self.area, (RectangleArea, SphereArea)):
            raise TypeError(f"a light's area must be a RectangleArea, a SphereArea or None, "
                            f"found {shown(self.area)}")
        store_checked(self, position=checked_vector(self.position, "position"),
               color=checked_colour(self.color, "light color"))

    @property
    def samples(self) -> int:
        """Its point samples: 1 for a point light."""
        return 1 if self.area is None else self.area.samples


@dataclass(frozen=True)
class Environment:
    """``environment { file "sky.exr" intensity X rotate < a b c > }`` or ``environment {
    color < r g b > intensity X }``: the light from far away, in every direction.

    ``file``: a latitude-longitude image (OpenEXR, Radiance HDR, 8-bit PNG or JPEG, the
    last two sRGB-decoded), as Mitsuba's ``envmap`` maps it: the direction d, turned back
    by ``rotate`` (R⁻¹·d; degrees about x, then y, then z, as a transform's ``rotate``),
    is seen at u = atan2(d_x, −d_z)/2π, v = acos(d_y)/π, bilinear (columns wrap, rows
    clamp). ``color``: the same radiance everywhere. Either is scaled by ``intensity``.
    ``path``: where the parser found ``file`` (built in Python without it, ``file`` is
    taken from the working directory); ``pos`` is the file string's when parsed.
    Path mode: Mitsuba's ``envmap`` / ``constant``, seen by the camera; whitted mode:
    the background of camera rays (docs/rendering-model.md, "The environment").
    """

    file: str | None = None
    color: RGB | None = None
    intensity: float = 1.0
    rotate: Vec3 = (0.0, 0.0, 0.0)
    path: str | None = None
    pos: Pos | None = pos_field()
    source: Source | None = source_field()

    def __post_init__(self) -> None:
        if self.file is not None and (not isinstance(self.file, str) or not self.file):
            raise ValueError(f"Environment: file={shown(self.file)} must be a non-empty path")
        rotate = checked_vector(self.rotate, "rotate")
        problem = rules.environment_problem(self.file is not None, self.color is not None,
                                            any(rotate))
        if problem:
            raise ValueError(problem)
        intensity = checked_number(self.intensity, "intensity")
        refuse(rules.intensity_problem(intensity), self.intensity)
        color = None if self.color is None else checked_colour(self.color, "environment color")
        store_checked(self, intensity=intensity, rotate=rotate, color=color)

    @property
    def location(self) -> str | None:
        """The file to read: ``path`` when the parser found it, else ``file``."""
        return self.path or self.file

    def rotation(self):
        """The 3×3 rotation R that ``rotate`` makes (environment to world), rows of floats."""
        return tuple(row[:3] for row in compose([("rotate", self.rotate)])[:3])


@dataclass(frozen=True)
class Subsurface:
    """``subsurface { reflectance CH | albedo CH  mean_free_path X density CH ior X }``: the
    material's inside is a scattering volume behind a boundary (path mode only;
    ``subsurface_boundary``).

    At a point p inside: extinction σ_t(p) = d(p) / ``mean_free_path`` (d the ``density``
    channel's mean of its three components, at least 0; 1 everywhere without one), single-
    scattering albedo α(p) = the ``albedo`` channel's colour clamped to [0, 1] — or, given
    ``reflectance`` instead (exactly one of the two), the α whose thick slab shows that
    colour C(p) under even light (the multiple-scattering albedo, inverted per point for the
    boundary's ``ior``: docs/rendering-model.md, "The colour you see: reflectance");
    σ_s = α·σ_t, σ_a = (1 − α)·σ_t; isotropic phase function. The boundary has relative
    index of refraction ``ior`` (inside over outside). Channels are evaluated at the world
    point (or in the shape's object space, for ``space object`` marbles), as on surfaces.

    ``mean_free_path`` is required; its default (None) only lets ``albedo`` default to
    None, so that ``Subsurface(reflectance=C, mean_free_path=0.2)`` reads as the block does.
    ``grid`` (default True): whether the random walk may read the albedo from a grid
    (mimarble/scene/albedo_grid.py, a stated bias); False: evaluated at every collision.
    """

    albedo: Channel | None = None
    mean_free_path: float = None
    ior: float = 1.5
    density: Channel | None = None
    reflectance: Channel | None = None
    grid: bool = True
    pos: Pos | None = pos_field()

    def __post_init__(self) -> None:
        if (self.albedo is None) == (self.reflectance is None):
            raise ValueError("a subsurface takes exactly one of albedo (single-scattering) "
                             "and reflectance (the colour seen), found "
                             + ("both" if self.albedo is not None else "neither"))
        for name in ("albedo", "reflectance", "density"):
            channel = getattr(self, name)
            if channel is not None and not isinstance(channel, CHANNEL_TYPES):
                raise TypeError(f"a subsurface's {name} must be a channel, found {shown(channel)}")
            if channel is not None and any(isinstance(c, ImageChannel) for c in walk(channel)):
                raise ValueError(f"a subsurface's {name} cannot hold an image map: a volume "
                                 f"has no (u, v)")
        mfp = checked_number(self.mean_free_path, "mean_free_path")
        refuse(rules.mean_free_path_problem(mfp), self.mean_free_path)
        if not isinstance(self.grid, bool):
            raise TypeError(f"a subsurface's grid is True or False, found {shown(self.grid)}")
        ior = checked_number(self.ior, "ior")
        refuse(rules.ior_problem(ior), self.ior)
        store_checked(self, mean_free_path=mfp, ior=ior)

    def channels(self) -> dict:
        """The channels present, by name (albedo or reflectance, density)."""
        return {k: c for k, c in (("albedo", self.albedo), ("reflectance", self.reflectance),
                                  ("density", self.density))
                if c is not None}


@dataclass(frozen=True)
class Material:
    """``material "name" { ambient {CH} diffuse {CH} specular {CH} shininess N }``.

    With ``subsurface`` (a :class:`Subsurface`), the material is a scattering volume behind a
    boundary in path mode, and whitted mode refuses it.

    Shading (whitted mode), per light l with visibility V and intensity I_l::

        L = ka(p) * A + sum_l V * I_l * (kd(p) * max(0, n.l)
                                         + ks(p) * max(0, n.h) ** shininess)
    """

    name: str
    ambient: Channel | None = None
    diffuse: Channel | None = None
    specular: Channel | None = None
    shininess: float = 32.0
    subsurface: Subsurface | None = None
    pos: Pos | None = pos_field()

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise TypeError(f"a material name must be a string, found {shown(self.name)}")
        problem = rules.material_name_problem(self.name)
        if problem:
            raise ValueError(problem)
        for component in ("ambient", "diffuse", "specular"):
            channel = getattr(self, component)
            if channel is not None and not isinstance(channel, CHANNEL_TYPES):
                raise TypeError(f'{component} of material "{rules.shortened(self.name)}" must '
                                f"be a channel or None, found {shown(channel)}")
        if self.subsurface is not None and not isinstance(self.subsurface, Subsurface):
            raise TypeError(f'the subsurface of material "{rules.shortened(self.name)}" must be '
                            f"a Subsurface or None, found {shown(self.subsurface)}")
        shininess = checked_number(self.shininess, "shininess")
        refuse(rules.shininess_problem(shininess), self.shininess)
        store_checked(self, shininess=shininess)

    def channels(self) -> dict[str, Channel]:
        """The components that are present, by name (ambient, diffuse, specular)."""
        return {
            k: c
            for k, c in (("ambient", self.ambient), ("diffuse", self.diffuse), ("specular", self.specular))
            if c is not None
        }


@dataclass(frozen=True)
class Scene:
    """A whole scene file.

    ``materials`` maps names to materials in file order, each under its own name;
    every shape's ``material`` is a key of it (the constructor checks it, as the parser
    does). ``ambient`` is the global ambient light A. ``textures`` maps the names of the
    file's ``texture "NAME" { … }`` to their channels (the materials hold the channels
    themselves, so a texture used twice is one value, evaluated once). ``environment``
    is the light from far away (:class:`Environment`, or None). ``source`` is the
    file it came from (None for text parsed without a file name); it takes no part in
    equality.
    """

    image: Image = Image()
    camera: Camera = Camera()
    ambient: RGB = (0.0, 0.0, 0.0)
    lights: tuple[Light, ...] = ()
    materials: Mapping[str, Material] = field(default_factory=FrozenMap)
    spheres: tuple[Sphere, ...] = ()
    planes: tuple[Plane, ...] = ()
    boxes: tuple[Box, ...] = ()
    meshes: tuple[Mesh, ...] = ()
    textures: Mapping[str, Channel] = field(default_factory=FrozenMap)
    environment: Environment | None = None
    source: str | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        # Accept lists and dicts from programmatic construction; store immutably.
        if not isinstance(self.materials, FrozenMap):
            if not isinstance(self.materials, Mapping):
                raise TypeError(f"materials must map names to materials, found "
                                f"{shown(self.materials)}")
            object.__setattr__(self, "materials", FrozenMap(self.materials))
        if not isinstance(self.image, Image):
            raise TypeError(f"image must be an Image, found {shown(self.image)}")
        if not isinstance(self.camera, Camera):
            raise TypeError(f"camera must be a Camera, found {shown(self.camera)}")
        if not isinstance(self.textures, FrozenMap):
            if not isinstance(self.textures, Mapping):
                raise TypeError(f"textures must map names to channels, found "
                                f"{shown(self.textures)}")
            object.__setattr__(self, "textures", FrozenMap(self.textures))
        for name, channel in self.textures.items():
            problem = rules.material_name_problem(name) if isinstance(name, str) else \
                "a texture's name is a string"
            if problem:
                raise ValueError(problem.replace("material", "texture"))
            if not isinstance(channel, CHANNEL_TYPES):
                raise TypeError(f'texture "{rules.shortened(name)}" must be a channel, found '
                                f"{shown(channel)}")
        if self.environment is not None and not isinstance(self.environment, Environment):
            raise TypeError(f"environment must be an Environment or None, found "
                            f"{shown(self.environment)}")
        lights = checked_instances(self.lights, Light, "lights")
        of = {kind.plural: checked_instances(getattr(self, kind.plural), kind.cls, kind.plural)
              for kind in SHAPE_KINDS}
        for problem in (rules.count_problem("light", len(lights)),
                        *(kind.count_problem(len(of[kind.plural])) for kind in SHAPE_KINDS),
                        rules.count_problem("texture", len(self.textures))):
            if problem:
                raise ValueError(problem)
        for name, material in self.materials.items():
            if not isinstance(material, Material):
                raise TypeError(f"materials must hold Material objects, found "
                                f"{shown(material)}")
            if name != material.name:
                raise ValueError(f'materials: the name "{rules.shortened(name)}" holds '
                                 f'material "{rules.shortened(material.name)}"')
        for shape in (shape for items in of.values() for shape in items):
            problem = rules.unknown_material(shape.material, self.materials)
            if problem:
                raise ValueError(problem)
        for light in lights:
            if isinstance(light.area, SphereArea):
                problem = rules.area_light_enclosure_problem(
                    light.position, light.area.radius, self.camera.eye, self.camera.lookat)
                if problem:
                    raise ValueError(problem)
        store_checked(self, ambient=checked_colour(self.ambient, "ambient"), lights=lights, **of)

    def shapes(self) -> tuple:
        """``(id, shape)`` of every shape: kind by kind (SHAPE_KINDS: spheres, planes,
        boxes, meshes), each kind in file order, ids ``sphere_0``, ``plane_0``, ``box_0``,
        ``mesh_0``, … (the Mitsuba scene's ids, ``mimarble bake --shape``'s)."""
        return tuple((f"{kind.keyword}_{k}", shape) for kind in SHAPE_KINDS
                     for k, shape in enumerate(getattr(self, kind.plural)))

    def bounded_shapes(self) -> tuple:
        """Every shape of a bounded kind (all but the planes), kind by kind."""
        return tuple(shape for kind in SHAPE_KINDS if kind.bounded
                     for shape in getattr(self, kind.plural))

    def shape(self, shape_id: str):
        """The shape of id ``shape_id`` (:meth:`shapes`); KeyError naming the ids if none."""
        found = dict(self.shapes())
        if shape_id not in found:
            raise KeyError(f"no shape {shape_id!r:.60} in the scene (its shapes: "
                           f"{', '.join(found) or 'none'})")
        return found[shape_id]

    def image_maps(self) -> tuple:
        """Every distinct image map the materials use."""
        found = [c for m in self.materials.values() for ch in m.channels().values()
                 for c in walk(ch) if isinstance(c, ImageChannel)]
        return tuple(dict.fromkeys(found))

    def material_of(self, shape) -> Material:
        """The material a shape refers to."""
        return self.materials[shape.material]
