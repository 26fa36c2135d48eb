"""The scene builder's value readers: numbers, integers, vectors, colours, a block's keys,
file names and ``transform`` blocks, each checked by its rule (rules.py) and refused at
its token with the token as written.
"""

from __future__ import annotations

import math
import os

from lark import Token, Tree

from mimarble.parameters import hex_colour
from mimarble.scene import rules, transforms
from .errors import SceneError
from .model import Pos, Source

# Rule names whose keyword differs from the rule name.
_RULE_KEYWORD = {"shape_material": "material", "ambient_light": "ambient", "image_map": "image",
                 "transform_scale": "scale", "texture_definition": "texture",
                 "texture_use": "texture"}


def keyword_of(tree: Tree) -> str:
    return _RULE_KEYWORD.get(tree.data, str(tree.data))


def pos_of(tree: Tree) -> Pos:
    return Pos(tree.meta.line, tree.meta.column)


def span_of(node: Tree | Token) -> tuple[int, int]:
    """Where a tree or a token stands in the parsed text: offsets [start, end)."""
    if isinstance(node, Token):
        return node.start_pos, node.end_pos
    return node.meta.start_pos, node.meta.end_pos


def source_of(st: Tree, f: dict[str, Tree]) -> Source:
    """Where the block ``st`` and the values of its keys ``f`` (its fields) stand: each
    key's value (its one child), or, for a ``ramp``, the whole key and each stop's
    position and colour (model.Source)."""
    values, stops = {}, ()
    for key, tree in f.items():
        if key == "ramp":
            values[key] = span_of(tree)
            stops, before = [], None
            for child in tree.children:
                if isinstance(child, Token) and child.type == "NUMBER":
                    before = span_of(child)
                else:
                    stops.append((before, span_of(child)))
                    before = None
            stops = tuple(stops)
        elif len(tree.children) == 1:
            values[key] = span_of(tree.children[0])
    return Source(span_of(st), values, stops)


def unquoted(tok: Token) -> str:
    """A STRING token's text without its quotes."""
    return str(tok)[1:-1]


def vector_text(v) -> str:
    """A vector as the language writes it: ``< 1 0 -0.5 >``."""
    return "< " + " ".join(repr(x).removesuffix(".0") for x in v) + " >"


class ValueReader:
    """What every part of the builder reads values with; ``text`` and ``filename`` are the
    scene's (set by the builder), for the errors' positions."""

    text: str
    filename: str
    folder: str

    def switch(self, tok: Token, key: str) -> bool:
        """The value of a key of :data:`~mimarble.scene.keywords.SWITCH_KEYS`, ``true`` or
        ``false``, refused at the word."""
        if str(tok) not in ("true", "false"):
            raise self.error(tok, f"{key} is true or false, found "
                                  f"'{rules.shortened(str(tok), 40)}'")
        return str(tok) == "true"

    # -- errors ---------------------------------------------------------------

    def error(self, where, message: str) -> SceneError:
        if isinstance(where, Tree):
            line, col = where.meta.line, where.meta.column
        elif isinstance(where, Token):
            line, col = where.line, where.column
        else:
            line, col = where
        return SceneError.at(self.text, self.filename, line, col, message)

    # -- values ---------------------------------------------------------------
    def refuse(self, tok, problem: str | None) -> None:
        """A rule's problem (rules.py) at ``tok``, with the token as written."""
        if problem:
            raise self.error(tok, f"{problem}, found {rules.shortened(tok)}")

    def number(self, tok: Token) -> float:
        value = float(tok)
        problem = rules.number_problem(value)
        if problem:
            overflow = " (it overflows double precision)" if not math.isfinite(value) else ""
            raise self.error(tok, f"number {rules.shortened(tok)} {problem}{overflow}")
        return value

    def integer(self, tok: Token, what: str, lo: int, hi: int) -> int:
        value = self.number(tok)
        self.refuse(tok, rules.integer_problem(value, what, lo, hi))
        return int(value)

    def vector(self, tree: Tree, what: str) -> tuple[tuple[float, float, float], list[Token]]:
        toks = list(tree.children)
        if len(toks) != 3:
            raise self.error(tree, f"{what} needs 3 numbers, found {len(toks)}")
        return tuple(self.number(t) for t in toks), toks  # type: ignore[return-value]

    def point(self, tree: Tree, what: str) -> tuple[float, float, float]:
        return self.vector(tree, what)[0]

    def point_of(self, f: dict[str, Tree], key: str, default) -> tuple[float, float, float]:
        """The vector of the block's ``key`` (``f``: its fields), or ``default`` without it."""
        return self.point(f[key].children[0], key) if key in f else default

    def color(self, tree: Tree | Token, what: str) -> tuple[float, float, float]:
        """A colour: ``< r g b >`` (linear, each ≥ 0) or a ``#rrggbb`` token (sRGB-encoded,
        decoded as the marble plugin decodes its ramp's: ``hex_colour``; its form was
        checked as the tokens were read)."""
        if isinstance(tree, Token):
            return hex_colour(str(tree))
        value, toks = self.vector(tree, f"{what} (a colour < r g b >)")
        for v, t in zip(value, toks):
            self.refuse(t, rules.colour_problem(v, what))
        return value

    def fields(self, tree: Tree, block: str) -> dict[str, Tree]:
        """The keyword sub-trees of a block, by keyword; duplicates are errors."""
        out: dict[str, Tree] = {}
        for child in tree.children:
            if not isinstance(child, Tree):
                continue
            key = keyword_of(child)
            if key in out:
                first = out[key].meta
                raise self.error(
                    child, f"duplicate '{key}' in {block} (first given at {first.line}:{first.column})"
                )
            out[key] = child
        return out

    def file_name(self, tok: Token, kind: str) -> None:
        """A file's name (``kind``: an image, a mesh) is not empty and holds no NUL
        character (which no system's paths take)."""
        if not unquoted(tok):
            raise self.error(tok, f"{kind} file name must not be empty")
        if "\0" in tok:
            raise self.error(tok, f"{kind} file name must not hold a NUL character")

    def found_file(self, tok: Token, kind: str, sentence) -> tuple[str, str]:
        """(name as written, path) of the file the STRING ``tok`` names (``kind``: an image,
        an environment), found relative to the scene file's folder (``folder``, set by the
        builder) and checked from its header: ``sentence(name, path)`` is the one sentence
        that refuses it, or None; refused at the string."""
        name = unquoted(tok)
        self.file_name(tok, kind)
        path = os.path.normpath(os.path.join(self.folder, name))
        problem = sentence(name, path)
        if problem:
            raise self.error(tok, problem)
        return name, path

    def transform(self, st: Tree) -> tuple:
        """``transform { translate <> rotate <> scale s|<> … }``: its steps in the order
        written, any number of each; a scale factor 0 is refused at its number, a matrix
        the renderer cannot invert at the ``transform`` keyword (transforms.py)."""
        steps = []
        for step in (c for c in st.children if isinstance(c, Tree)):
            kind = keyword_of(step)
            (value,) = step.children
            if isinstance(value, Token):        # scale s: the same factor on each axis
                vector, toks = (self.number(value),) * 3, [value] * 3
            else:
                vector, toks = self.vector(value, f"{kind} (a vector < x y z >)")
            problem = transforms.step_problem(kind, vector)
            if problem:
                zero = next(t for v, t in zip(vector, toks) if v == 0)
                raise self.error(zero, f"{problem}, found {rules.shortened(zero)}")
            steps.append((kind, vector))
        problem = transforms.matrix_problem(transforms.compose(steps))
        if problem:
            raise self.error(st, problem)
        return tuple(steps)
