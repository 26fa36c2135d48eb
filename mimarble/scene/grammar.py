"""The scene language's grammar: the text of ``scene.lark``, the marble block's rules written from the marble's parameter table, the shapes' from their kinds.

The marble's keys and the syntax of their values are facts of the table
(mimarble/parameters.py): one rule a row, its value written as its kind says. So
a new parameter is a new key of the language without an edit here or in ``scene.lark``,
and the grammar cannot disagree with what the builder checks or the plugin reads (the
language adds one rule of its own: every colour it writes, ramps' too, is ≥ 0).
"""

from __future__ import annotations

import re
from pathlib import Path

from mimarble import parameters as marble_parameters
# The rows with a key of their own (ramp_positions is written inside the ramp block).
from mimarble.parameters import KEYWORD_PARAMETERS as PARAMETERS
from .shapes import SHAPE_KINDS

__all__ = ["GRAMMAR_PATH", "VALUE_SYNTAX", "LANGUAGE_MARBLE_KEYS", "marble_rules", "shape_rules",
           "grammar_text"]

#: The hand-written part of the grammar: everything but the marble block's rules.
GRAMMAR_PATH = Path(__file__).with_name("scene.lark")

#: The marble block's keys that are the language's own, not rows of the table: their rules
#: are written in ``scene.lark`` (``transform``: the pattern's translate / rotate / scale,
#: which the plugin takes as its ``to_world``; ``space``: world or object, where the
#: pattern is evaluated; ``preset``: a named marble of mimarble/presets.toml, written first
#: in the block). They come after the table's keys.
LANGUAGE_MARBLE_KEYS: tuple[str, ...] = ("transform", "space", "preset")

#: How a value of each kind of parameter is written. Words are any name here; which
#: names a choice takes is checked after parsing, so that a wrong one gets a message
#: that lists the right ones, at the word.
VALUE_SYNTAX: dict[str, str] = {
    marble_parameters.NUMBER: "NUMBER",
    marble_parameters.INTEGER: "NUMBER",
    marble_parameters.CHOICE: "WORD",
    marble_parameters.BOOLEAN: "WORD",
    # < r g b > or #rrggbb each, each maybe after its position (a number; the parser
    # checks that every colour has one or none does):  ramp { 0 < 1 1 1 > 1 #202020 }
    marble_parameters.COLOURS: '"{" (NUMBER | _colour)* "}"',
}


def marble_rules() -> str:
    """The marble block's rules in Lark's notation: the block, its keys, one rule a key."""
    width = max(len(p.name) for p in PARAMETERS) + 1
    rules = [
        "// The marble block, written from mimarble/parameters.py by",
        "// mimarble/scene/grammar.py (each value's range: after parsing).",
        'marble: "marble" "{" _marble_key* "}"',
        "_marble_key: " + " | ".join([p.name for p in PARAMETERS] + list(LANGUAGE_MARBLE_KEYS)),
    ]
    for p in PARAMETERS:
        rule = f'{p.name + ":":<{width}} "{p.name}" {VALUE_SYNTAX[p.kind]}'
        rules.append(f"{rule:<40}// {p.requirement}")
    return "\n".join(rules) + "\n"


#: How a shape key's value is written, by its syntax (shapes.ShapeKey).
_SHAPE_KEY_SYNTAX = {"vector": "vector", "number": "NUMBER", "boolean": "WORD"}


def shape_rules(text: str) -> str:
    """The shapes' rules (shapes.SHAPE_KINDS): ``_shape``, the statement of each kind,
    each kind's block and its keys (``material`` last), and a rule for each key that
    ``text`` (the hand-written grammar) does not define."""
    rules = ["// The shapes, written from mimarble/scene/shapes.py by",
             "// mimarble/scene/grammar.py (each value's rule: after parsing).",
             "_shape: " + " | ".join(kind.keyword for kind in SHAPE_KINDS)]
    defined = set()
    for kind in SHAPE_KINDS:
        rules.append(f'{kind.keyword}: "{kind.keyword}" "{{" _{kind.keyword}_key* "}}"')
        rules.append(f"_{kind.keyword}_key: "
                     + " | ".join([key.name for key in kind.keys] + ["shape_material"]))
        for key in kind.keys:
            if key.name not in defined and not re.search(rf"^{key.name}\s*:", text, re.M):
                rules.append(f'{key.name}: "{key.name}" {_SHAPE_KEY_SYNTAX[key.syntax]}')
                defined.add(key.name)
    return "\n".join(rules) + "\n"


def grammar_text() -> str:
    """The whole grammar: ``scene.lark`` followed by :func:`marble_rules` and
    :func:`shape_rules`."""
    text = GRAMMAR_PATH.read_text(encoding="utf-8")
    return text + "\n" + marble_rules() + "\n" + shape_rules(text)
