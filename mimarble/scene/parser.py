"""Scene text -> :class:`~mimarble.scene.model.Scene`, with positioned errors.

Two stages:

1. Lark parses the text with ``scene.lark`` (LALR(1), basic lexer, positions
   propagated). Lark's exceptions are translated here into :class:`SceneError`
   with a human message; no Lark exception escapes.

   The *basic* lexer rather than the contextual one: the contextual lexer only
   tries the terminals the parser accepts in the current state, so in a
   ``camera`` block the unknown word ``eyes`` would lex as the keyword ``eye``
   followed by ``s``. With the basic lexer every keyword is a reserved word, and
   an unknown word is reported as such, at its first character.

2. :class:`_Builder` walks the tree into the frozen model, checking what the
   grammar does not: duplicates, arity, ranges, names, references.
"""

from __future__ import annotations

import functools
import math
import os
import re
from pathlib import Path

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

from .errors import SceneError
from .model import (
    AXES,
    Add,
    ImageChannel,
    Mix,
    Multiply,
    MARBLE_FILTERS,
    MARBLE_FUNCTIONS,
    Camera,
    ColorChannel,
    FrozenMap,
    Image,
    Light,
    MarbleChannel,
    Material,
    Pos,
    Scene,
    Sphere,
)

__all__ = ["parse", "load", "BLOCK_KEYS", "STATEMENTS", "LIMITS"]

GRAMMAR_PATH = Path(__file__).with_name("scene.lark")

#: Top-level statements, in documentation order.
STATEMENTS = ("image", "camera", "ambient", "light", "material", "sphere")

#: The keywords that start a channel.
CHANNEL_KEYWORDS = ("color", "marble", "image", "add", "multiply", "mix")
#: The blocks whose contents are channels.
_CHANNEL_BLOCKS = ("ambient", "diffuse", "specular", "add", "multiply", "mix")

#: The keywords allowed in each kind of block (keyed by the block's rule name: an image
#: map is ``image_map``, written ``image { file "…" }`` like the image statement).
BLOCK_KEYS: dict[str, tuple[str, ...]] = {
    "image": ("width", "height", "samples", "background"),
    "camera": ("eye", "lookat", "up", "fov"),
    "light": ("position", "color"),
    "material": ("ambient", "diffuse", "specular", "shininess"),
    "ambient": CHANNEL_KEYWORDS,
    "diffuse": CHANNEL_KEYWORDS,
    "specular": CHANNEL_KEYWORDS,
    "add": CHANNEL_KEYWORDS,
    "multiply": CHANNEL_KEYWORDS,
    "mix": CHANNEL_KEYWORDS + ("weight",),
    "image_map": ("file",),
    "marble": ("scale", "period", "distortion", "octaves", "function", "axis", "turbulence",
               "filter", "tolerance", "ramp"),
    "sphere": ("center", "radius", "material"),
}

#: Keys that were renamed, and what to write now (said in the error).
_RENAMED_KEYS = {"bandlimit": " (it is now 'filter bandlimit'; also 'filter prefilter')"}

#: Limits checked after parsing (documented in docs/scene-language.md).
LIMITS = {
    "image_size": (1, 16384),  # width and height, pixels
    "max_image_samples": 1 << 28,  # width * height * samples
    "octaves": (0, 64),
    "ramp_colours": (1, 256),
    "max_abs_number": 3.4028234663852886e38,  # float32 max: the Mitsuba path is single precision
}

_FLT_MAX = LIMITS["max_abs_number"]

# Rule names whose keyword differs from the rule name.
_RULE_KEYWORD = {"sphere_material": "material", "ambient_light": "ambient", "image_map": "image"}

_PUNCT = {
    "LBRACE": "'{'",
    "RBRACE": "'}'",
    "LESSTHAN": "'<'",
    "MORETHAN": "'>'",
    "COMMA": "','",
    "NUMBER": "a number",
    "STRING": 'a quoted name ("...")',
    "WORD": "a name",
    "$END": "end of file",
}


def _parser_cache_file(grammar: str) -> str | bool:
    """Where Lark keeps the built parser between processes, or False for no cache.

    Building the LALR tables takes ~0.15 s, three times the rest of a scene
    error's answer; Lark's cache keeps them as a pickle checked against the
    grammar's hash. The file lives in the user's own cache folder
    (``$XDG_CACHE_HOME/mimarble``, default ``~/.cache/mimarble``), not in a shared
    temporary folder where another user could plant one.
    """
    import hashlib
    import lark
    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "mimarble"
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    digest = hashlib.sha256(grammar.encode("utf-8")).hexdigest()[:16]
    return str(root / f"scene-parser-{digest}-lark{lark.__version__}.pickle")


@functools.lru_cache(maxsize=None)
def _lark() -> Lark:
    grammar = GRAMMAR_PATH.read_text(encoding="utf-8")
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


# --------------------------------------------------------------------------
#  Image files (standard library only: the scene package imports no imaging library)
# --------------------------------------------------------------------------

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def image_file_problem(path: str) -> str | None:
    """Why ``path`` cannot be an image map (None: it can): it must exist, be readable,
    and be an 8-bit PNG or a JPEG (read from its header; decoding comes later)."""
    try:
        with open(path, "rb") as f:
            head = f.read(33)
    except FileNotFoundError:
        return f"no such file (looked for {path})"
    except IsADirectoryError:
        return f"it is a directory ({path})"
    except PermissionError:
        return f"permission denied ({path})"
    except OSError as e:
        return f"cannot read it: {e.strerror or e} ({path})"
    if head.startswith(_PNG_SIGNATURE):
        if len(head) < 33 or head[12:16] != b"IHDR":
            return "a truncated PNG (no IHDR header)"
        width, height = int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
        depth = head[24]
        if width == 0 or height == 0:
            return f"an empty PNG ({width}x{height})"
        if depth != 8:
            return f"a {depth}-bit PNG; image maps are 8-bit PNG or JPEG"
        return None
    if head.startswith(b"\xff\xd8\xff"):
        return None
    return "not a PNG or JPEG file; image maps are 8-bit PNG or JPEG"


# --------------------------------------------------------------------------
#  Public entry points
# --------------------------------------------------------------------------


def load(path: str | os.PathLike) -> Scene:
    """Read and parse a scene file. Every failure is a :class:`SceneError`."""
    filename = os.fspath(path)
    if isinstance(filename, bytes):
        filename = os.fsdecode(filename)
    try:
        with open(path, "rb") as f:
            data = f.read()
    except FileNotFoundError:
        raise SceneError(f"cannot read scene file: no such file (looked for "
                         f"{os.path.abspath(filename)})", filename=filename) from None
    except IsADirectoryError:
        raise SceneError("cannot read scene file: it is a directory", filename=filename) from None
    except PermissionError:
        raise SceneError("cannot read scene file: permission denied", filename=filename) from None
    except OSError as e:
        raise SceneError(f"cannot read scene file: {e.strerror or e}", filename=filename) from None
    return parse(data, filename=filename, source=filename)


def parse(text: str | bytes, filename: str = "<string>", *, source: str | None = None) -> Scene:
    """Parse scene text. ``filename`` is used in messages only.

    ``Scene.source`` is ``source`` if given, else ``filename`` unless that is
    the default ``"<string>"``.
    """
    if isinstance(text, (bytes, bytearray)):
        text = _decode(bytes(text), filename)
    if text.startswith("\ufeff"):  # a UTF-8 byte order mark is not part of the scene
        text = text[1:]
    if source is None and filename != "<string>":
        source = filename
    try:
        tree = _lark().parse(text)
    except UnexpectedInput as e:
        raise _syntax_error(e, text, filename) from None
    return _Builder(text, filename, source).scene(tree, source)


def _decode(data: bytes, filename: str) -> str:
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


# --------------------------------------------------------------------------
#  Syntax errors: Lark exception -> SceneError with a human message
# --------------------------------------------------------------------------


def _describe(tok: Token) -> str:
    if tok.type == "$END":
        return "end of file"
    if tok.type == "NUMBER":
        return f"number {tok}"
    if tok.type == "STRING":
        return f"string {tok}"
    if tok.type in _keyword_terminals():
        return f"keyword '{tok}'"
    return f"'{tok}'"


def _expected_list(names) -> str:
    kw = _keyword_terminals()
    order = [k for ks in ((STATEMENTS,) + tuple(BLOCK_KEYS.values())) for k in ks]
    words = sorted((kw[n] for n in names if n in kw), key=lambda w: (order.index(w) if w in order else 99, w))
    words = list(dict.fromkeys(words))
    rest = [_PUNCT.get(n, n) for n in sorted(names) if n not in kw]
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
                blocks.append((stack[i - 2], f"material {opener}"))
            elif isinstance(opener, Token):
                blocks.append((opener, f"'{opener}' block"))
    return blocks


def _eof_position(text: str) -> tuple[int, int]:
    end = len(text.rstrip())
    line = text.count("\n", 0, end) + 1
    col = end - (text.rfind("\n", 0, end) + 1) + 1
    return line, col


def _syntax_error(e: UnexpectedInput, text: str, filename: str) -> SceneError:
    def at(line, col, msg):
        return SceneError.at(text, filename, line, col, msg)

    if isinstance(e, UnexpectedCharacters):
        pos = e.pos_in_stream
        rest = text[pos:]
        if rest.startswith("/*"):
            return at(e.line, e.column, "unterminated block comment: '/*' has no matching '*/'")
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
            return at(
                e.line,
                col,
                f"malformed number '{word}': write numbers like 2, -0.5, .5 or 1e-3, "
                "separated by spaces or commas (there is no arithmetic)",
            )
        ch = rest[:1]
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
    kwt = _keyword_terminals()
    found = _describe(tok)

    if tok.type == "$END":
        line, col = _eof_position(text)
        if blocks:
            opener, name = blocks[-1]
            return at(line, col, f"missing closing '}}' for {name} opened at {opener.line}:{opener.column}")
        return at(line, col, f"unexpected end of file; expected {_expected_list(expected)}")

    line, col = tok.line, tok.column

    statement_keys = {n for n in expected if _keyword_terminals().get(n) in STATEMENTS}
    if tok.type == "RBRACE" and not blocks and expected <= statement_keys | {"$END"}:
        return at(line, col, "unexpected '}': no block is open here")

    keys = {n for n in expected if n in kwt}
    if keys and expected <= keys | {"RBRACE", "$END"}:
        # A keyword is expected: top-level statement or a key inside a block.
        allowed = _expected_list(keys)
        if not blocks:
            if tok.type == "WORD":
                return at(line, col, f"unknown statement '{tok}'; a statement is one of {allowed}")
            return at(line, col, f"unexpected {found} at top level; a statement is one of {allowed}")
        opener, name = blocks[-1]
        if opener in _CHANNEL_BLOCKS:
            what = ("a channel: 'color < r g b >', 'marble { ... }', 'image { file \"...\" }', "
                    "'add { ... }', 'multiply { ... }' or 'mix { ... }'")
            if opener == "mix":
                what += ", or 'weight W' last"
            if tok.type == "RBRACE":
                return at(line, col, f"empty {name}: expected {what}")
            if str(tok) == "weight":
                return at(line, col, "'weight' belongs in a mix block: mix { A B weight W }")
            if tok.type == "WORD":
                return at(line, col, f"unknown channel '{tok}' in {name}; expected {what}")
            return at(line, col, f"unexpected {found} in {name}; expected {what}")
        if tok.type == "WORD":
            renamed = _RENAMED_KEYS.get(str(tok), "")
            return at(line, col, f"unknown keyword '{tok}' in {name}{renamed}; allowed: {allowed}")
        if tok.type in kwt:
            return at(line, col, f"keyword '{tok}' is not allowed in {name}; allowed: {allowed}")
        return at(line, col, f"unexpected {found} in {name}; expected a keyword ({allowed}) or '}}'")

    if expected == {"RBRACE"} and blocks:
        opener, name = blocks[-1]
        msg = f"expected '}}' to close {name} opened at {opener.line}:{opener.column}, found {found}"
        if opener in ("ambient", "diffuse", "specular"):
            msg += " (a component takes exactly one channel)"
        return at(line, col, msg)

    after = f" after '{prev}'" if isinstance(prev, Token) and prev.type in kwt else ""
    if expected == {"NUMBER"}:
        return at(line, col, f"expected a number{after}, found {found}")
    if {"NUMBER", "MORETHAN"} <= expected:
        return at(line, col, f"expected a number or '>' in vector, found {found}")
    if expected == {"LESSTHAN"}:
        return at(line, col, f"expected a vector '< x y z >'{after}, found {found}")
    if expected == {"LESSTHAN", "RBRACE"}:
        return at(line, col, f"expected a colour '< r g b >' or '}}' in ramp, found {found}")
    if expected == {"STRING"}:
        return at(line, col, f'expected a quoted material name like "marble"{after}, found {found}')
    if expected == {"LBRACE"}:
        return at(line, col, f"expected '{{'{after}, found {found}")
    if expected == {"WORD"}:
        choices = {
            "function": "a function name: abs_sine, sine or cosine",
            "axis": "an axis: x, y or z",
            "turbulence": "true or false",
            "filter": "a filter: none, bandlimit or prefilter",
        }.get(str(prev), "a name")
        return at(line, col, f"expected {choices}{after}, found {found}")
    return at(line, col, f"unexpected {found}; expected {_expected_list(expected)}")


# --------------------------------------------------------------------------
#  Tree -> model, with validation
# --------------------------------------------------------------------------


def _keyword(tree: Tree) -> str:
    return _RULE_KEYWORD.get(tree.data, str(tree.data))


def _pos_of(tree: Tree) -> Pos:
    return Pos(tree.meta.line, tree.meta.column)


class _Builder:
    def __init__(self, text: str, filename: str, source: str | None = None) -> None:
        self.text = text
        self.filename = filename
        # Image maps are found relative to the scene file (else the working directory).
        self.folder = os.path.dirname(os.path.abspath(source)) if source else os.getcwd()

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
    def number(self, tok: Token) -> float:
        value = float(tok)
        if not math.isfinite(value):
            raise self.error(tok, f"number {tok} is not finite (it overflows double precision)")
        if abs(value) > _FLT_MAX:
            raise self.error(tok, f"number {tok} is too large: the renderer is single precision, |x| <= 3.4e38")
        return value

    def integer(self, tok: Token, what: str, lo: int, hi: int) -> int:
        value = self.number(tok)
        if not value.is_integer():
            raise self.error(tok, f"{what} must be an integer, found {tok}")
        if not lo <= value <= hi:
            raise self.error(tok, f"{what} must be in {lo}..{hi}, found {tok}")
        return int(value)

    def vector(self, tree: Tree, what: str) -> tuple[tuple[float, float, float], list[Token]]:
        toks = list(tree.children)
        if len(toks) != 3:
            raise self.error(tree, f"{what} needs 3 numbers, found {len(toks)}")
        return tuple(self.number(t) for t in toks), toks  # type: ignore[return-value]

    def point(self, tree: Tree, what: str) -> tuple[float, float, float]:
        return self.vector(tree, what)[0]

    def color(self, tree: Tree, what: str) -> tuple[float, float, float]:
        value, toks = self.vector(tree, f"{what} (a colour < r g b >)")
        for v, t in zip(value, toks):
            if v < 0:
                raise self.error(t, f"{what}: colour components must be >= 0, found {t}")
        return value

    def fields(self, tree: Tree, block: str) -> dict[str, Tree]:
        """The keyword sub-trees of a block, by keyword; duplicates are errors."""
        out: dict[str, Tree] = {}
        for child in tree.children:
            if not isinstance(child, Tree):
                continue
            key = _keyword(child)
            if key in out:
                first = out[key].meta
                raise self.error(
                    child, f"duplicate '{key}' in {block} (first given at {first.line}:{first.column})"
                )
            out[key] = child
        return out

    # -- statements -----------------------------------------------------------
    def scene(self, tree: Tree, source: str | None) -> Scene:
        once: dict[str, Tree] = {}
        image, camera, ambient = Image(), Camera(), (0.0, 0.0, 0.0)
        lights: list[Light] = []
        materials: dict[str, Material] = {}
        material_at: dict[str, Token] = {}
        spheres: list[tuple[Sphere, Token]] = []
        for st in tree.children:
            kind = st.data
            if kind in ("image", "camera", "ambient_light"):
                kw = _keyword(st)
                if kw in once:
                    first = once[kw].meta
                    raise self.error(
                        st,
                        f"duplicate '{kw}' statement (first given at {first.line}:{first.column}); "
                        f"a scene has at most one",
                    )
                once[kw] = st
            if kind == "image":
                image = self.image(st)
            elif kind == "camera":
                camera = self.camera(st)
            elif kind == "ambient_light":
                ambient = self.color(st.children[0], "ambient")
            elif kind == "light":
                lights.append(self.light(st))
            elif kind == "material":
                name_tok = st.children[0]
                mat = self.material(st)
                if mat.name in materials:
                    first = material_at[mat.name]
                    raise self.error(
                        name_tok,
                        f"duplicate material {name_tok} (first defined at {first.line}:{first.column})",
                    )
                materials[mat.name] = mat
                material_at[mat.name] = name_tok
            elif kind == "sphere":
                spheres.append(self.sphere(st))
            else:  # pragma: no cover - grammar and builder out of step
                raise self.error(st, f"internal error: unhandled statement {kind}")
        for sphere, name_tok in spheres:
            if sphere.material not in materials:
                known = ", ".join(f'"{n}"' for n in materials) or "none"
                raise self.error(name_tok, f'unknown material "{sphere.material}" (defined: {known})')
        return Scene(
            image=image,
            camera=camera,
            ambient=ambient,
            lights=tuple(lights),
            materials=FrozenMap(materials),
            spheres=tuple(s for s, _ in spheres),
            source=source,
        )

    def image(self, st: Tree) -> Image:
        f = self.fields(st, "'image' block")
        lo, hi = LIMITS["image_size"]
        d = Image()
        width = self.integer(f["width"].children[0], "width", lo, hi) if "width" in f else d.width
        height = self.integer(f["height"].children[0], "height", lo, hi) if "height" in f else d.height
        samples = d.samples
        if "samples" in f:
            tok = f["samples"].children[0]
            # Any count: path mode takes any; whitted mode and the reference tracer need a
            # perfect square (their n×n grid) and say so when asked to render it.
            samples = self.integer(tok, "samples", 1, LIMITS["max_image_samples"])
        total = width * height * samples
        if total > LIMITS["max_image_samples"]:
            where = f.get("samples") or f.get("width") or f.get("height") or st
            raise self.error(
                where,
                f"image too large: width*height*samples = {total} exceeds 2^28 = {LIMITS['max_image_samples']}",
            )
        background = self.color(f["background"].children[0], "background") if "background" in f else d.background
        return Image(width, height, samples, background, pos=_pos_of(st))

    def camera(self, st: Tree) -> Camera:
        f = self.fields(st, "'camera' block")
        d = Camera()
        eye = self.point(f["eye"].children[0], "eye") if "eye" in f else d.eye
        lookat = self.point(f["lookat"].children[0], "lookat") if "lookat" in f else d.lookat
        up = self.point(f["up"].children[0], "up") if "up" in f else d.up
        fov = d.fov
        if "fov" in f:
            tok = f["fov"].children[0]
            fov = self.number(tok)
            if not 0 < fov < 180:
                raise self.error(tok, f"fov must be in (0, 180) degrees, found {tok}")
        view = tuple(b - a for a, b in zip(eye, lookat))
        view_len = math.sqrt(sum(c * c for c in view))
        if view_len == 0 or not math.isfinite(view_len):
            where = f.get("lookat") or f.get("eye") or st
            raise self.error(where, "camera eye and lookat must be different points")
        up_len = math.sqrt(sum(c * c for c in up))
        cross = (
            up[1] * view[2] - up[2] * view[1],
            up[2] * view[0] - up[0] * view[2],
            up[0] * view[1] - up[1] * view[0],
        )
        cross_len = math.sqrt(sum(c * c for c in cross))
        if up_len == 0 or not cross_len > 1e-9 * up_len * view_len:
            where = f.get("up") or st
            raise self.error(where, "camera 'up' must not be zero or parallel to the view direction (lookat - eye)")
        return Camera(eye, lookat, up, fov, pos=_pos_of(st))

    def light(self, st: Tree) -> Light:
        f = self.fields(st, "'light' block")
        if "position" not in f:
            raise self.error(st, "light has no 'position'")
        position = self.point(f["position"].children[0], "position")
        color = self.color(f["color"].children[0], "light color") if "color" in f else Light(position).color
        return Light(position, color, pos=_pos_of(st))

    def material(self, st: Tree) -> Material:
        name_tok = st.children[0]
        name = str(name_tok)[1:-1]
        if not name:
            raise self.error(name_tok, "a material name must not be empty")
        block = f'material "{name}"'
        f = self.fields(st, block)
        channels = {k: self.channel(f[k], f"{k} of {block}") if k in f else None for k in ("ambient", "diffuse", "specular")}
        shininess = Material(name).shininess
        if "shininess" in f:
            tok = f["shininess"].children[0]
            shininess = self.number(tok)
            if not shininess > 0:
                raise self.error(tok, f"shininess must be > 0, found {tok}")
        return Material(name, shininess=shininess, pos=_pos_of(st), **channels)

    def channel(self, component: Tree, what: str):
        """The one channel of a component block (ambient, diffuse, specular)."""
        (ch,) = [c for c in component.children if isinstance(c, Tree)]
        return self.channel_of(ch, what)

    def channel_of(self, ch: Tree, what: str):
        if ch.data == "weight":
            raise self.error(ch, "'weight' belongs in a mix block: mix { A B weight W }")
        if ch.data == "color":
            return ColorChannel(self.color(ch.children[0], what), pos=_pos_of(ch))
        if ch.data == "marble":
            return self.marble(ch)
        if ch.data == "image_map":
            return self.image_map(ch)
        return self.expression(ch, what)

    def expression(self, st: Tree, what: str):
        """add / multiply / mix: their operands, counted and placed."""
        kind = str(st.data)
        parts = [c for c in st.children if isinstance(c, Tree)]
        operands = [c for c in parts if c.data != "weight"]
        weights = [c for c in parts if c.data == "weight"]
        inside = f"{what}, in '{kind}'"
        if kind != "mix" and weights:
            raise self.error(weights[0], f"'weight' belongs in a mix block, not in '{kind}': "
                                         f"mix {{ A B weight W }}")
        if kind == "mix":
            if len(operands) != 2:
                where = operands[2] if len(operands) > 2 else st
                raise self.error(where, f"mix takes exactly two channels and a weight "
                                        f"(mix {{ A B weight W }}), found {len(operands)} channels")
            if not weights:
                raise self.error(st, "mix has no 'weight'; write mix { A B weight W } "
                                     "(W a channel or a number)")
            if len(weights) > 1:
                first = weights[0].meta
                raise self.error(weights[1], f"duplicate 'weight' in 'mix' block (first given "
                                             f"at {first.line}:{first.column})")
            if parts.index(weights[0]) != len(parts) - 1:
                raise self.error(weights[0], "'weight' comes last: mix { A B weight W }")
            (value,) = weights[0].children
            weight = self.number(value) if isinstance(value, Token) \
                else self.channel_of(value, f"{inside} weight")
            a, b = (self.channel_of(c, inside) for c in operands)
            return Mix(a, b, weight, pos=_pos_of(st))
        if len(operands) < 2:
            raise self.error(st, f"'{kind}' needs two or more channels, found {len(operands)}")
        channels = tuple(self.channel_of(c, inside) for c in operands)
        return (Add if kind == "add" else Multiply)(channels, pos=_pos_of(st))

    def image_map(self, st: Tree) -> ImageChannel:
        """``image { file "…" }``: the file must be there and be an 8-bit PNG or JPEG."""
        f = self.fields(st, "'image' channel")
        if "file" not in f:
            raise self.error(st, 'image channel has no \'file\'; write image { file "maps/x.png" }')
        tok = f["file"].children[0]
        name = str(tok)[1:-1]
        if not name:
            raise self.error(tok, "an image file name must not be empty")
        path = os.path.normpath(os.path.join(self.folder, name))
        problem = image_file_problem(path)
        if problem:
            raise self.error(tok, f"image file '{name}': {problem}")
        # Its position is the file string's, where every error about the file points.
        return ImageChannel(name, path, pos=Pos(tok.line, tok.column))

    def marble(self, st: Tree) -> MarbleChannel:
        f = self.fields(st, "'marble' block")
        kw: dict = {}
        if "scale" in f:
            tok = f["scale"].children[0]
            kw["scale"] = self.number(tok)
            if not kw["scale"] > 0:
                raise self.error(tok, f"scale must be > 0, found {tok}")
        for key in ("period", "distortion"):
            if key in f:
                kw[key] = self.number(f[key].children[0])
        if "tolerance" in f:
            tok = f["tolerance"].children[0]
            kw["tolerance"] = self.number(tok)
            if not kw["tolerance"] >= 0:
                raise self.error(tok, f"tolerance must be ≥ 0, found {tok}")
        if "octaves" in f:
            lo, hi = LIMITS["octaves"]
            kw["octaves"] = self.integer(f["octaves"].children[0], "octaves", lo, hi)
        booleans = ("turbulence",)
        for key, choices in (("function", MARBLE_FUNCTIONS), ("axis", AXES),
                             ("turbulence", ("true", "false")), ("filter", MARBLE_FILTERS)):
            if key in f:
                tok = f[key].children[0]
                if str(tok) not in choices:
                    listed = ", ".join(choices[:-1]) + " or " + choices[-1]
                    raise self.error(tok, f"unknown {key} '{tok}'; expected {listed}")
                kw[key] = str(tok) == "true" if key in booleans else str(tok)
        if "ramp" in f:
            ramp_tree = f["ramp"]
            vecs = [c for c in ramp_tree.children if isinstance(c, Tree)]
            lo, hi = LIMITS["ramp_colours"]
            if len(vecs) < lo:
                raise self.error(
                    ramp_tree, f"a ramp needs at least {lo} colours, found {len(vecs)}" + (" (empty ramp)" if not vecs else "")
                )
            if len(vecs) > hi:
                raise self.error(vecs[hi], f"a ramp has at most {hi} colours, found {len(vecs)}")
            kw["ramp"] = tuple(self.color(v, "ramp colour") for v in vecs)
        return MarbleChannel(**kw, pos=_pos_of(st))

    def sphere(self, st: Tree) -> tuple[Sphere, Token]:
        f = self.fields(st, "'sphere' block")
        if "material" not in f:
            raise self.error(st, "sphere has no 'material'; add material \"name\"")
        name_tok = f["material"].children[0]
        d = Sphere("")
        center = self.point(f["center"].children[0], "center") if "center" in f else d.center
        radius = d.radius
        if "radius" in f:
            tok = f["radius"].children[0]
            radius = self.number(tok)
            if not radius > 0:
                raise self.error(tok, f"radius must be > 0, found {tok}")
        return Sphere(str(name_tok)[1:-1], center, radius, pos=_pos_of(st)), name_tok
