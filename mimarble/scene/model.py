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
``marble { }`` block and ``Scene()`` is an empty file. Constructors do not
validate; :func:`mimarble.scene.parse` does, with file positions.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from typing import Literal, NamedTuple, Union

from .. import marble_parameters

__all__ = [
    "Vec3",
    "RGB",
    "Pos",
    "Image",
    "Camera",
    "Light",
    "ColorChannel",
    "MarbleChannel",
    "Channel",
    "Material",
    "Sphere",
    "Scene",
    "FrozenMap",
    "ImageChannel",
    "Add",
    "Multiply",
    "Mix",
    "EXPRESSIONS",
    "CHANNEL_TYPES",
    "walk",
    "replace_marbles",
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
MarbleFunction = Literal["abs_sine", "sine", "cosine"]
MarbleFilter = Literal["none", "bandlimit", "prefilter"]
Axis = Literal["x", "y", "z"]

#: The marble functions, its filters and axes, and the Fig. 5 ramp (the marble's
#: parameter table, mimarble/marble_parameters.py, declares them).
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


@dataclass(frozen=True)
class Light:
    """``light { position <> color <> }``: a point light without distance falloff."""

    position: Vec3
    color: RGB = (1.0, 1.0, 1.0)
    pos: Pos | None = _pos()


@dataclass(frozen=True)
class ColorChannel:
    """``color < r g b >``: a constant colour (the paper's ChannelColor)."""

    rgb: RGB
    pos: Pos | None = _pos()


@dataclass(frozen=True)
class MarbleChannel(marble_parameters.MarbleParameters):
    """``marble { ... }``: the paper's marble (ChannelMarble).

    With ``v = scale * p`` (p in world space) and
    ``F(v) = sum_{i<octaves} N(2^i v) / 2^i`` (``|N|`` when ``turbulence``)::

        abs_sine: t = |sin(pi * (period * v_axis + distortion * F(v)))|
        sine:     t = 0.5 * (sin(period * v_axis + distortion * F(v)) + 1)
        cosine:   t = 0.5 * (cos(v_axis + distortion * F(v)) + 1)   (period unused)

    Its fields are the rows of the marble's parameter table
    (mimarble/marble_parameters.py: names, defaults, ranges), in order, then ``pos``.

    The colour is ``ramp`` at ``t``: K >= 1 colours at keys ``k / (K - 1)``,
    piecewise linear, ``t`` clamped to [0, 1] (one colour: a constant).

    ``filter`` and ``tolerance`` are rendering options for Mitsuba (``bandlimit``
    leaves out octaves finer than the pixel footprint, ``prefilter`` averages the
    colour over the pixel's interval of phase; octaves that the colour error
    ``tolerance`` allows are left out, ``None``: the scene's default,
    mimarble/error_budget.py); the reference tracer always renders the full marble.
    """

    pos: Pos | None = _pos()

    @property
    def axis_index(self) -> int:
        """0, 1 or 2 for ``axis`` x, y or z."""
        return AXES.index(self.axis)


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


@dataclass(frozen=True)
class _Operation:
    """Two or more channels combined componentwise (``keyword`` names it)."""

    operands: tuple
    pos: Pos | None = _pos()
    keyword = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "operands", _check_operands(self.keyword, self.operands))


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
            if not math.isfinite(self.weight):
                raise ValueError(f"mix: weight={self.weight!r} must be finite")
            object.__setattr__(self, "weight", float(self.weight))

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
class Material:
    """``material "name" { ambient {CH} diffuse {CH} specular {CH} shininess N }``.

    Shading (whitted mode), per light l with visibility V and intensity I_l::

        L = ka(p) * A + sum_l V * I_l * (kd(p) * max(0, n.l)
                                         + ks(p) * max(0, n.h) ** shininess)
    """

    name: str
    ambient: Channel | None = None
    diffuse: Channel | None = None
    specular: Channel | None = None
    shininess: float = 32.0
    pos: Pos | None = _pos()

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


@dataclass(frozen=True)
class Scene:
    """A whole scene file.

    ``materials`` maps names to materials in file order; every
    ``Sphere.material`` is a key of it (after :func:`parse`). ``ambient`` is
    the global ambient light A. ``source`` is the file it came from (None for
    text parsed without a file name); it takes no part in equality.
    """

    image: Image = Image()
    camera: Camera = Camera()
    ambient: RGB = (0.0, 0.0, 0.0)
    lights: tuple[Light, ...] = ()
    materials: Mapping[str, Material] = field(default_factory=FrozenMap)
    spheres: tuple[Sphere, ...] = ()
    source: str | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        # Accept lists and dicts from programmatic construction; store immutably.
        if not isinstance(self.materials, FrozenMap):
            object.__setattr__(self, "materials", FrozenMap(self.materials))
        for name in ("lights", "spheres"):
            value = getattr(self, name)
            if not isinstance(value, tuple):
                object.__setattr__(self, name, tuple(value))

    def image_maps(self) -> tuple:
        """Every distinct image map the materials use."""
        found = [c for m in self.materials.values() for ch in m.channels().values()
                 for c in walk(ch) if isinstance(c, ImageChannel)]
        return tuple(dict.fromkeys(found))

    def material_of(self, sphere: Sphere) -> Material:
        """The material a sphere refers to."""
        return self.materials[sphere.material]
