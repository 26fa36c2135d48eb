"""The scene model: immutable, typed, dependency-free.

This is the only thing the rest of mimarble consumes from the scene language
(the Mitsuba translator and the NumPy reference tracer both read it). Every
class is a frozen dataclass, compared and hashed by value. Vectors and colours
are tuples of three Python floats; counts are ints.

Each node may carry ``pos``, the :class:`Pos` (1-based line and column) of the
keyword that introduced it in the source file, so that later stages can point
at it in their own messages. ``pos`` takes no part in equality, hashing or
``repr``: two scenes that differ only in layout or comments are equal.

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
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from typing import Literal, NamedTuple, Union

from mimarble import parameters as marble_parameters
from . import rules, transforms
from .limits import MAX_IMAGE_SAMPLES

__all__ = [
    "Vec3",
    "RGB",
    "Pos",
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
    "Sphere",
    "Plane",
    "Box",
    "Mesh",
    "SHAPE_TYPES",
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

Vec3 = tuple[float, float, float]
RGB = tuple[float, float, float]
# Type hints only: the values are the marble's parameter table's (FUNCTIONS, FILTERS, AXES).
MarbleFunction = Literal[marble_parameters.FUNCTIONS]   # the one list: parameters.FUNCTIONS
MarbleFilter = Literal["none", "bandlimit", "prefilter"]
Axis = Literal["x", "y", "z"]

#: The marble functions, its filters and axes, and the Fig. 5 ramp (the marble's
#: parameter table, mimarble/parameters.py, declares them).
MARBLE_FUNCTIONS: tuple[str, ...] = marble_parameters.FUNCTIONS
MARBLE_FILTERS: tuple[str, ...] = marble_parameters.FILTERS
AXES: tuple[str, ...] = marble_parameters.AXES
FIG5_RAMP: tuple[RGB, ...] = marble_parameters.FIG5_RAMP


class Pos(NamedTuple):
    """A 1-based source position."""

    line: int
    column: int

    def __str__(self) -> str:
        return f"{self.line}:{self.column}"


def _pos() -> Pos | None:
    return field(default=None, compare=False, repr=False, kw_only=True)  # type: ignore[return-value]


class FrozenMap(Mapping):
    """An immutable, hashable, insertion-ordered mapping (``str -> Material``)."""

    __slots__ = ("_d", "_h")

    def __init__(self, items=()):
        self._d = dict(items)
        self._h = None

    def __getitem__(self, key):
        return self._d[key]

    def __iter__(self) -> Iterator:
        return iter(self._d)

    def __len__(self) -> int:
        return len(self._d)

    def __hash__(self) -> int:
        if self._h is None:
            self._h = hash(tuple(self._d.items()))
        return self._h

    def __eq__(self, other) -> bool:
        if isinstance(other, Mapping):
            return dict(self._d.items()) == dict(other.items())
        return NotImplemented

    def __repr__(self) -> str:
        return f"FrozenMap({self._d!r})"


# ---------------------------------------------------------------------------
# The constructors' checks: the parser's rules (rules.py), raised as ValueError/TypeError

def _shown(value) -> str:
    return rules.shortened(repr(value))


def _refuse(problem: str | None, value) -> None:
    """A rule's problem as the parser words it, with the value found."""
    if problem:
        raise ValueError(f"{problem}, found {_shown(value)}")


def _number(value, what: str) -> float:
    """A real number (not a bool), finite and within float32's range, as a float."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{what} must be a number, found {_shown(value)}")
    try:
        number = float(value)
    except OverflowError:
        number = math.copysign(math.inf, value)
    problem = rules.number_problem(number)
    if problem:
        raise ValueError(f"{what}: number {_shown(value)} {problem}")
    return number


def _integer(value, what: str, lo: int, hi: int) -> int:
    """An integral number in lo..hi, as an int."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{what} must be an integer, found {_shown(value)}")
    if not isinstance(value, numbers.Integral) and not math.isfinite(value):
        raise ValueError(f"{what} must be an integer, found {_shown(value)}")
    _refuse(rules.integer_problem(value, what, lo, hi), value)
    return int(value)


def _vector(value, what: str) -> tuple[float, float, float]:
    """Three numbers, as a tuple of floats."""
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{what} must be 3 numbers, found {_shown(value)}")
    try:
        items = tuple(value)
    except TypeError:
        raise TypeError(f"{what} must be 3 numbers, found {_shown(value)}") from None
    if len(items) != 3:
        raise ValueError(f"{what} needs 3 numbers, found {len(items)}")
    return tuple(_number(x, what) for x in items)  # type: ignore[return-value]


def _colour(value, what: str) -> tuple[float, float, float]:
    """A colour: three numbers, each ≥ 0."""
    given = tuple(value) if not isinstance(value, (str, bytes)) and hasattr(value, "__iter__") \
        else value
    rgb = _vector(given, f"{what} (a colour < r g b >)")
    for component, written in zip(rgb, given):
        _refuse(rules.colour_problem(component, what), written)
    return rgb


def _store(node, **values) -> None:
    """Set the checked (normalised) values on a frozen node."""
    for name, value in values.items():
        object.__setattr__(node, name, value)


def _instances(values, kind, what: str) -> tuple:
    """``values`` as a tuple, each an instance of ``kind``."""
    values = tuple(values)
    for value in values:
        if not isinstance(value, kind):
            raise TypeError(f"{what} must hold {kind.__name__} objects, found {_shown(value)}")
    return values


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
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        lo, hi = rules.IMAGE_SIZE
        width = _integer(self.width, "width", lo, hi)
        height = _integer(self.height, "height", lo, hi)
        samples = _integer(self.samples, "samples", 1, MAX_IMAGE_SAMPLES)
        problem = rules.image_samples_problem(width, height, samples)
        if problem:
            raise ValueError(problem)
        _store(self, width=width, height=height, samples=samples,
               background=_colour(self.background, "background"))

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
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        eye, lookat, up = (_vector(getattr(self, name), name) for name in ("eye", "lookat", "up"))
        fov = _number(self.fov, "fov")
        _refuse(rules.fov_problem(fov), self.fov)
        for problem in (rules.view_problem(eye, lookat), rules.up_problem(eye, lookat, up)):
            if problem:
                raise ValueError(problem)
        _store(self, eye=eye, lookat=lookat, up=up, fov=fov)


#: An area light's samples when its block says none (a 4×4 grid).
AREA_SAMPLES = 16


def _light_samples(value) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"samples must be an integer, found {_shown(value)}")
    if not isinstance(value, numbers.Integral) and not math.isfinite(value):
        raise ValueError(f"samples must be an integer, found {_shown(value)}")
    _refuse(rules.light_samples_problem(value), value)
    return int(value)


@dataclass(frozen=True)
class RectangleArea:
    """``area { axis1 <> axis2 <> samples N }``: a light's parallelogram, centred on its
    position, with edges ``axis1`` and ``axis2`` (full lengths, as POV-Ray's
    ``area_light``), sampled at the centres of an n×n grid (N = n²)."""

    axis1: Vec3
    axis2: Vec3
    samples: int = AREA_SAMPLES
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        axis1, axis2 = _vector(self.axis1, "axis1"), _vector(self.axis2, "axis2")
        problem = rules.area_axes_problem(axis1, axis2)
        if problem:
            raise ValueError(problem)
        _store(self, axis1=axis1, axis2=axis2, samples=_light_samples(self.samples))


@dataclass(frozen=True)
class SphereArea:
    """``area { radius R samples N }``: a spherical light of radius R around its
    position, seen from each shaded point as a disk facing it, sampled at N = n²
    stratum centres mapped onto the disk (docs/rendering-model.md, "Area lights")."""

    radius: float
    samples: int = AREA_SAMPLES
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        radius = _number(self.radius, "radius")
        _refuse(rules.area_radius_problem(radius), self.radius)
        _store(self, radius=radius, samples=_light_samples(self.samples))


@dataclass(frozen=True)
class Light:
    """``light { position <> color <> area { … } }``: a point light without distance
    falloff, or with ``area`` (a :class:`RectangleArea` or :class:`SphereArea`) an area
    light: its ``color`` is the total, split evenly over its samples, each a point light
    of the same model."""

    position: Vec3
    color: RGB = (1.0, 1.0, 1.0)
    area: RectangleArea | SphereArea | None = None
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        if self.area is not None and not isinstance(self.area, (RectangleArea, SphereArea)):
            raise TypeError(f"a light's area must be a RectangleArea, a SphereArea or None, "
                            f"found {_shown(self.area)}")
        _store(self, position=_vector(self.position, "position"),
               color=_colour(self.color, "light color"))

    @property
    def samples(self) -> int:
        """Its point samples: 1 for a point light."""
        return 1 if self.area is None else self.area.samples


@dataclass(frozen=True)
class ColorChannel:
    """``color < r g b >``: a constant colour (the paper's ChannelColor): three finite
    numbers. The language writes them ≥ 0; built in Python they may be negative (a
    signed term of an ``add``), and both renderers take them so."""

    rgb: RGB
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        _store(self, rgb=_vector(self.rgb, "color (a colour < r g b >)"))


@dataclass(frozen=True)
class MarbleChannel(marble_parameters.MarbleParameters):
    """``marble { ... }``: the paper's marble (ChannelMarble).

    With ``v = scale * p`` (p in world space) and
    ``F(v) = sum_{i<octaves} N(2^i v) / 2^i`` (``|N|`` when ``turbulence``)::

        abs_sine: t = |sin(pi * (period * v_axis + distortion * F(v)))|
        sine:     t = 0.5 * (sin(period * v_axis + distortion * F(v)) + 1)
        cosine:   t = 0.5 * (cos(v_axis + distortion * F(v)) + 1)   (period unused)

    Its fields are the rows of the marble's parameter table
    (mimarble/parameters.py: names, defaults, ranges), in order, then ``pos``.

    The colour is ``ramp`` at ``t``: K >= 1 colours at keys ``k / (K - 1)`` (or at
    ``ramp_positions``), piecewise linear, ``t`` clamped to [0, 1] (one colour: a
    constant). ``gain`` and ``lacunarity`` (0.5 and 2, the paper's) weigh and space the
    octaves, F = sum gain^i N(lacunarity^i v); ``triangle`` and ``sawtooth`` are
    POV-Ray's waves of the ``abs_sine`` phase (mimarble/texture/stripes.py).

    ``filter`` and ``tolerance`` are rendering options for Mitsuba (``bandlimit``
    leaves out octaves finer than the pixel footprint, ``prefilter`` averages the
    colour over the pixel's interval of phase; octaves that the colour error
    ``tolerance`` allows are left out, ``None``: the scene's default,
    mimarble/texture/error_budget.py); the reference tracer always renders the full marble.

    ``space`` (keyword-only, the language's ``space world|object``): ``world`` (the
    default, the paper's) evaluates the marble at the world point p; ``object`` at the
    point in the object space of the shape it shades (mimarble/scene/geometry.py), so
    that moving, turning or scaling the shape carries its pattern.

    ``transform`` (keyword-only, the language's ``transform { … }``) moves the pattern:
    steps ``(kind, (x, y, z))`` with kind ``translate``, ``rotate`` (degrees about x, then
    y, then z) or ``scale`` (POV-Ray's: 2 is twice as coarse), applied in order, so that
    ``v = scale · M⁻¹ · p`` with M = :attr:`to_world` (mimarble/scene/transforms.py).
    A scale step may be given one number. Checked here: the kinds, three finite numbers
    each, no scale factor 0, and M invertible in single precision.
    """

    pos: Pos | None = _pos()
    transform: tuple = field(default=(), kw_only=True)
    space: str = field(default="world", kw_only=True)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.space not in SPACES:
            raise ValueError(f"a marble's space is {' or '.join(SPACES)}, found "
                             f"{_shown(self.space)}")
        _store(self, transform=_transform_steps(self.transform, "MarbleChannel"))

    @property
    def axis_index(self) -> int:
        """0, 1 or 2 for ``axis`` x, y or z."""
        return AXES.index(self.axis)

    @property
    def to_world(self):
        """The transform's 4×4 matrix M (rows of floats, double precision): the identity
        without one."""
        return transforms.compose(self.transform)


#: Where a marble is evaluated: at the world point, or in the shaded shape's object space.
SPACES: tuple[str, ...] = ("world", "object")


def _transform_steps(steps, owner: str) -> tuple:
    """A transform's steps (a marble's, a box's, a mesh's: ``owner``), checked and stored
    as ``(kind, (x, y, z))`` tuples."""
    if isinstance(steps, (str, bytes)) or not hasattr(steps, "__iter__"):
        raise TypeError(f"{owner}: transform must be a sequence of (step, < x y z >), "
                        f"found {_shown(steps)}")
    out = []
    for step in steps:
        try:
            kind, vector = step
        except (TypeError, ValueError):
            raise TypeError(f"{owner}: a transform step is (kind, < x y z >), found "
                            f"{_shown(step)}") from None
        if kind not in transforms.STEPS:
            raise ValueError(f"{owner}: a transform step is translate, rotate or scale, "
                             f"found {_shown(kind)}")
        if kind == "scale" and isinstance(vector, numbers.Real):
            vector = (vector,) * 3
        vector = _vector(vector, f"transform {kind}")
        problem = transforms.step_problem(kind, vector)
        if problem:
            raise ValueError(f"{problem}, found {_shown(vector)}")
        out.append((kind, vector))
    problem = transforms.matrix_problem(transforms.compose(out))
    if problem:
        raise ValueError(problem)
    return tuple(out)


@dataclass(frozen=True)
class ImageChannel:
    """``image { file "maps/veins.png" }``: an 8-bit PNG or JPEG on the sphere's (u, v).

    ``file`` is as written; ``path`` is where it was found (the parser resolves it
    against the scene file's folder; built in Python without ``path``, ``file`` is
    taken from the working directory). Looked up as Mitsuba's ``bitmap`` texture
    does by default: 8-bit sRGB decoded to linear, bilinear, repeating; (u, v) as
    Mitsuba's ``sphere`` defines them (u = φ/2π around the z axis, v = θ/π from +z;
    v = 0 is the image's top row). Parsed, ``pos`` is the file string's (where errors
    about the file point), not the ``image`` keyword's.
    """

    file: str
    path: str | None = None
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        if not isinstance(self.file, str) or not self.file:
            raise ValueError(f"ImageChannel: file={self.file!r} must be a non-empty path")

    @property
    def location(self) -> str:
        """The file to read: ``path`` when the parser found it, else ``file``."""
        return self.path or self.file


def _check_operands(kind: str, operands) -> tuple:
    operands = tuple(operands)
    if len(operands) < 2:
        raise ValueError(f"{kind} needs two or more channels, got {len(operands)}")
    for operand in operands:
        if not isinstance(operand, CHANNEL_TYPES):
            raise TypeError(f"{kind}: {operand!r} is not a channel")
    return operands


def depth(channel) -> int:
    """How deep a channel nests: 1 for a colour, marble or image map, one more for each
    expression around the deepest of them (at most ``LIMITS["max_channel_depth"]``)."""
    return channel.__dict__.get("_depth", 1)


def size(channel) -> int:
    """How many channels a channel holds, itself included, each use of a shared one
    counted again (at most ``LIMITS["max_channel_size"]``)."""
    return channel.__dict__.get("_size", 1)


def _nest(expression) -> None:
    """Note an expression's depth (its operands', plus one) and size (theirs, plus one),
    within the limits."""
    level = 1 + max(depth(c) for c in expression.operands)
    count = 1 + sum(size(c) for c in expression.operands)
    problem = rules.depth_problem(level) or rules.size_problem(count)
    if problem:
        raise ValueError(problem)
    object.__setattr__(expression, "_depth", level)   # not fields: no part of ==, hash
    object.__setattr__(expression, "_size", count)


@dataclass(frozen=True)
class _Operation:
    """Two or more channels combined componentwise (``keyword`` names it)."""

    operands: tuple
    pos: Pos | None = _pos()
    keyword = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "operands", _check_operands(self.keyword, self.operands))
        _nest(self)


@dataclass(frozen=True)
class Add(_Operation):
    """``add { CH CH … }``: the componentwise sum of two or more channels."""

    keyword = "add"


@dataclass(frozen=True)
class Multiply(_Operation):
    """``multiply { CH CH … }``: the componentwise product of two or more channels."""

    keyword = "multiply"


@dataclass(frozen=True)
class Mix:
    """``mix { A B weight W }``: a·(1 − w) + b·w, componentwise; ``weight`` a channel or a
    number (a constant weight, not clamped)."""

    a: object
    b: object
    weight: object
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        _check_operands("mix", (self.a, self.b))
        if isinstance(self.weight, bool) or not isinstance(self.weight, CHANNEL_TYPES + (int, float)):
            raise TypeError(f"mix: weight={self.weight!r} must be a channel or a number")
        if isinstance(self.weight, (int, float)):
            object.__setattr__(self, "weight", _number(self.weight, "mix: weight"))
        _nest(self)

    @property
    def operands(self) -> tuple:
        """a, b and, when it is a channel, the weight."""
        return (self.a, self.b) + ((self.weight,) if isinstance(self.weight, CHANNEL_TYPES) else ())


#: Channels that combine other channels (the paper's future work, §5).
EXPRESSIONS = (Add, Multiply, Mix)
CHANNEL_TYPES = (ColorChannel, MarbleChannel, ImageChannel) + EXPRESSIONS

#: What a material component is bound to. ``None`` in a Material means the
#: component is absent (contributes nothing; renderers may skip it).
Channel = Union[ColorChannel, MarbleChannel, ImageChannel, Add, Multiply, Mix]


def walk(channel) -> Iterator:
    """The channel and every channel inside it, outermost first."""
    yield channel
    if isinstance(channel, EXPRESSIONS):
        for operand in channel.operands:
            yield from walk(operand)


def in_object_space(channel) -> bool:
    """Whether the channel holds a ``space object`` marble: evaluated in the object space of
    the shape it shades, so that each shape needs its own evaluation of it."""
    return any(isinstance(c, MarbleChannel) and c.space == "object" for c in walk(channel))


def replace_marbles(channel, **changes):
    """The channel with ``changes`` applied to every marble inside it."""
    if isinstance(channel, MarbleChannel):
        return replace(channel, **changes)
    if isinstance(channel, Mix):
        weight = channel.weight if isinstance(channel.weight, float) else \
            replace_marbles(channel.weight, **changes)
        return replace(channel, a=replace_marbles(channel.a, **changes),
                       b=replace_marbles(channel.b, **changes), weight=weight)
    if isinstance(channel, EXPRESSIONS):
        return replace(channel, operands=tuple(replace_marbles(c, **changes)
                                               for c in channel.operands))
    return channel


@dataclass(frozen=True)
class Subsurface:
    """``subsurface { albedo CH mean_free_path X density CH ior X }``: the material's inside
    is a scattering volume behind a smooth dielectric boundary (path mode only).

    At a point p inside: extinction σ_t(p) = d(p) / ``mean_free_path`` (d the ``density``
    channel's mean of its three components, at least 0; 1 everywhere without one), single-
    scattering albedo α(p) = the ``albedo`` channel's colour clamped to [0, 1]; σ_s = α·σ_t,
    σ_a = (1 − α)·σ_t; isotropic phase function. The boundary has relative index of
    refraction ``ior`` (inside over outside). Channels are evaluated at the world point (or
    in the shape's object space, for ``space object`` marbles), as on surfaces.
    """

    albedo: Channel
    mean_free_path: float
    ior: float = 1.5
    density: Channel | None = None
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        for name in ("albedo", "density"):
            channel = getattr(self, name)
            if (channel is not None or name == "albedo") and not isinstance(channel, CHANNEL_TYPES):
                raise TypeError(f"a subsurface's {name} must be a channel, found {_shown(channel)}")
            if channel is not None and any(isinstance(c, ImageChannel) for c in walk(channel)):
                raise ValueError(f"a subsurface's {name} cannot hold an image map: a volume "
                                 f"has no (u, v)")
        mfp = _number(self.mean_free_path, "mean_free_path")
        _refuse(rules.mean_free_path_problem(mfp), self.mean_free_path)
        ior = _number(self.ior, "ior")
        _refuse(rules.ior_problem(ior), self.ior)
        _store(self, mean_free_path=mfp, ior=ior)

    def channels(self) -> dict:
        """The channels present, by name (albedo, density)."""
        return {k: c for k, c in (("albedo", self.albedo), ("density", self.density))
                if c is not None}


@dataclass(frozen=True)
class Material:
    """``material "name" { ambient {CH} diffuse {CH} specular {CH} shininess N }``.

    With ``subsurface`` (a :class:`Subsurface`), the material is a scattering volume behind a
    dielectric boundary in path mode, and whitted mode refuses it.

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
    pos: Pos | None = _pos()

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise TypeError(f"a material name must be a string, found {_shown(self.name)}")
        problem = rules.material_name_problem(self.name)
        if problem:
            raise ValueError(problem)
        for component in ("ambient", "diffuse", "specular"):
            channel = getattr(self, component)
            if channel is not None and not isinstance(channel, CHANNEL_TYPES):
                raise TypeError(f'{component} of material "{rules.shortened(self.name)}" must '
                                f"be a channel or None, found {_shown(channel)}")
        if self.subsurface is not None and not isinstance(self.subsurface, Subsurface):
            raise TypeError(f'the subsurface of material "{rules.shortened(self.name)}" must be '
                            f"a Subsurface or None, found {_shown(self.subsurface)}")
        shininess = _number(self.shininess, "shininess")
        _refuse(rules.shininess_problem(shininess), self.shininess)
        _store(self, shininess=shininess)

    def channels(self) -> dict[str, Channel]:
        """The components that are present, by name (ambient, diffuse, specular)."""
        return {
            k: c
            for k, c in (("ambient", self.ambient), ("diffuse", self.diffuse), ("specular", self.specular))
            if c is not None
        }


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


@dataclass(frozen=True)
class Scene:
    """A whole scene file.

    ``materials`` maps names to materials in file order, each under its own name;
    every shape's ``material`` is a key of it (the constructor checks it, as the parser
    does). ``ambient`` is the global ambient light A. ``textures`` maps the names of the
    file's ``texture "NAME" { … }`` to their channels (the materials hold the channels
    themselves, so a texture used twice is one value, evaluated once). ``source`` is the
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
    source: str | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        # Accept lists and dicts from programmatic construction; store immutably.
        if not isinstance(self.materials, FrozenMap):
            if not isinstance(self.materials, Mapping):
                raise TypeError(f"materials must map names to materials, found "
                                f"{_shown(self.materials)}")
            object.__setattr__(self, "materials", FrozenMap(self.materials))
        if not isinstance(self.image, Image):
            raise TypeError(f"image must be an Image, found {_shown(self.image)}")
        if not isinstance(self.camera, Camera):
            raise TypeError(f"camera must be a Camera, found {_shown(self.camera)}")
        if not isinstance(self.textures, FrozenMap):
            if not isinstance(self.textures, Mapping):
                raise TypeError(f"textures must map names to channels, found "
                                f"{_shown(self.textures)}")
            object.__setattr__(self, "textures", FrozenMap(self.textures))
        for name, channel in self.textures.items():
            problem = rules.material_name_problem(name) if isinstance(name, str) else \
                "a texture's name is a string"
            if problem:
                raise ValueError(problem.replace("material", "texture"))
            if not isinstance(channel, CHANNEL_TYPES):
                raise TypeError(f'texture "{rules.shortened(name)}" must be a channel, found '
                                f"{_shown(channel)}")
        lights = _instances(self.lights, Light, "lights")
        spheres = _instances(self.spheres, Sphere, "spheres")
        planes = _instances(self.planes, Plane, "planes")
        boxes = _instances(self.boxes, Box, "boxes")
        meshes = _instances(self.meshes, Mesh, "meshes")
        for kind, items in (("light", lights), ("sphere", spheres), ("plane", planes),
                            ("box", boxes), ("mesh", meshes), ("texture", self.textures)):
            problem = rules.count_problem(kind, len(items))
            if problem:
                raise ValueError(problem)
        for name, material in self.materials.items():
            if not isinstance(material, Material):
                raise TypeError(f"materials must hold Material objects, found "
                                f"{_shown(material)}")
            if name != material.name:
                raise ValueError(f'materials: the name "{rules.shortened(name)}" holds '
                                 f'material "{rules.shortened(material.name)}"')
        for shape in spheres + planes + boxes + meshes:
            problem = rules.unknown_material(shape.material, self.materials)
            if problem:
                raise ValueError(problem)
        for light in lights:
            if isinstance(light.area, SphereArea):
                problem = rules.area_light_enclosure_problem(
                    light.position, light.area.radius, self.camera.eye, self.camera.lookat)
                if problem:
                    raise ValueError(problem)
        _store(self, ambient=_colour(self.ambient, "ambient"), lights=lights, spheres=spheres,
               planes=planes, boxes=boxes, meshes=meshes)

    def shapes(self) -> tuple:
        """``(id, shape)`` of every shape: spheres, planes, boxes, meshes, each kind in file
        order, ids ``sphere_0``, ``plane_0``, ``box_0``, ``mesh_0``, … (the Mitsuba
        scene's ids, ``mimarble bake --shape``'s)."""
        return tuple((f"{kind}_{k}", shape)
                     for kind, items in (("sphere", self.spheres), ("plane", self.planes),
                                         ("box", self.boxes), ("mesh", self.meshes))
                     for k, shape in enumerate(items))

    def bounded_shapes(self) -> tuple:
        """Every shape but the planes."""
        return self.spheres + self.boxes + self.meshes

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
