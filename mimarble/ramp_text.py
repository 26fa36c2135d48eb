"""Colours and ramps written as text: ``#rrggbb`` (sRGB-encoded) and ``"[p] r g b, …"``.

How the ``marble`` plugin's ``ramp`` string (and ``ramp_positions``) and the scene
language's ``#rrggbb`` colours are read, checked and written back: the form of the parameter
table's colour and position values (mimarble/parameters.py, which re-exports every name
here). The standard library only: the command line, the scene package and the plugin all
read it.
"""

from __future__ import annotations

import math
import re

__all__ = ["ParameterError", "MAX_RAMP_COLOURS", "HEX_FORM", "srgb_to_linear",
           "hex_colour_problem", "hex_colour", "parse_ramp", "parse_positioned_ramp",
           "parse_positions", "positions_problem", "ramp_count_problem", "positions_text",
           "ramp_text", "hex_of_linear"]

#: The most colours a ramp may hold.
MAX_RAMP_COLOURS = 256


class ParameterError(ValueError):
    """A value a parameter cannot take. The message names the parameter and says what it
    must be (``scale must be > 0``); the caller says where it came from and what it was.
    The parameter table's error (``mimarble.parameters.ParameterError``), declared here,
    below the table, where its first values are read."""


# ---------------------------------------------------------------------------
# Colours written #rrggbb: sRGB-encoded, decoded to linear (the plugin and the language)

#: How a hexadecimal colour is written, in messages.
HEX_FORM = "#rrggbb (six hexadecimal digits, sRGB-encoded, e.g. #ff8000)"
_HEX = re.compile(r"#[0-9A-Fa-f]{6}")


def srgb_to_linear(code: float) -> float:
    """The exact sRGB decoding curve of IEC 61966-2-1 on an encoded value in [0, 1]:
    c/12.92 up to 0.04045, else ((c + 0.055)/1.055)^2.4 (Mitsuba's ``bitmap`` decodes
    8-bit sRGB textures with the same curve; so does the reference tracer's image map)."""
    return code / 12.92 if code <= 0.04045 else ((code + 0.055) / 1.055) ** 2.4


def hex_colour_problem(text: str, linear: str = "'r g b'") -> str | None:
    """What is wrong with ``text`` as a colour ``#rrggbb``, in a sentence, or None.
    ``linear``: how the linear alternative is written where it was read (the scene
    language: ``< r g b >``)."""
    if _HEX.fullmatch(text):
        return None
    if text == "#":
        return f"'#' is not a colour: write {HEX_FORM} or {linear} (linear)"
    shown = text if len(text) <= 20 else text[:17] + "..."
    return f"colour '{shown}' is not {HEX_FORM}; or write {linear} (linear)"


def hex_colour(text: str) -> tuple[float, float, float]:
    """The linear RGB of ``#rrggbb``: each byte b decoded as sRGB, ``srgb_to_linear(b/255)``
    (``#808080`` -> 0.21586, ``#ffffff`` -> 1 exactly); ParameterError if it is not
    written so. Mitsuba 3.9 itself accepts no ``#rrggbb`` (its ``rgb`` values are linear
    numbers: ``could not parse RGB value "#808080"``); sRGB is what every web and paint
    program means by it, and what Mitsuba 0.6's ``<srgb value="#rrggbb"/>`` meant."""
    problem = hex_colour_problem(text)
    if problem:
        raise ParameterError(problem)
    return tuple(srgb_to_linear(int(text[i:i + 2], 16) / 255.0) for i in (1, 3, 5))


def hex_of_linear(rgb) -> str:
    """``#rrggbb`` of a linear RGB colour: each component clamped to [0, 1], encoded with
    the exact sRGB curve (the inverse of :func:`srgb_to_linear`) and rounded to the
    nearest byte — what a colour picker shows for it. :func:`hex_colour` of the result
    is within half a code value of the colour (exactly it for colours read from hex)."""
    def code(c: float) -> int:
        c = min(max(float(c), 0.0), 1.0)
        encoded = 12.92 * c if c <= 0.0031308 else 1.055 * c ** (1.0 / 2.4) - 0.055
        return int(round(encoded * 255.0))
    return "#" + "".join(f"{code(c):02x}" for c in rgb)


# ---------------------------------------------------------------------------
# Ramps as text and as Mitsuba properties

def parse_ramp(value, name: str = "ramp") -> tuple[tuple[float, float, float], ...]:
    """Colours from ``"r g b, r g b, …"`` (linear) and ``#rrggbb`` items (sRGB-encoded:
    :func:`hex_colour`), one RGB triple or a sequence of triples; ParameterError unless
    each is three finite numbers. A string whose items carry positions is refused here:
    :func:`parse_positioned_ramp` reads it whole."""
    colours, positions = parse_positioned_ramp(value, name)
    if positions is not None:
        raise ParameterError(f"{name} carries positions here, where only colours are "
                             f"read; give them as ramp_positions")
    return colours


def parse_positioned_ramp(value, name: str = "ramp"):
    """(colours, positions or None) from a ramp as :func:`parse_ramp` takes it, whose
    string items may each start with a position: ``"0 1 1 1, 0.5 #808080, 1 0 0 0"``
    (every item or none). The positions are as written, checked by
    :func:`positions_problem` where they are read."""
    if isinstance(value, str):
        items = [_item_text(item.strip(), value, name) for item in value.split(",")]
        placed = [position is not None for position, _ in items]
        if any(placed) and not all(placed):
            k = placed.index(not placed[0])
            raise ParameterError(f"{name}: give every colour a position or none; colour "
                                 f"{k + 1} ({value.split(',')[k].strip()!r}) "
                                 f"{'has one' if placed[k] else 'has none'}, colour 1 "
                                 f"{'has one' if placed[0] else 'has none'}")
        colours = _checked_colours([c for _, c in items], name)
        return colours, (tuple(p for p, _ in items) if all(placed) else None)
    return _checked_colours(_colour_values(value, name), name), None


def _colour_values(value, name: str) -> list:
    if _is_colour(value):               # <rgb name="ramp" …/>: one colour, a constant
        colours = [tuple(float(value[i]) for i in range(3))]
    else:
        try:
            colours = [tuple(float(x) for x in c) for c in value]
        except (TypeError, ValueError):
            raise ParameterError(f"{name} is not a list of colours") from None
        if any(len(c) != 3 for c in colours):
            raise ParameterError(f"{name} has a colour without 3 components")
    return colours


def _checked_colours(colours, name: str) -> tuple[tuple[float, float, float], ...]:
    if not colours:
        raise ParameterError(f"{name} is empty; give at least one colour")
    if not all(math.isfinite(x) for c in colours for x in c):
        raise ParameterError(f"{name} has a non-finite component")
    return tuple(colours)


def _item_text(item: str, whole: str, name: str):
    """(position or None, colour) of one item of a ramp string: ``[p] r g b`` or
    ``[p] #rrggbb``."""
    words = item.split()
    position = None
    if len(words) in (2, 4) and (len(words) == 4 or words[1].startswith("#")):
        try:
            position = float(words[0])
        except ValueError:
            position = None
        if position is not None:
            item = " ".join(words[1:])
    if item.startswith("#"):
        problem = hex_colour_problem(item)
        if problem:
            raise ParameterError(f"{name} colour in {whole!r}: {problem}")
        return position, hex_colour(item)
    try:
        numbers = tuple(float(x) for x in item.split())
    except ValueError:
        numbers = ()
    if len(numbers) != 3:
        raise ParameterError(f"{name} colour {item!r} in {whole!r} is not three numbers "
                             f"'r g b' nor {HEX_FORM}, each maybe after its position "
                             f"('p r g b'; colours are separated by commas)")
    return position, numbers


def parse_positions(value, name: str = "ramp_positions"):
    """Positions from ``"p, p, …"`` (commas or spaces) or a sequence of numbers; None
    (or an empty string): none, the colours evenly spaced. Not yet checked
    (:func:`positions_problem`)."""
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    if isinstance(value, str):
        words = [w for w in re.split(r"[,\s]+", value.strip()) if w]
        try:
            return tuple(float(w) for w in words)
        except ValueError:
            raise ParameterError(f"{name} {value!r} is not numbers 'p, p, …'") from None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return (float(value),)
    try:
        return tuple(float(x) for x in value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} is not a list of numbers") from None


def positions_problem(positions, name: str = "ramp_positions"):
    """(index, sentence) of the first position that breaks the rule (finite, in [0, 1],
    no smaller than the one before), or None. The index is that of the position at fault
    (the scene language points at its token)."""
    if not positions:
        return 0, f"{name} is empty; give one position for each colour"
    if len(positions) > MAX_RAMP_COLOURS:
        return MAX_RAMP_COLOURS, f"{name} has {len(positions)} positions; a ramp holds " \
                                 f"1..{MAX_RAMP_COLOURS} colours"
    for k, position in enumerate(positions):
        if not math.isfinite(position) or not 0.0 <= position <= 1.0:
            return k, f"ramp position {position!r} (colour {k + 1}) must be in [0, 1]"
        if k and position < positions[k - 1]:
            return k, (f"ramp position {position!r} (colour {k + 1}) is below the one "
                       f"before it, {positions[k - 1]!r}: positions must not decrease")
    return None


def ramp_count_problem(colours, positions) -> str | None:
    """Positions, when given, must be one for each colour."""
    if positions is not None and len(positions) != len(colours):
        return (f"ramp_positions has {len(positions)} positions for {len(colours)} "
                f"colours; give one for each colour")
    return None


def positions_text(positions) -> str:
    """``"p, p, …"``, every float as Python writes it (exact)."""
    return ", ".join(repr(float(x)) for x in positions)


def _is_colour(value) -> bool:
    """An RGB triple of numbers (a Mitsuba colour property), not a list of colours."""
    try:
        return len(value) == 3 and all(isinstance(float(value[i]), float) for i in range(3)) \
            and not isinstance(value[0], (tuple, list))
    except (TypeError, ValueError, IndexError):
        return False


def ramp_text(colours) -> str:
    """``"r g b, r g b, …"``, every float as Python writes it (exact)."""
    return ", ".join(" ".join(repr(float(x)) for x in c) for c in colours)
