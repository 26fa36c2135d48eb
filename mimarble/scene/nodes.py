"""What every node of the scene model shares: the vector and colour types, source positions,
frozen maps, and the constructors' checks (the parser's rules, rules.py, raised as
ValueError/TypeError without a file position)."""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Literal, NamedTuple

from mimarble import parameters as marble_parameters
from . import rules

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


def pos_field() -> Pos | None:
    """A node's ``pos`` field: None by default, keyword only, no part of equality or repr."""
    return field(default=None, compare=False, repr=False, kw_only=True)  # type: ignore[return-value]


#: A stretch of the parsed text: offsets [start, end) into it (its byte order mark removed).
Span = tuple[int, int]


@dataclass(frozen=True, eq=False)
class Source:
    """Where a block's text stands in the text it was parsed from, for rewriting its values
    in place (mimarble/scene/rewrite.py): offsets into the text as parsed (a leading byte
    order mark removed), which its comments, blanked to spaces of the same length, keep.

    ``block``: the block, its keyword to its closing brace. ``values``: each key written,
    the span of its value's text (a number, a word, ``< x y z >``, ``#rrggbb``; ``ramp``:
    the whole ``ramp { … }``). ``stops``: a ramp's stops, (the span of its position or
    None, the span of its colour) each. Like ``pos``, no part of a node's equality, hash
    or repr; a node edited in Python keeps the source of the node it was made from."""

    block: Span
    values: Mapping[str, Span]
    stops: tuple = ()


def source_field() -> Source | None:
    """A node's ``source`` field (:class:`Source`): as :func:`pos_field`."""
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

def shown(value) -> str:
    """``repr(value)`` as a message shows it, shortened by the parser's rule."""
    return rules.shortened(repr(value))


def refuse(problem: str | None, value) -> None:
    """A rule's problem as the parser words it, with the value found."""
    if problem:
        raise ValueError(f"{problem}, found {shown(value)}")


def checked_number(value, what: str) -> float:
    """A real number (not a bool), finite and within float32's range, as a float."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{what} must be a number, found {shown(value)}")
    try:
        number = float(value)
    except OverflowError:
        number = math.copysign(math.inf, value)
    problem = rules.number_problem(number)
    if problem:
        raise ValueError(f"{what}: number {shown(value)} {problem}")
    return number


def checked_integer(value, what: str, lo: int, hi: int) -> int:
    """An integral number in lo..hi, as an int."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{what} must be an integer, found {shown(value)}")
    if not isinstance(value, numbers.Integral) and not math.isfinite(value):
        raise ValueError(f"{what} must be an integer, found {shown(value)}")
    refuse(rules.integer_problem(value, what, lo, hi), value)
    return int(value)


def checked_vector(value, what: str) -> tuple[float, float, float]:
    """Three numbers, as a tuple of floats."""
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{what} must be 3 numbers, found {shown(value)}")
    try:
        items = tuple(value)
    except TypeError:
        raise TypeError(f"{what} must be 3 numbers, found {shown(value)}") from None
    if len(items) != 3:
        raise ValueError(f"{what} needs 3 numbers, found {len(items)}")
    return tuple(checked_number(x, what) for x in items)  # type: ignore[return-value]


def checked_colour(value, what: str) -> tuple[float, float, float]:
    """A colour: three numbers, each ≥ 0."""
    given = tuple(value) if not isinstance(value, (str, bytes)) and hasattr(value, "__iter__") \
        else value
    rgb = checked_vector(given, f"{what} (a colour < r g b >)")
    for component, written in zip(rgb, given):
        refuse(rules.colour_problem(component, what), written)
    return rgb


def store_checked(node, **values) -> None:
    """Set the checked (normalised) values on a frozen node."""
    for name, value in values.items():
        object.__setattr__(node, name, value)


def checked_instances(values, kind, what: str) -> tuple:
    """``values`` as a tuple, each an instance of ``kind``."""
    values = tuple(values)
    for value in values:
        if not isinstance(value, kind):
            raise TypeError(f"{what} must hold {kind.__name__} objects, found {shown(value)}")
    return values
