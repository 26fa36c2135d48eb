"""The channels a material component is bound to: a colour, a marble, an image map, and
the expressions that combine them (add, multiply, mix); walks over a channel's parts."""

from __future__ import annotations

import numbers
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from typing import Union

from mimarble import parameters as marble_parameters
from . import rules, transforms
from .nodes import (AXES, RGB, Pos, Source, checked_number, pos_field, shown, source_field,
                    store_checked, checked_vector)


@dataclass(frozen=True)
class ColorChannel:
    """``color < r g b >``: a constant colour (the paper's ChannelColor): three finite
    numbers. The language writes them ≥ 0; built in Python they may be negative (a
    signed term of an ``add``), and both renderers take them so."""

    rgb: RGB
    pos: Pos | None = pos_field()

    def __post_init__(self) -> None:
        store_checked(self, rgb=checked_vector(self.rgb, "color (a colour < r g b >)"))


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

    pos: Pos | None = pos_field()
    source: Source | None = source_field()
    transform: tuple = field(default=(), kw_only=True)
    space: str = field(default="world", kw_only=True)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.space not in SPACES:
            raise ValueError(f"a marble's space is {' or '.join(SPACES)}, found "
                             f"{shown(self.space)}")
        store_checked(self, transform=transform_steps(self.transform, "MarbleChannel"))

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


def transform_steps(steps, owner: str) -> tuple:
    """A transform's steps (a marble's, a box's, a mesh's: ``owner``), checked and stored
    as ``(kind, (x, y, z))`` tuples."""
    if isinstance(steps, (str, bytes)) or not hasattr(steps, "__iter__"):
        raise TypeError(f"{owner}: transform must be a sequence of (step, < x y z >), "
                        f"found {shown(steps)}")
    out = []
    for step in steps:
        try:
            kind, vector = step
        except (TypeError, ValueError):
            raise TypeError(f"{owner}: a transform step is (kind, < x y z >), found "
                            f"{shown(step)}") from None
        if kind not in transforms.STEPS:
            raise ValueError(f"{owner}: a transform step is translate, rotate or scale, "
                             f"found {shown(kind)}")
        if kind == "scale" and isinstance(vector, numbers.Real):
            vector = (vector,) * 3
        vector = checked_vector(vector, f"transform {kind}")
        problem = transforms.step_problem(kind, vector)
        if problem:
            raise ValueError(f"{problem}, found {shown(vector)}")
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
    pos: Pos | None = pos_field()

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
    pos: Pos | None = pos_field()
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
    pos: Pos | None = pos_field()

    def __post_init__(self) -> None:
        _check_operands("mix", (self.a, self.b))
        if isinstance(self.weight, bool) or not isinstance(self.weight, CHANNEL_TYPES + (int, float)):
            raise TypeError(f"mix: weight={self.weight!r} must be a channel or a number")
        if isinstance(self.weight, (int, float)):
            object.__setattr__(self, "weight", checked_number(self.weight, "mix: weight"))
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
    return map_marbles(channel, lambda marble: replace(marble, **changes))


def map_marbles(channel, change):
    """The channel with every marble m inside it replaced by ``change(m)``."""
    if isinstance(channel, MarbleChannel):
        return change(channel)
    if isinstance(channel, Mix):
        weight = channel.weight if isinstance(channel.weight, float) else \
            map_marbles(channel.weight, change)
        return replace(channel, a=map_marbles(channel.a, change),
                       b=map_marbles(channel.b, change), weight=weight)
    if isinstance(channel, EXPRESSIONS):
        return replace(channel, operands=tuple(map_marbles(c, change)
                                               for c in channel.operands))
    return channel
