"""The scene grammar's Lark parser: its tables (cached between processes), and the text fed
to it token by token into a tree, the counted statements and nesting refused on the way.

The *basic* lexer rather than the contextual one: the contextual lexer only tries the
terminals the parser accepts in the current state, so in a ``camera`` block the unknown
word ``eyes`` would lex as the keyword ``eye`` followed by ``s``. With the basic lexer
every keyword is a reserved word, and an unknown word is reported as such, at its first
character.

The tokens are fed to Lark one by one (its interactive parser), so that the statements
past a limit (lights, shapes, textures: limits.py) are refused at the first one too many,
before the rest of the file is parsed. Lark's exceptions become :class:`SceneError` with a
human message (syntax_errors.py); no Lark exception escapes.
"""

from __future__ import annotations

import functools
import re

from lark import Lark, Tree
from lark.exceptions import UnexpectedInput

from mimarble.parameters import hex_colour_problem
from mimarble.scene import rules
from .comments import blanked
from .errors import SceneError
from .grammar import grammar_text
from .keywords import CHANNEL_KEYWORDS
from .limits import MAX_SCENE_BYTES
from .shapes import SHAPE_KINDS, count_problem
from .syntax_errors import povray_hint, syntax_error

__all__ = ["scene_tree", "oversized"]

#: How the language writes a linear colour, in the sentences about ``#rrggbb``.
_LINEAR_COLOUR = "< r g b >"

#: The statements whose count is limited (shapes.count_problem), counted as the tokens
#: are fed. ``texture`` is counted where it starts a statement (a definition, outside every
#: block), not where it names a channel.
_COUNTED = ("light", *(kind.keyword for kind in SHAPE_KINDS), "texture")


def _parser_cache_file(grammar: str) -> str | bool:
    """Where Lark keeps the built parser between processes, or False for no cache.

    Building the LALR tables takes several times the rest of a scene error's answer
    (docs/benchmarks.md, "Figures moved out of the code"); Lark's cache keeps them as a
    pickle checked against the grammar's hash. The file lives in the user's own cache folder
    (:func:`mimarble.runtime.files.cache_folder`), not in a shared temporary folder where
    another user could plant one.
    """
    import hashlib
    import lark

    from mimarble.runtime.files import cache_folder
    root = cache_folder()
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    digest = hashlib.sha256(grammar.encode("utf-8")).hexdigest()[:16]
    return str(root / f"scene-parser-{digest}-lark{lark.__version__}.pickle")


@functools.lru_cache(maxsize=None)
def _lark() -> Lark:
    grammar = grammar_text()
    return Lark(
        grammar,
        parser="lalr",
        lexer="basic",
        propagate_positions=True,
        maybe_placeholders=False,
        cache=_parser_cache_file(grammar),
    )


@functools.lru_cache(maxsize=None)
def _keyword_terminals() -> dict[str, str]:
    """Terminal name -> keyword text, for the reserved words of the grammar."""
    return {
        t.name: t.pattern.value
        for t in _lark().terminals
        if t.pattern.type == "str" and t.pattern.value.isidentifier()
    }


@functools.lru_cache(maxsize=None)
def _watched_terminals() -> tuple[dict[str, str], frozenset, frozenset]:
    """The terminals :func:`scene_tree` watches: the statements whose count is limited
    (terminal -> its keyword, :data:`_COUNTED`), the expressions' keywords (``add``,
    ``multiply``, ``mix``) and every channel's (``texture`` among them)."""
    words = _keyword_terminals()
    counted = {name: word for name, word in words.items() if word in _COUNTED}
    expressions = frozenset(name for name, word in words.items()
                            if word in ("add", "multiply", "mix"))
    channels = frozenset(name for name, word in words.items() if word in CHANNEL_KEYWORDS)
    return counted, expressions, channels


def scene_tree(text: str, filename: str) -> Tree:
    """Lark's tree of ``text`` (its comments blanked out: comments.py; the messages quote
    the text as written), fed token by token, refusing at its keyword, before the
    rest is parsed, a statement past its count limit (a counted keyword outside every
    block: ``texture`` there defines one, inside a block it names a channel), a channel
    nested past the depth limit (its depth: the expression blocks open around it, plus
    one; the builder checks the same on its way down, and a named texture's own depth
    where it is used), and a colour ``#…`` that is not ``#rrggbb``. Lark's errors
    become SceneErrors."""
    counted, expressions, channels = _watched_terminals()
    counts = dict.fromkeys(counted.values(), 0)
    braces: list[bool] = []          # each open '{': whether an expression opened it
    open_expressions = 0
    parser = _lark().parse_interactive(blanked(text, filename))
    last = previous = None
    try:
        for last in parser.iter_parse():
            kind = last.type
            problem = None
            if kind in counted and not braces:
                counts[counted[kind]] += 1
                problem = count_problem(counted[kind], counts[counted[kind]])
            elif kind in channels and open_expressions:
                problem = rules.depth_problem(open_expressions + 1)
            elif kind == "LBRACE":
                braces.append(previous is not None and previous.type in expressions)
                open_expressions += braces[-1]
            elif kind == "RBRACE" and braces:
                open_expressions -= braces.pop()
            elif kind == "HEX_COLOUR":
                problem = hex_colour_problem(last, linear=_LINEAR_COLOUR)
                if problem and not re.match(r"#[0-9A-Fa-f]", last):     # '# note', '#include'
                    problem += "; comments are // … or /* … */"
            if problem:
                hint = povray_hint(str(last)) if kind == "HEX_COLOUR" else None   # #declare
                raise SceneError.at(text, filename, last.line, last.column, problem, hint)
            previous = last
        return parser.feed_eof(last)
    except UnexpectedInput as e:
        if getattr(e, "interactive_parser", None) is None:
            e.interactive_parser = parser       # as Lark's own parse() leaves it
        error = syntax_error(e, text, filename, _keyword_terminals())
    # Raised outside the handler, so Lark's exception (whose parser state holds modules)
    # is not its __context__: a process that imported dask.distributed pickles an
    # exception with its context (tblib's reducers), and this one must pickle.
    raise error


def oversized(text) -> bool:
    """More than the scene limit's bytes (text: as UTF-8)."""
    if len(text) > MAX_SCENE_BYTES:
        return True
    if isinstance(text, str) and len(text) * 4 > MAX_SCENE_BYTES:
        return len(text.encode("utf-8", "surrogatepass")) > MAX_SCENE_BYTES
    return False
