"""Syntax errors in words: a Lark exception (or undecodable bytes) -> :class:`SceneError`.

Lark says which token it did not expect and which terminals it would have taken. The
user wants a sentence in the language's own terms, at the right place: the unknown word
and the keywords allowed there, the block left open and where it was opened, the value a
key wants. The wording is kept apart from the parser, which only asks for it; no Lark
exception escapes the scene package.
"""

from __future__ import annotations

import re

from lark import Token
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

from mimarble.parameters import BOOLEAN, BY_NAME, CHOICE, RENAMED, hex_colour_problem
from .errors import SceneError
from .keywords import (BARE_CHANNEL_KEYS, BLOCK_KEYS, CHANNEL_BLOCKS, CHANNEL_KEYWORDS,
                       STATEMENTS, SWITCH_KEYS)
from .channels import SPACES
from .rules import shortened

__all__ = ["syntax_error", "decoded", "POVRAY_HINTS", "povray_hint"]

#: How the terminals that are not keywords are named in a message.
_PUNCT = {
    "LBRACE": "'{'",
    "RBRACE": "'}'",
    "LESSTHAN": "'<'",
    "MORETHAN": "'>'",
    "COMMA": "','",
    "NUMBER": "a number",
    "STRING": 'a quoted name ("...")',
    "WORD": "a name",
    "HEX_COLOUR": "a colour '#rrggbb'",
    "$END": "end of file",
}


#: Habits of POV-Ray's scene language, and a line naming this language's way: shown as
#: ``hint: …`` under the error a habit causes (SceneError.hint). A key is what was
#: written where the error is: the token itself (a word, ``#declare``, ``;``), or, tried
#: first, the token in the innermost open block (``sphere <``) or after the keyword before
#: it (``turbulence <number>``: a number after ``turbulence``).
#: docs/coming-from-povray.md says the rest.
POVRAY_HINTS: dict[str, str] = {
    "#declare": "the language has no variables: write each value where it is used; a "
                "material, named once (material \"m\" { … }), serves any number of spheres",
    "#local": "the language has no variables: write each value where it is used",
    "#include": "the language has no #include: a scene is one file (pictures are read by "
                "image { file \"…\" })",
    "#version": "the language has no #version: leave it out",
    ";": "nothing ends with ';' here: leave it out",
    "pigment": "POV-Ray's pigment is a channel of a material here: material \"m\" { diffuse "
               "{ color < 1 0 0 > } }, or marble { … } or image { file \"…\" } in its place",
    "texture": "POV-Ray's texture is a material here, named in the shape: material \"m\" "
               "{ diffuse { … } specular { … } } and sphere { … material \"m\" }; texture "
               "\"NAME\" { … } names a channel",
    "finish": "POV-Ray's finish is the material's components here: material \"m\" { "
              "ambient { … } diffuse { … } specular { color < 0.3 0.3 0.3 > } shininess 32 }",
    "rgb": "write the colour alone: color < 1 0 0 > is linear RGB (POV-Ray's rgb), "
           "color #ff0000 sRGB",
    "srgb": "POV-Ray's srgb is #rrggbb here (sRGB-encoded, e.g. color #ff8000); < r g b > is "
            "linear",
    "light_source": "POV-Ray's light_source is light { position < x y z > color < r g b > } "
                    "here (z negated: docs/coming-from-povray.md)",
    "light <": "a light's position is named: light { position < 10 10 10 > color < 1 1 1 > }",
    "area_light": "an area light is an area { … } block in a light: see light { … } in "
                  "docs/scene-language.md",
    "location": "POV-Ray's camera location is eye < x y z > here, with z negated (POV-Ray is "
                "left-handed; copied as it is, the image comes out mirrored left to right)",
    "look_at": "write lookat < x y z >, one word",
    "angle": "POV-Ray's angle is the horizontal field of view; fov is the vertical one: "
             "fov = 2·atan(tan(angle/2)·height/width), 35 for POV-Ray's 46 at 4:3",
    "sky": "POV-Ray's sky is up < x y z > here",
    "sphere <": "a sphere's values are named: sphere { center < 0 0 0 > radius 2 material \"m\" }",
    "ramp ,": "ramp colours are separated by spaces, not commas: ramp { < 1 0 0 > < 0 0 1 > } "
              "(commas may separate a vector's numbers only)",
    "color_map": "POV-Ray's color_map is the marble's ramp here: marble { ramp { < 1 1 1 > "
                 "< 0.2 0.2 0.3 > } }",
    "turbulence <number>": "turbulence is a switch here (true: Perlin's |N| noise); the amount "
                           "POV-Ray's turbulence sets is distortion: marble { distortion 0.8 }",
    "omega": "POV-Ray's omega (each octave's amplitude factor) is gain here: marble { gain 0.5 }",
    "lambda": "POV-Ray's lambda (each octave's frequency factor) is lacunarity here: "
              "marble { lacunarity 2 }",
    "marble translate": "a marble's pattern moves inside transform: marble { transform { "
                        "translate < 1 0 0 > rotate < 0 0 30 > scale 2 } }",
    "marble rotate": "a marble's pattern turns inside transform: marble { transform { "
                     "rotate < 0 0 30 > } }",
    "translate": "a marble's pattern, a box and a mesh move in transform { translate < x y z > }; "
                 "a sphere is placed by its center, a plane by its point",
    "rotate": "a marble's pattern, a box and a mesh turn in transform { rotate < x y z > }; a "
              "plane by its normal",
    "global_settings": "the ambient light is the statement ambient < r g b >; there are no "
                       "other global settings",
    "background": "the background is in the image statement: image { background < r g b > }",
    # textures.inc's marbles: presets of the marble library (mimarble/presets.toml).
    **{name: f"POV-Ray's {name} (textures.inc) is a preset here: marble {{ preset "
             f"\"{name.lower()}\" }} (docs/presets.md)"
       for name in ("White_Marble", "Red_Marble", "Blood_Marble", "Jade")},
}

#: The channels, in the sentences that expect one.
_CHANNELS = ("'color < r g b >', 'marble { ... }', 'image { file \"...\" }', 'add { ... }', "
             "'multiply { ... }', 'mix { ... }' or 'texture \"NAME\"'")

_NUMBER_TEXT = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


def povray_hint(token: str, *, block: str | None = None, after: str | None = None) -> str | None:
    """The hint for ``token`` (as written) in the innermost open ``block`` (its keyword),
    right after the keyword ``after``: :data:`POVRAY_HINTS`' line, or None."""
    shape = "<number>" if _NUMBER_TEXT.fullmatch(token) else token
    keys = ([f"{after} {shape}"] if after else []) + ([f"{block} {shape}"] if block else []) + [shape]
    return next((POVRAY_HINTS[k] for k in keys if k in POVRAY_HINTS), None)


def _hint(e: UnexpectedInput, text: str, keywords: dict[str, str]) -> str | None:
    """The POV-Ray hint for the error ``e`` (None: none applies)."""
    if isinstance(e, UnexpectedCharacters):
        return povray_hint(text[e.pos_in_stream:e.pos_in_stream + 1])
    tok = getattr(e, "token", None)
    if not isinstance(tok, Token) or tok.type == "$END":
        return None
    state = getattr(e, "state", None)
    blocks = _open_blocks(state)
    stack = getattr(state, "value_stack", None) or []
    prev = stack[-1] if stack else None
    after = str(prev) if isinstance(prev, Token) and prev.type in keywords else None
    return povray_hint(str(tok), block=str(blocks[-1][0]) if blocks else None, after=after)


def decoded(data: bytes, filename: str) -> str:
    """``data`` as UTF-8 text, or a SceneError at the first byte that is not UTF-8."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        start = e.start
        line = data.count(b"\n", 0, start) + 1
        line_start = data.rfind(b"\n", 0, start) + 1
        line_end = data.find(b"\n", start)
        if line_end < 0:
            line_end = len(data)
        column = len(data[line_start:start].decode("utf-8", "replace")) + 1
        src = data[line_start:line_end].decode("utf-8", "replace").rstrip("\r")
        if any((ord(ch) < 32 and ch != "\t") or ord(ch) == 127 for ch in src):
            src = None   # control characters: a binary file, whose bytes would garble the terminal
        raise SceneError(
            f"invalid UTF-8 byte 0x{data[start]:02x}: scene files must be UTF-8 text",
            filename=filename,
            line=line,
            column=column,
            source_line=src,
        ) from None


def _describe(tok: Token, keywords: dict[str, str]) -> str:
    """The token as a message names it: ``keyword 'eye'``, ``number 3``, ``'}'``."""
    if tok.type == "$END":
        return "end of file"
    if tok.type == "NUMBER":
        return f"number {shortened(tok)}"
    if tok.type == "STRING":
        return f"string {shortened(tok)}"
    if tok.type == "HEX_COLOUR":
        return f"colour '{shortened(tok)}'"
    if tok.type in keywords:
        return f"keyword '{tok}'"
    return f"'{shortened(tok)}'"


def _expected_list(names, keywords: dict[str, str], block: str | None = None) -> str:
    """The terminals ``names`` in words, keywords first in the language's order — the
    order of ``block``'s keys (a key of BLOCK_KEYS) when given, else the statements' —
    ``'eye', 'lookat', 'up', 'fov' or '}'``."""
    first = (BLOCK_KEYS.get(block, ()),) if block else ()
    order = [k for ks in (first + (STATEMENTS,) + tuple(BLOCK_KEYS.values())) for k in ks]
    words = sorted((keywords[n] for n in names if n in keywords), key=lambda w: (order.index(w) if w in order else 99, w))
    words = list(dict.fromkeys(words))
    rest = [_PUNCT.get(n, n) for n in sorted(names) if n not in keywords]
    items = [f"'{w}'" for w in words] + rest
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " or " + items[-1]


def _open_blocks(state) -> list[tuple[Token, str]]:
    """The unclosed blocks at the error, outermost first: (opener keyword token, display name).

    Read from the LALR value stack: a block already reduced is a Tree; one still
    open leaves its '{' token (and, when the error came right after its '}',
    that token too) on the stack.
    """
    stack = getattr(state, "value_stack", None) or []
    blocks: list[tuple[Token, str]] = []
    for i, item in enumerate(stack):
        if not isinstance(item, Token):
            continue
        if item.type == "RBRACE" and blocks:
            blocks.pop()
        elif item.type == "LBRACE" and i > 0:
            opener = stack[i - 1]
            if isinstance(opener, Token) and opener.type == "STRING" and i > 1:
                # material "m" { or texture "t" {
                blocks.append((stack[i - 2], f"{stack[i - 2]} {shortened(opener)}"))
            elif isinstance(opener, Token):
                blocks.append((opener, f"'{opener}' block"))
    return blocks


def _block_rule(blocks, k: int) -> str:
    """The rule name (a key of BLOCK_KEYS) of the k-th open block: its keyword, but
    ``image`` inside any block is an image map (the image statement is top-level only; a
    subsurface's ``albedo image { … }`` opens one with no channel block around it)."""
    word = str(blocks[k][0])
    if word == "image" and k > 0:
        return "image_map"
    return word


def _unclosed_note(tok: Token, blocks) -> str:
    """When ``tok``, refused in the innermost open block, is a keyword that a block around
    it (or the top level) takes, the likely mistake is that block's missing '}': a
    note naming it and where it opened (else nothing)."""
    word = str(tok)
    outer = [STATEMENTS] + [BLOCK_KEYS.get(_block_rule(blocks, k), ()) for k in range(len(blocks) - 1)]
    if not any(word in keys for keys in outer):
        return ""
    opener, name = blocks[-1]
    the = "the " if name.endswith("block") else ""
    return f" (is the '}}' of {the}{name}, opened at {opener.line}:{opener.column}, missing?)"


#: What a quoted string after a keyword is, by the keyword (tried first: the innermost
#: open block and the keyword); a material's name otherwise (material, and every shape's
#: material key).
_STRING_AFTER = {"texture": 'texture name like "veins"', "file": 'file name like "maps/veins.png"',
                 "mesh file": 'file name like "models/vase.ply"',
                 "environment file": 'file name like "sky.exr"',
                 "preset": 'preset name like "carrara"'}

#: What is said at a bracket that is no part of the language, where a vector goes.
_BRACKETS = {"(": ")", "[": "]"}
#: Keywords followed by a colour, and by a point or direction.
_COLOUR_KEYS = ("color", "background", "ambient")
_VECTOR_KEYS = ("eye", "lookat", "up", "position", "center", "point", "normal", "min", "max")


def _bracket_sentence(text: str, pos: int, ch: str) -> str:
    """The sentence for ``(`` or ``[``: how a colour or a vector is written, chosen by the
    word before it."""
    before = re.search(r"([A-Za-z_]\w*)\s*$", text[max(0, pos - 200):pos])
    word = before.group(1) if before else ""
    colour = "a colour as < r g b > (linear) or #rrggbb (sRGB)"
    vector = "a vector as < x y z >"
    if word in _COLOUR_KEYS:
        how = f"write {colour}, e.g. {word} < 1 0 0 > or {word} #ff0000"
    elif word in _VECTOR_KEYS:
        how = f"write {vector}, e.g. {word} < 0 0 1 >"
    else:
        how = f"write a number bare (2), {vector} and {colour}"
    return f"unexpected '{ch}': {how}; the language has no '{ch} {_BRACKETS[ch]}'"


def _eof_position(text: str) -> tuple[int, int]:
    """Just after the last character that is not white space: where the file ended."""
    end = len(text.rstrip())
    line = text.count("\n", 0, end) + 1
    col = end - (text.rfind("\n", 0, end) + 1) + 1
    return line, col


def _renamed_note(key: str) -> str:
    """What replaced ``key``, when it is a marble key that was renamed (else nothing)."""
    if key not in RENAMED:
        return ""
    new = BY_NAME[RENAMED[key]]
    now = f"{new.name} {key}" if key in new.choices else new.name
    return f" (it is now '{now}'; {new.name} {new.requirement})"


def syntax_error(e: UnexpectedInput, text: str, filename: str,
                 keywords: dict[str, str]) -> SceneError:
    """The SceneError for Lark's ``e`` while parsing ``text``. ``keywords`` maps the
    grammar's keyword terminals to their text (``EYE`` -> ``eye``). A habit of POV-Ray's
    gets its hint (:data:`POVRAY_HINTS`)."""
    error = _syntax_error(e, text, filename, keywords)
    error.hint = _hint(e, text, keywords)
    return error


def _syntax_error(e: UnexpectedInput, text: str, filename: str,
                  keywords: dict[str, str]) -> SceneError:
    def at(line, col, msg):
        return SceneError.at(text, filename, line, col, msg)

    if isinstance(e, UnexpectedCharacters):
        pos = e.pos_in_stream
        rest = text[pos:]
        # Comments are blanked out before lexing (comments.py, which refuses an unclosed
        # '/*'), so a '*/' here closes nothing.
        if rest.startswith("*/"):
            return at(e.line, e.column, "'*/' without a matching '/*'")
        if rest.startswith('"'):
            return at(e.line, e.column, "unterminated string: a name must close with '\"' on the same line")
        if rest[:1] in "+-.0123456789" or (rest[:1].isalnum() and pos > 0 and text[pos - 1].isdigit()):
            # A number glued to what precedes or follows it: 1-2, 1.2.3, 3abc, 1e
            start = pos
            while start > 0 and (text[start - 1].isalnum() or text[start - 1] in "._"):
                start -= 1
            m = re.match(r"[\w.+-]+", text[start:])
            word = m.group(0) if m else rest[:1]
            col = e.column - (pos - start)
            if start > 0 and text[start - 1] == "#":        # #ff0000.5: a colour, glued
                return at(e.line, col - 1, hex_colour_problem("#" + word, linear="< r g b >"))
            return at(
                e.line,
                col,
                f"malformed number '{shortened(word)}': write numbers like 2, -0.5, .5 or 1e-3, "
                "separated by spaces or commas (there is no arithmetic)",
            )
        ch = rest[:1]
        if ch in _BRACKETS:
            return at(e.line, e.column, _bracket_sentence(text, pos, ch))
        shown = repr(ch) if ch.isprintable() else f"U+{ord(ch):04X}"
        return at(e.line, e.column, f"unexpected character {shown}")

    if isinstance(e, UnexpectedEOF):  # not raised by LALR, but be safe
        line, col = _eof_position(text)
        return at(line, col, "unexpected end of file")

    assert isinstance(e, UnexpectedToken)
    tok: Token = e.token
    expected = set(e.expected or ())
    # LALR merges look-ahead sets, so e.expected can list tokens that would fail
    # after a reduction; the interactive parser tries each one and is exact.
    ip = getattr(e, "interactive_parser", None)
    if ip is not None:
        try:
            expected = set(ip.accepts()) or expected
        except Exception:  # pragma: no cover - keep the coarse set
            pass
    state = getattr(e, "state", None)
    blocks = _open_blocks(state)
    stack = getattr(state, "value_stack", None) or []
    prev = stack[-1] if stack else None
    found = _describe(tok, keywords)

    if tok.type == "$END":
        line, col = _eof_position(text)
        if blocks:
            opener, name = blocks[-1]
            return at(line, col, f"missing closing '}}' for {name} opened at {opener.line}:{opener.column}")
        return at(line, col, f"unexpected end of file; expected {_expected_list(expected, keywords)}")

    line, col = tok.line, tok.column

    statement_keys = {n for n in expected if keywords.get(n) in STATEMENTS}
    if tok.type == "RBRACE" and not blocks and expected <= statement_keys | {"$END"}:
        return at(line, col, "unexpected '}': no block is open here")

    keys = {n for n in expected if n in keywords}
    if keys and expected <= keys | {"RBRACE", "$END"}:
        # A keyword is expected: top-level statement or a key inside a block.
        allowed = _expected_list(keys, keywords,
                                 _block_rule(blocks, len(blocks) - 1) if blocks else None)
        if not blocks:
            if tok.type == "WORD":
                return at(line, col, f"unknown statement '{shortened(tok)}'; a statement is one of "
                                     f"{allowed}")
            return at(line, col, f"unexpected {found} at top level; a statement is one of {allowed}")
        opener, name = blocks[-1]
        if isinstance(prev, Token) and prev.type in keywords and str(prev) in BARE_CHANNEL_KEYS:
            # albedo / reflectance / density: one channel, written bare (a component block's braces are
            # the likely habit)
            bare = (f"; a subsurface's {prev} takes its channel without braces: {prev} "
                    f"color < 1 1 1 >") if tok.type == "LBRACE" else ""
            return at(line, col, f"expected a channel after '{prev}' ({_CHANNELS}), found "
                                 f"{found}{bare}")
        if opener in CHANNEL_BLOCKS:
            what = f"a channel: {_CHANNELS}"
            if opener == "mix":
                what += ", or 'weight W' last"
            if tok.type == "RBRACE":
                return at(line, col, f"empty {name}: expected {what}")
            if str(tok) == "weight":
                return at(line, col, "'weight' belongs in a mix block: mix { A B weight W }")
            if tok.type == "WORD":
                return at(line, col, f"unknown channel '{shortened(tok)}' in {name}; expected {what}")
            return at(line, col, f"unexpected {found} in {name}; expected "
                                 f"{what}{_unclosed_note(tok, blocks)}")
        if tok.type == "WORD":
            return at(line, col, f"unknown keyword '{shortened(tok)}' in {name}{_renamed_note(str(tok))}; "
                                 f"allowed: {allowed}")
        if tok.type in keywords:
            one = (" (albedo, reflectance and density take exactly one channel each)"
                   if opener == "subsurface" and str(tok) in CHANNEL_KEYWORDS else "")
            return at(line, col, f"keyword '{tok}' is not allowed in {name}; allowed: "
                                 f"{allowed}{one}{_unclosed_note(tok, blocks)}")
        return at(line, col, f"unexpected {found} in {name}; expected a keyword ({allowed}) or '}}'")

    if expected == {"RBRACE"} and blocks:
        opener, name = blocks[-1]
        msg = f"expected '}}' to close {name} opened at {opener.line}:{opener.column}, found {found}"
        # A second channel (else a keyword that a block around takes: a '}' missing).
        second = str(tok) in CHANNEL_KEYWORDS or not _unclosed_note(tok, blocks)
        if opener in ("ambient", "diffuse", "specular") and second:
            msg += " (a component takes exactly one channel)"
        elif opener == "texture" and second:
            msg += " (a texture holds exactly one channel)"
        return at(line, col, msg)

    after = f" after '{prev}'" if isinstance(prev, Token) and prev.type in keywords else ""
    if expected == {"NUMBER"}:
        return at(line, col, f"expected a number{after}, found {found}")
    if {"NUMBER", "MORETHAN"} <= expected:
        return at(line, col, f"expected a number or '>' in vector, found {found}")
    if expected == {"LESSTHAN"}:
        only = " (#rrggbb writes colours, not points)" if tok.type == "HEX_COLOUR" else ""
        return at(line, col, f"expected a vector '< x y z >'{after}, found {found}{only}")
    if expected == {"LESSTHAN", "HEX_COLOUR"}:
        return at(line, col, f"expected a colour '< r g b >' or '#rrggbb'{after}, found {found}")
    if expected == {"LESSTHAN", "HEX_COLOUR", "RBRACE"}:
        return at(line, col, f"expected a colour '< r g b >' or '#rrggbb', or '}}', in ramp, "
                             f"found {found}")
    if expected == {"STRING"}:
        keys = [f"{blocks[-1][0]} {prev}"] if after and blocks else []
        keys += [str(prev)] if after else []
        what = next((_STRING_AFTER[k] for k in keys if k in _STRING_AFTER),
                    'material name like "marble"')
        return at(line, col, f"expected a quoted {what}{after}, found {found}")
    if expected == {"LBRACE"}:
        return at(line, col, f"expected '{{'{after}, found {found}")
    if expected == {"WORD"}:
        parameter = BY_NAME.get(str(prev)) if after else None
        if parameter is not None and parameter.kind in (CHOICE, BOOLEAN):
            # The same sentence as for a wrong word (the builder's), at the token.
            return at(line, col, f"{parameter.name} {parameter.requirement}, found {found}")
        if after and str(prev) == "space":                  # the builder's sentence
            return at(line, col, f"a marble's space is {' or '.join(SPACES)}, found {found}")
        if after and str(prev) in SWITCH_KEYS:              # the builder's sentence
            return at(line, col, f"{prev} is true or false, found {found}")
        return at(line, col, f"expected a name{after}, found {found}")
    return at(line, col, f"unexpected {found}; expected {_expected_list(expected, keywords)}")
