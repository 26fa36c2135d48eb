"""A key's value as a user writes it (``mimarble sweep --set KEY=VALUE``, a page's control,
Python), read into what the scene model holds, and written back as the scene language
writes it (for saving a file: rewrite.py).

The value syntax (docs/scene-language.md, "Key paths"):

=====================  ==============================================  ==================
kind                   text                                            Python
=====================  ==============================================  ==================
number, integer        ``1.5``, ``8``                                  int, float
choice, boolean        ``abs_sine``, ``true``                          str, bool
vector                 ``1 2 3`` or ``< 1 2 3 >``                      three numbers
colour                 ``#rrggbb`` (sRGB-encoded) or ``r g b``         three numbers
ramp stop              a colour, maybe after its position:             a colour, or
                       ``#ffffff``, ``0.5 #ffffff``, ``0.5 1 1 1``     (position, colour)
whole ramp             the ramp string, ``#ffffff, 0.8 0.8 0.8`` or    colours, or
                       ``0 #ffffff, 1 #202020`` (every item or none)   (colours, positions)
=====================  ==============================================  ==================

Numbers are the language's (scene.lark's NUMBER: no ``nan``, ``inf`` or ``1_000``),
finite within float32's range; colours ≥ 0. A marble parameter's value is checked by its
row of the parameter table (mimarble/parameters.py), with the table's sentence.
"""

from __future__ import annotations

import dataclasses
import re

from mimarble.parameters import (BOOLEAN, BY_NAME, CHOICE, COLOURS, INTEGER, NUMBER,
                                 PARAMETERS, Parameter, ParameterError, checked, hex_colour,
                                 hex_colour_problem, parse_positioned_ramp)
from . import rules

#: Kinds of the keys that are no marble parameter's (the table's kinds are the others).
VECTOR, COLOUR = "vector", "colour"
#: The table's rows a whole ramp is checked by.
_RAMP, _POSITIONS = BY_NAME["ramp"], BY_NAME["ramp_positions"]
#: A number as the language writes one (scene.lark's NUMBER, without its look-arounds).
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


class KeyPathError(ValueError):
    """A key path the scene does not have, or a value it cannot take there. The message
    starts with the key path (``camera.fov: fov must be > 0 and < 180, found 200``)."""


@dataclasses.dataclass(frozen=True)
class Value:
    """A key's value read: ``value`` as the scene model holds it, ``text`` as the scene
    language writes it. A ramp stop's ``value`` is (position or None, colour) and its
    ``text`` the colour's, ``position_text`` the position's; a whole ramp's ``value`` is
    (colours, positions or None) and ``stops`` each item's (position text or None,
    colour text)."""

    value: object
    text: str = ""
    position_text: str | None = None
    stops: tuple = ()


def number_text(x) -> str:
    """A number as the language writes it, read back exactly: ``8``, ``1.5``, ``2``,
    ``1e-05`` (Python's shortest repr of the float, ``.0`` left off)."""
    if isinstance(x, int) and not isinstance(x, bool):
        return str(x)
    return repr(float(x)).removesuffix(".0")


def vector_text(v) -> str:
    """``< 1 0 -0.5 >``."""
    return "< " + " ".join(number_text(x) for x in v) + " >"


def _number(path: str, word) -> float:
    """A number given as text (the language's form) or as a Python number, finite within
    float32's range."""
    if isinstance(word, str):
        if not _NUMBER.fullmatch(word.strip()):
            raise KeyPathError(f"{path}: {rules.shortened(repr(word), 40)} is not a number")
        word = float(word)
    if isinstance(word, bool) or not isinstance(word, (int, float)):
        raise KeyPathError(f"{path}: {rules.shortened(repr(word), 40)} is not a number")
    try:
        number = float(word)
    except OverflowError:
        number = float("inf")
    problem = rules.number_problem(number)
    if problem:
        raise KeyPathError(f"{path}: number {rules.shortened(repr(word), 40)} {problem}")
    return number


def read_parameter(path: str, parameter: Parameter, value) -> Value:
    """A number, integer, choice or boolean: checked by ``parameter``, in the table's
    words, when it is a row of the marble's table; a key's own row (key_families.py) only
    reads it (a number, an integer), the scene model checks it by the parser's rule."""
    if parameter not in PARAMETERS:                 # a key's own row: the model checks it
        number = _number(path, value)
        if parameter.kind == INTEGER:
            if not number.is_integer():
                raise KeyPathError(f"{path}: {rules.shortened(repr(value), 40)} is not an "
                                   f"integer")
            return Value(int(number), str(int(number)))
        return Value(number, number_text(number))
    if parameter.kind in (NUMBER, INTEGER) and isinstance(value, str):
        number = _number(path, value)               # the language's form of a number
        value = int(number) if parameter.kind == INTEGER and number.is_integer() else number
    elif parameter.kind in (CHOICE, BOOLEAN) and isinstance(value, str):
        value = value.strip()
    try:
        held = checked(parameter, value, path, text=True)
    except ParameterError as e:
        raise KeyPathError(str(e)) from None
    if isinstance(held, float):                     # and every number's rule: float32's range
        _number(path, held)
    if isinstance(held, bool):
        return Value(held, "true" if held else "false")
    return Value(held, number_text(held) if isinstance(held, (int, float)) else str(held))


def _numbers(path: str, value, what: str) -> tuple:
    """Three numbers: ``"1 2 3"``, ``"< 1, 2, 3 >"`` or a sequence."""
    if isinstance(value, str):
        words = [w for w in re.split(r"[\s,]+", value.strip().removeprefix("<")
                                     .removesuffix(">").strip()) if w]
    elif isinstance(value, (list, tuple)):
        words = list(value)
    else:
        words = None
    if words is None or len(words) != 3:
        raise KeyPathError(f"{path}: {rules.shortened(repr(value), 40)} is not {what}")
    return tuple(_number(path, w) for w in words)


def read_vector(path: str, value) -> Value:
    """A point or a direction: ``x y z``."""
    v = _numbers(path, value, "a vector 'x y z'")
    return Value(v, vector_text(v))


def read_colour(path: str, value) -> Value:
    """A colour: ``#rrggbb`` (sRGB-encoded: the language's ``hex_colour``) or ``r g b``
    (linear), each component ≥ 0."""
    if isinstance(value, str) and value.strip().startswith("#"):
        word = value.strip()
        problem = hex_colour_problem(word)
        if problem:
            raise KeyPathError(f"{path}: {problem}")
        return Value(hex_colour(word), word)
    rgb = _numbers(path, value, "a colour '#rrggbb' or 'r g b'")
    for x in rgb:
        problem = rules.colour_problem(x, "the colour")
        if problem:
            raise KeyPathError(f"{path}: {problem}, found {rules.shortened(repr(value), 40)}")
    return Value(rgb, vector_text(rgb))


def read_stop(path: str, value) -> Value:
    """A ramp stop: a colour, maybe after its position (``0.5 #ffffff``, ``0.5 1 1 1``);
    from Python a colour or (position, colour). Its value: (position or None, colour)."""
    position = None
    if isinstance(value, str):
        words = value.replace(",", " ").split()
        if len(words) == 4 or (len(words) == 2 and words[1].startswith("#")):
            position, value = words[0], " ".join(words[1:])
    elif isinstance(value, (list, tuple)) and len(value) == 2:
        position, value = value
    colour = read_colour(path, value)
    if position is None:
        return Value((None, colour.value), colour.text)
    p = _number(path, position)
    if not 0.0 <= p <= 1.0:
        raise KeyPathError(f"{path}: a ramp position must be in [0, 1], found "
                           f"{rules.shortened(repr(position), 40)}")
    return Value((p, colour.value), colour.text, number_text(p))


def read_ramp(path: str, value) -> Value:
    """A whole ramp: the ramp string (``"#ffffff, 0.5 0.4 0.3"``, maybe each item after its
    position) read by the table's own reader (``parse_positioned_ramp``), or colours, or
    (colours, positions) from Python; every colour ≥ 0, within the table's count."""
    positions = None
    if isinstance(value, str):
        try:
            parse_positioned_ramp(value, path)          # the table's reading and its words
        except ParameterError as e:
            raise KeyPathError(str(e)) from None
        stops = [read_stop(path, item) for item in value.split(",")]
    else:
        if isinstance(value, tuple) and len(value) == 2 and isinstance(value[0], (list, tuple)) \
                and value[0] and isinstance(value[0][0], (list, tuple)) \
                and (value[1] is None or not isinstance(value[1][0], (list, tuple))):
            value, positions = value                    # (colours, positions): Key.value
        if not isinstance(value, (list, tuple)) or not value:
            raise KeyPathError(f"{path}: {rules.shortened(repr(value), 40)} is not a ramp: "
                               f"give colours '#rrggbb, r g b, …'")
        if positions is not None and len(positions) != len(value):
            raise KeyPathError(f"{path}: {len(positions)} positions for {len(value)} colours")
        stops = [read_stop(path, c if positions is None else (positions[k], c))
                 for k, c in enumerate(value)]
    placed = [s.value[0] is not None for s in stops]
    if any(placed) and not all(placed):
        raise KeyPathError(f"{path}: give every colour a position or none")
    colours = tuple(s.value[1] for s in stops)
    positions = tuple(s.value[0] for s in stops) if all(placed) else None
    try:
        checked(_RAMP, colours, path)
        if positions is not None:
            checked(_POSITIONS, positions, path)
    except ParameterError as e:
        raise KeyPathError(str(e)) from None
    return Value((colours, positions), stops=tuple((s.position_text, s.text) for s in stops))


#: The longest value text read: a ramp of the table's most colours, each with its position
#: and three numbers of 17 digits, takes about 20 000 characters; a longer text (a page's
#: message, say) is refused before it is split.
MAX_VALUE_TEXT = 65536


def read(path: str, parameter: Parameter, value, stop: int | None = None) -> Value:
    """``value`` read as ``parameter``'s kind says (a ramp's stop when ``stop`` is given)."""
    if isinstance(value, str) and len(value) > MAX_VALUE_TEXT:
        raise KeyPathError(f"{path}: a value of {len(value)} characters; a value is at most "
                           f"{MAX_VALUE_TEXT}")
    if parameter.kind == COLOURS:
        return read_ramp(path, value) if stop is None else read_stop(path, value)
    if parameter.kind == VECTOR:
        return read_vector(path, value)
    if parameter.kind == COLOUR:
        return read_colour(path, value)
    return read_parameter(path, parameter, value)


def current_text(parameter: Parameter, value, stop: int | None = None) -> str:
    """A value the model holds, in the value syntax (what ``--set`` takes back)."""
    if value is None:
        return "default"
    if parameter.kind == COLOURS:
        if stop is not None:
            position, rgb = value
            return (f"{number_text(position)} " if position is not None else "") + \
                " ".join(number_text(x) for x in rgb)
        colours, positions = value
        return ", ".join((f"{number_text(positions[k])} " if positions else "")
                         + " ".join(number_text(x) for x in rgb)
                         for k, rgb in enumerate(colours))
    if parameter.kind in (VECTOR, COLOUR):
        return " ".join(number_text(x) for x in value)
    if isinstance(value, bool):
        return "true" if value else "false"
    return number_text(value) if isinstance(value, (int, float)) else str(value)
