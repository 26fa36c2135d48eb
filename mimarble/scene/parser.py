"""Scene text -> :class:`~mimarble.scene.model.Scene`, with positioned errors.

Two stages:

1. Lark parses the text with the grammar (``scene.lark`` and the marble's rules
   written from its parameter table: grammar.py; LALR(1), basic lexer, positions
   propagated). Lark's exceptions become :class:`SceneError` with a human message
   (syntax_errors.py); no Lark exception escapes.

   The *basic* lexer rather than the contextual one: the contextual lexer only
   tries the terminals the parser accepts in the current state, so in a
   ``camera`` block the unknown word ``eyes`` would lex as the keyword ``eye``
   followed by ``s``. With the basic lexer every keyword is a reserved word, and
   an unknown word is reported as such, at its first character.

   The tokens are fed to Lark one by one (its interactive parser), so that the
   statements past a limit (lights, shapes, textures: limits.py) are refused at the
   first one too many, before the rest of the file is parsed.

2. :class:`_Builder` walks the tree into the frozen model, checking what the
   grammar does not: duplicates, arity, ranges, names, references, how deep channels
   nest; named textures are resolved into the channels they name (a texture defined
   anywhere in the file, none using itself), and mesh files' headers read
   (mesh_header.py). The values are checked by the rules the model's constructors apply
   (rules.py), here with the token's position; a marble's by the parameter table's
   own rules (``Parameter.check``).

Limits (limits.py, docs/scene-language.md "Limits") are enforced at the edge: a scene
file larger than :data:`~mimarble.scene.limits.MAX_SCENE_BYTES` is refused from its
size (at most that many bytes and one more are read), a FIFO or a device without being
opened for a read that could block (reading.py).
"""

from __future__ import annotations

import functools
import hashlib
import math
import os
import re

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedInput

from mimarble import parameters as marble_parameters
from mimarble.parameters import (BOOLEAN, CHOICE, COLOURS, PARAMETERS, Parameter, ParameterError,
    hex_colour, hex_colour_problem)
from mimarble.scene import rules, transforms
from .comments import blanked
from .errors import SceneError
from .grammar import grammar_text
from .image_header import image_file_sentence
from .keywords import CHANNEL_KEYWORDS
from .limits import LIMITS, MAX_IMAGE_SAMPLES, MAX_SCENE_BYTES
from .reading import NotRegularFile, open_regular
from .model import (
    MESH_FORMATS,
    SPACES,
    Add,
    Box,
    ImageChannel,
    Mix,
    Multiply,
    Camera,
    ColorChannel,
    FrozenMap,
    Image,
    AREA_SAMPLES,
    Light,
    MarbleChannel,
    Material,
    Mesh,
    Plane,
    Pos,
    RectangleArea,
    Scene,
    Sphere,
    SphereArea,
    Subsurface,
    walk,
)
from .model import depth as depth_of
from .model import size as size_of
from .syntax_errors import decoded, povray_hint, syntax_error

__all__ = ["parse", "load", "LIMITS"]

# LIMITS: limits.py, each stated once with why (and in docs/scene-language.md, Limits);
# the marble's are its parameter table's.

#: The refusal of a scene larger than the limit.
_TOO_LARGE = (f"the scene is larger than 4 MiB ({MAX_SCENE_BYTES} bytes), the most a scene "
              f"file holds (docs/scene-language.md, Limits)")

#: How the language writes a linear colour, in the sentences about ``#rrggbb``.
_LINEAR_COLOUR = "< r g b >"

# Rule names whose keyword differs from the rule name.
_RULE_KEYWORD = {"shape_material": "material", "ambient_light": "ambient", "image_map": "image",
                 "transform_scale": "scale", "texture_definition": "texture",
                 "texture_use": "texture"}

#: The statements whose count is limited (rules.count_problem), counted as the tokens are
#: fed. ``texture`` is counted where it starts a statement (a definition, outside every
#: block), not where it names a channel.
_COUNTED = ("light", "sphere", "plane", "box", "mesh", "texture")

#: What each kind of shape lacks for an image map: texture coordinates (u, v).
_NO_UV = {"plane": "a plane", "box": "a box", "mesh": "this mesh's file"}


def _parser_cache_file(grammar: str) -> str | bool:
    """Where Lark keeps the built parser between processes, or False for no cache.

    Building the LALR tables takes ~0.15 s, three times the rest of a scene
    error's answer; Lark's cache keeps them as a pickle checked against the
    grammar's hash. The file lives in the user's own cache folder
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
    """The terminals :func:`_tree` watches: the statements whose count is limited
    (terminal -> its keyword, :data:`_COUNTED`), the expressions' keywords (``add``,
    ``multiply``, ``mix``) and every channel's (``texture`` among them)."""
    words = _keyword_terminals()
    counted = {name: word for name, word in words.items() if word in _COUNTED}
    expressions = frozenset(name for name, word in words.items()
                            if word in ("add", "multiply", "mix"))
    channels = frozenset(name for name, word in words.items() if word in CHANNEL_KEYWORDS)
    return counted, expressions, channels


def _tree(text: str, filename: str) -> Tree:
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
                problem = rules.count_problem(counted[kind], counts[counted[kind]])
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


def _oversized(text) -> bool:
    """More than the scene limit's bytes (text: as UTF-8)."""
    if len(text) > MAX_SCENE_BYTES:
        return True
    if isinstance(text, str) and len(text) * 4 > MAX_SCENE_BYTES:
        return len(text.encode("utf-8", "surrogatepass")) > MAX_SCENE_BYTES
    return False


# --------------------------------------------------------------------------
#  Public entry points
# --------------------------------------------------------------------------


#: Scenes parsed from files, by file name (and where it is) and a digest of the bytes
#: read, with their image maps' file facts: the model is immutable, so a file read again
#: with the same bytes and maps is not parsed again (a warm ``mimarble.render(path)``
#: reads the file, ~20 µs, where parsing took ~2 ms).
_PARSED: dict = {}
_PARSED_KEPT = 16


def load(path: str | os.PathLike) -> Scene:
    """Read and parse a scene file. Every failure is a :class:`SceneError`; a file that
    is not a regular file (a FIFO, a device) is refused without being opened for a
    read that could block, and one larger than ``LIMITS["max_scene_bytes"]`` without
    being read past that. The file is read every time; the same bytes under the same
    name give the scene parsed before."""
    filename = os.fspath(path)
    if isinstance(filename, bytes):
        filename = os.fsdecode(filename)
    if filename == "" or "\0" in filename:    # "" is the current folder to the system
        raise SceneError("cannot read scene file: " + (
            "the name is empty" if not filename else
            "the name holds a NUL character, which no file name can"), filename=repr(filename))
    try:
        with open_regular(path) as f:
            if os.fstat(f.fileno()).st_size > MAX_SCENE_BYTES:
                raise SceneError(_TOO_LARGE, filename=filename)
            data = f.read(MAX_SCENE_BYTES + 1)     # no more, should it have grown since
    except NotRegularFile as e:
        raise SceneError(f"cannot read scene file: {e}", filename=filename) from None
    except FileNotFoundError:
        raise SceneError(f"cannot read scene file: no such file (looked for "
                         f"{os.path.abspath(filename)})", filename=filename) from None
    except IsADirectoryError:
        raise SceneError("cannot read scene file: it is a directory", filename=filename) from None
    except PermissionError:
        raise SceneError("cannot read scene file: permission denied", filename=filename) from None
    except OSError as e:
        raise SceneError(f"cannot read scene file: {e.strerror or e}", filename=filename) from None
    key = (os.path.abspath(filename), filename, hashlib.blake2b(data, digest_size=16).digest())
    kept = _PARSED.get(key)
    # The parser also checks the image maps' and mesh files' headers: a file changed
    # since is read again.
    if kept is None or kept[1] != _file_facts(kept[0]):
        scene = parse(data, filename=filename, source=filename)   # errors are not kept
        if len(_PARSED) >= _PARSED_KEPT:
            _PARSED.pop(next(iter(_PARSED)))
        kept = _PARSED[key] = (scene, _file_facts(scene))
    return kept[0]


def _file_facts(scene) -> tuple:
    """(size, modification and change times, inode) of each image map's and mesh's file
    (None: unreadable)."""
    facts = []
    for located in scene.image_maps() + scene.meshes:
        try:
            found = os.stat(located.location)
            facts.append((found.st_size, found.st_mtime_ns, found.st_ctime_ns, found.st_ino))
        except OSError:
            facts.append(None)
    return tuple(facts)


def _image_maps(materials) -> tuple:
    """Every distinct image map of ``materials`` (Scene.image_maps' walk; a channel holds at
    most LIMITS["max_channel_size"] channels, so walking every use of a texture is bounded)."""
    return tuple(dict.fromkeys(c for m in materials for ch in m.channels().values()
                               for c in walk(ch) if isinstance(c, ImageChannel)))


def parse(text: str | bytes, filename: str = "<string>", *, source: str | None = None) -> Scene:
    """Parse scene text. ``filename`` is used in messages only.

    ``Scene.source`` is ``source`` if given, else ``filename`` unless that is
    the default ``"<string>"``. Text of more than ``LIMITS["max_scene_bytes"]``
    bytes (as UTF-8) is refused, as a file of that size is.
    """
    if not isinstance(text, (str, bytes, bytearray)):
        raise TypeError(f"parse: the scene text must be str or bytes, found "
                        f"{type(text).__name__}")
    if _oversized(text):
        raise SceneError(_TOO_LARGE, filename=filename)
    if isinstance(text, (bytes, bytearray)):
        text = decoded(bytes(text), filename)
    if text.startswith("\ufeff"):  # a UTF-8 byte order mark is not part of the scene
        text = text[1:]
    if source is None and filename != "<string>":
        source = filename
    return _Builder(text, filename, source).scene(_tree(text, filename), source)


# --------------------------------------------------------------------------
#  Tree -> model, with validation
# --------------------------------------------------------------------------


def _keyword(tree: Tree) -> str:
    return _RULE_KEYWORD.get(tree.data, str(tree.data))


def _pos_of(tree: Tree) -> Pos:
    return Pos(tree.meta.line, tree.meta.column)


def _name(tok: Token) -> str:
    """A STRING token's text without its quotes."""
    return str(tok)[1:-1]


def _vector_text(v) -> str:
    """A vector as the language writes it: ``< 1 0 -0.5 >``."""
    return "< " + " ".join(repr(x).removesuffix(".0") for x in v) + " >"


class _Builder:
    def __init__(self, text: str, filename: str, source: str | None = None) -> None:
        self.text = text
        self.filename = filename
        # Image maps and meshes are found relative to the scene file (else the working
        # directory).
        self.folder = os.path.dirname(os.path.abspath(source)) if source else os.getcwd()
        self.meshes_read: dict = {}      # mesh file path -> its MeshFacts, in this parse
        #: The texture definitions, by name (the first of a name), and the channels of
        #: those resolved so far.
        self.definitions: dict[str, Tree] = {}
        self.resolved: dict[str, object] = {}
        #: The triangles of the meshes read so far (the limit is on their sum).
        self.triangles = 0

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
        light_at: list[Tree] = []       # each light's statement
        materials: dict[str, Material] = {}
        material_at: dict[str, Token] = {}
        # Every shape, in file order: (shape, its material's name token, whether it has
        # texture coordinates for image maps).
        shapes: list[tuple[object, Token, bool]] = []
        # Textures may be used before they are defined, as materials may.
        for st in tree.children:
            if st.data == "texture_definition":
                self.definitions.setdefault(_name(st.children[0]), st)
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
                light_at.append(st)
            elif kind == "material":
                name_tok = st.children[0]
                mat = self.material(st)
                if mat.name in materials:
                    first = material_at[mat.name]
                    raise self.error(
                        name_tok,
                        f"duplicate material {rules.shortened(name_tok)} (first defined at "
                        f"{first.line}:{first.column})",
                    )
                materials[mat.name] = mat
                material_at[mat.name] = name_tok
            elif kind == "texture_definition":
                self.texture_definition(st)
            elif kind in ("sphere", "plane", "box", "mesh"):
                shapes.append(getattr(self, kind)(st))
            else:  # pragma: no cover - grammar and builder out of step
                raise self.error(st, f"internal error: unhandled statement {kind}")
        imaged = {m.name for m in materials.values() if _image_maps([m])}
        for shape, name_tok, has_uv in shapes:
            problem = rules.unknown_material(shape.material, materials)
            if problem:
                raise self.error(name_tok, problem)
            if not has_uv and shape.material in imaged:
                kind = type(shape).__name__.lower()
                raise self.error(name_tok, rules.image_map_uv_problem(shape.material,
                                                                      _NO_UV[kind]))
        for light, st in zip(lights, light_at):   # against the camera, wherever it is
            if isinstance(light.area, SphereArea):
                problem = rules.area_light_enclosure_problem(light.position, light.area.radius,
                                                             camera.eye, camera.lookat)
                if problem:
                    area = self.fields(st, "'light' block")["area"]
                    raise self.error(self.fields(area, "'area' block")["radius"].children[0],
                                     problem)
        of = {kind: tuple(s for s, _, _ in shapes if isinstance(s, kind))
              for kind in (Sphere, Plane, Box, Mesh)}
        return Scene(
            image=image,
            camera=camera,
            ambient=ambient,
            lights=tuple(lights),
            materials=FrozenMap(materials),
            spheres=of[Sphere],
            planes=of[Plane],
            boxes=of[Box],
            meshes=of[Mesh],
            textures=FrozenMap((name, self.resolved[name]) for name in self.definitions),
            source=source,
        )

    # -- named textures ---------------------------------------------------------
    def texture_definition(self, st: Tree) -> None:
        """``texture "NAME" { CHANNEL }``: its name (the material name rule; unique: a
        second definition is refused at its name), and its channel, resolved."""
        name_tok = st.children[0]
        name = _name(name_tok)
        problem = rules.texture_name_problem(name)
        if problem:
            raise self.error(name_tok, problem)
        first = self.definitions[name]
        if first is not st:
            at = first.children[0]
            raise self.error(name_tok, f"duplicate texture {rules.shortened(name_tok)} (first "
                                       f"defined at {at.line}:{at.column})")
        self.texture(name_tok)

    def texture(self, name_tok: Token):
        """The channel the texture named by ``name_tok`` (a use, or a definition's name)
        stands for. Its definition and those it uses, directly or through others, are
        built once, those it uses first (:meth:`texture_order`), so that building one
        finds every texture it uses already built: no recursion through the uses."""
        name = _name(name_tok)
        if name not in self.resolved:
            for each in self.texture_order(name_tok):
                self.resolved[each] = self.channel(self.definitions[each], f'texture "{each}"')
        return self.resolved[name]

    def texture_order(self, name_tok: Token) -> list[str]:
        """The textures not yet built that the texture ``name_tok`` names needs, itself
        last, each after those it uses: a depth-first walk of the uses (an explicit
        stack: a chain of thousands of textures is within the limits). An unknown name
        is refused at the use's name; a use that closes a cycle at its name, naming the
        cycle."""
        self.known(name_tok)
        first = _name(name_tok)
        order: list[str] = []
        walked = set(self.resolved)
        stack = [(first, self.uses(first))]           # the path walked, each its uses left
        on_path = {first}
        while stack:
            current, uses = stack[-1]
            for use in uses:
                used = _name(self.known(use))
                if used in on_path:
                    path = [n for n, _ in stack]
                    cycle = " -> ".join(rules.shortened(n, 30)
                                        for n in path[path.index(used):] + [used])
                    raise self.error(use, f'texture "{rules.shortened(used)}" uses itself: '
                                          f"{cycle}")
                if used not in walked:
                    stack.append((used, self.uses(used)))
                    on_path.add(used)
                    break
            else:
                stack.pop()
                on_path.discard(current)
                walked.add(current)
                order.append(current)
        return order

    def uses(self, name: str):
        """The name tokens of the textures the definition of ``name`` uses, in text order."""
        return (t.children[0] for t in self.definitions[name].iter_subtrees_topdown()
                if t.data == "texture_use")

    def known(self, name_tok: Token) -> Token:
        """``name_tok``, when it names a defined texture; else an error at it."""
        if _name(name_tok) not in self.definitions:
            raise self.error(name_tok, f"unknown texture {rules.shortened(name_tok)} (defined: "
                                       f"{rules.listed_names(self.definitions)})")
        return name_tok

    def image(self, st: Tree) -> Image:
        f = self.fields(st, "'image' block")
        lo, hi = rules.IMAGE_SIZE
        d = Image()
        width = self.integer(f["width"].children[0], "width", lo, hi) if "width" in f else d.width
        height = self.integer(f["height"].children[0], "height", lo, hi) if "height" in f else d.height
        samples = d.samples
        if "samples" in f:
            tok = f["samples"].children[0]
            # Any count: path mode takes any; whitted mode and the reference tracer need a
            # perfect square (their n×n grid) and say so when asked to render it.
            samples = self.integer(tok, "samples", 1, MAX_IMAGE_SAMPLES)
        problem = rules.image_samples_problem(width, height, samples)
        if problem:
            raise self.error(f.get("samples") or f.get("width") or f.get("height") or st, problem)
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
            self.refuse(tok, rules.fov_problem(fov))
        problem = rules.view_problem(eye, lookat)
        if problem:
            raise self.error(f.get("lookat") or f.get("eye") or st, problem)
        problem = rules.up_problem(eye, lookat, up)
        if problem:
            raise self.error(f.get("up") or st, problem)
        return Camera(eye, lookat, up, fov, pos=_pos_of(st))

    def light(self, st: Tree) -> Light:
        f = self.fields(st, "'light' block")
        if "position" not in f:
            raise self.error(st, "light has no 'position'")
        position = self.point(f["position"].children[0], "position")
        color = self.color(f["color"].children[0], "light color") if "color" in f else Light(position).color
        area = self.area(f["area"]) if "area" in f else None
        return Light(position, color, area, pos=_pos_of(st))

    def area(self, st: Tree) -> RectangleArea | SphereArea:
        """``area { axis1 <> axis2 <> samples N }`` (a rectangle) or ``area { radius R
        samples N }`` (a sphere); samples a square n² within the limit, at the number."""
        f = self.fields(st, "'area' block")
        edges = [f[k] for k in ("axis1", "axis2") if k in f]
        if edges and "radius" in f:
            second = max(edges + [f["radius"]], key=lambda t: (t.meta.line, t.meta.column))
            raise self.error(second, "an area light is a rectangle (axis1 and axis2) or a "
                                     "sphere (radius), not both")
        if not edges and "radius" not in f:
            raise self.error(st, "area needs axis1 and axis2 (a rectangle) or radius (a "
                                 "sphere), e.g. area { radius 0.5 samples 16 }")
        samples = AREA_SAMPLES
        if "samples" in f:
            tok = f["samples"].children[0]
            samples = self.number(tok)
            self.refuse(tok, rules.light_samples_problem(samples))
        if "radius" in f:
            tok = f["radius"].children[0]
            radius = self.number(tok)
            self.refuse(tok, rules.area_radius_problem(radius))
            return SphereArea(radius, samples, pos=_pos_of(st))
        if len(edges) < 2:
            missing = "axis2" if "axis1" in f else "axis1"
            raise self.error(st, f"a rectangular area light needs both axis1 and axis2 "
                                 f"(no '{missing}')")
        axis1, axis2 = (self.point(f[k].children[0], k) for k in ("axis1", "axis2"))
        problem = rules.area_axes_problem(axis1, axis2)
        if problem:
            at = ("axis1" if not any(axis1) else "axis2") if "zero" in problem else \
                "axis1" if "axis1 is too small" in problem else "axis2"
            raise self.error(f[at], problem)
        return RectangleArea(axis1, axis2, samples, pos=_pos_of(st))

    def material(self, st: Tree) -> Material:
        name_tok = st.children[0]
        name = _name(name_tok)
        problem = rules.material_name_problem(name)
        if problem:
            raise self.error(name_tok, problem)
        block = f'material "{name}"'
        f = self.fields(st, block)
        channels = {k: self.channel(f[k], f"{k} of {block}") if k in f else None for k in ("ambient", "diffuse", "specular")}
        shininess = Material(name).shininess
        if "shininess" in f:
            tok = f["shininess"].children[0]
            shininess = self.number(tok)
            self.refuse(tok, rules.shininess_problem(shininess))
        subsurface = self.subsurface(f["subsurface"], block) if "subsurface" in f else None
        return Material(name, shininess=shininess, subsurface=subsurface, pos=_pos_of(st),
                        **channels)

    def subsurface(self, st: Tree, block: str) -> Subsurface:
        """``subsurface { albedo CH mean_free_path X density CH ior X }``: albedo and
        mean_free_path required (refused at the ``subsurface`` keyword without them), each
        key at most once; the numbers by their rules (rules.py) at the number, the
        channels read as any channel is (depth, size, named textures) but with no image
        map in them, directly or through a texture (:meth:`volume_channel`); the keys
        checked in the order written."""
        f = self.fields(st, "'subsurface' block")
        for key in ("albedo", "mean_free_path"):
            if key not in f:
                raise self.error(st, f"subsurface has no '{key}'; write subsurface {{ albedo "
                                     f"color < 0.9 0.9 0.9 > mean_free_path 0.2 }}")
        values = {}             # ior absent: the model's default
        for key, tree in f.items():
            if key in ("albedo", "density"):
                values[key] = self.volume_channel(tree, f"{key} of the subsurface of {block}")
                continue
            tok = tree.children[0]
            values[key] = self.number(tok)
            problem = (rules.mean_free_path_problem if key == "mean_free_path"
                       else rules.ior_problem)(values[key])
            self.refuse(tok, problem)
        return Subsurface(pos=_pos_of(st), **values)

    def volume_channel(self, key: Tree, what: str):
        """The channel after a subsurface's ``albedo`` or ``density`` (written bare). A
        volume's points have no texture coordinates (u, v): an image map written in it is
        refused at its ``image`` keyword before its file is read, one brought in by a
        named texture at that texture's use."""
        (ch,) = [c for c in key.children if isinstance(c, Tree)]
        for inner in ch.iter_subtrees_topdown():
            held = inner.data == "texture_use" and any(
                isinstance(c, ImageChannel) for c in walk(self.texture(inner.children[0])))
            if inner.data == "image_map" or held:
                said = f"texture {rules.shortened(inner.children[0])} holds an image map, " \
                    f"which" if held else "an image map"
                raise self.error(inner, f"{said} has no place in a subsurface: it is read at a "
                                        f"surface's texture coordinates (u, v), and the points "
                                        f"inside a volume have none; use colours, marbles and "
                                        f"expressions of them there")
        return self.channel_of(ch, what)

    def channel(self, component: Tree, what: str):
        """The one channel of a component block (ambient, diffuse, specular)."""
        (ch,) = [c for c in component.children if isinstance(c, Tree)]
        return self.channel_of(ch, what)

    def channel_of(self, ch: Tree, what: str, depth: int = 1):
        """The channel ``ch`` at ``depth`` (1: a component's own); one nested past the
        limit is refused at its keyword, before its operands are read."""
        problem = rules.depth_problem(depth)
        if problem:
            raise self.error(ch, problem)
        if ch.data == "weight":
            raise self.error(ch, "'weight' belongs in a mix block: mix { A B weight W }")
        if ch.data == "color":
            return ColorChannel(self.color(ch.children[0], what), pos=_pos_of(ch))
        if ch.data == "marble":
            return self.marble(ch)
        if ch.data == "image_map":
            return self.image_map(ch)
        if ch.data == "texture_use":
            return self.texture_use(ch, depth)
        return self.expression(ch, what, depth)

    def texture_use(self, ch: Tree, depth: int):
        """``texture "NAME"`` at ``depth``: the texture's channel, whose own levels count
        from there (refused at the use when the deepest goes past the limit)."""
        (name_tok,) = ch.children
        channel = self.texture(name_tok)
        problem = rules.depth_problem(depth - 1 + depth_of(channel))
        if problem:
            raise self.error(ch, f"{problem}: texture {rules.shortened(name_tok)} nests "
                                 f"{depth_of(channel)} levels and is used at level {depth}")
        return channel

    def expression(self, st: Tree, what: str, depth: int = 1):
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
                else self.channel_of(value, f"{inside} weight", depth + 1)
            a, b = (self.channel_of(c, inside, depth + 1) for c in operands)
            self.sized(st, (a, b) + (() if isinstance(weight, float) else (weight,)))
            return Mix(a, b, weight, pos=_pos_of(st))
        if len(operands) < 2:
            raise self.error(st, f"'{kind}' needs two or more channels, found {len(operands)}")
        channels = tuple(self.channel_of(c, inside, depth + 1) for c in operands)
        self.sized(st, channels)
        return (Add if kind == "add" else Multiply)(channels, pos=_pos_of(st))

    def sized(self, st: Tree, operands) -> None:
        """An expression of ``operands`` within the channel size limit (named textures
        counted at each use), else an error at its keyword."""
        problem = rules.size_problem(1 + sum(size_of(c) for c in operands))
        if problem:
            raise self.error(st, problem)

    def image_map(self, st: Tree) -> ImageChannel:
        """``image { file "…" }``: the file must be there and be an 8-bit PNG or JPEG."""
        f = self.fields(st, "'image' channel")
        if "file" not in f:
            raise self.error(st, 'image channel has no \'file\'; write image { file "maps/x.png" }')
        tok = f["file"].children[0]
        name = _name(tok)
        self.file_name(tok, "an image")
        path = os.path.normpath(os.path.join(self.folder, name))
        problem = image_file_sentence(name, path)
        if problem:
            raise self.error(tok, problem)
        # Its position is the file string's, where every error about the file points.
        return ImageChannel(name, path, pos=Pos(tok.line, tok.column))

    def file_name(self, tok: Token, kind: str) -> None:
        """A file's name (``kind``: an image, a mesh) is not empty and holds no NUL
        character (which no system's paths take)."""
        if not _name(tok):
            raise self.error(tok, f"{kind} file name must not be empty")
        if "\0" in tok:
            raise self.error(tok, f"{kind} file name must not hold a NUL character")

    def marble(self, st: Tree) -> MarbleChannel:
        """``marble { … }``: each key given, read as its kind is written and checked by
        its row of the parameter table; the error is at the value, in the table's words."""
        f = self.fields(st, "'marble' block")
        values = {}
        for p in PARAMETERS:
            if p.name not in f:
                continue
            value, where = self.marble_value(p, f[p.name])
            if p.kind == COLOURS:       # ramp { [p] colour … }: its positions, checked
                value, positions = value
                if positions is not None:
                    values["ramp_positions"] = positions
            try:
                values[p.name] = p.check(value, text=True)
            except ParameterError as e:
                if p.kind == COLOURS:   # a count: the message says it
                    raise self.error(where, str(e)) from None
                raise self.error(where, f"{e}, found {rules.shortened(where)}") from None
        steps = self.transform(f["transform"]) if "transform" in f else ()
        space = "world"
        if "space" in f:
            (tok,) = f["space"].children
            space = str(tok)
            self.refuse(tok, None if space in SPACES else
                        f"a marble's space is {' or '.join(SPACES)}")
        return MarbleChannel(**values, transform=steps, space=space, pos=_pos_of(st))

    def transform(self, st: Tree) -> tuple:
        """``transform { translate <> rotate <> scale s|<> … }``: its steps in the order
        written, any number of each; a scale factor 0 is refused at its number, a matrix
        the renderer cannot invert at the ``transform`` keyword (transforms.py)."""
        steps = []
        for step in (c for c in st.children if isinstance(c, Tree)):
            kind = _keyword(step)
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

    def marble_value(self, p: Parameter, key: Tree):
        """The value of a marble key as written, for ``p.check``, and where to point at
        it: a number (finite, in float32's range), a word, or colours (each ≥ 0, as
        every colour of the language; a wrong count points at the colour past the
        most, or at the block)."""
        if p.kind != COLOURS:
            (tok,) = key.children
            is_word = p.kind in (CHOICE, BOOLEAN)
            return (str(tok) if is_word else self.number(tok)), tok
        vecs = [c for c in key.children if isinstance(c, Tree) or c.type == "HEX_COLOUR"]
        most = p.bounds[1]
        where = vecs[most] if len(vecs) > most else key
        colours = tuple(self.color(v, f"{p.name} colour") for v in vecs)
        return (colours, self.ramp_positions(key, vecs)), where

    def ramp_positions(self, key: Tree, vecs: list):
        """The positions of a ramp block, ``ramp { 0 < 1 1 1 > 0.5 #808080 1 < 0 0 0 > }``
        (a number before each colour, or before none), checked by the table's rule at
        the number at fault; None without positions."""
        before, written = None, []      # the number written before each colour, or None
        for child in key.children:
            if isinstance(child, Token) and child.type == "NUMBER":
                if before is not None:
                    raise self.error(before, f"ramp position {rules.shortened(before)} has "
                                             f"no colour after it; write a position, then "
                                             f"its colour: ramp {{ 0 < 1 1 1 > 1 #202020 }}")
                before = child
            elif isinstance(child, Tree) or child.type == "HEX_COLOUR":
                written.append(before)
                before = None
        if before is not None:
            raise self.error(before, f"ramp position {rules.shortened(before)} has no colour "
                                     f"after it; the ramp ends there")
        if not any(t is not None for t in written):
            return None
        if any(t is None for t in written):
            k = next(k for k, t in enumerate(written) if t is None)
            raise self.error(vecs[k], f"ramp colour {k + 1} has no position, where others "
                                      f"have one: give every colour a position or none")
        positions = tuple(self.number(t) for t in written)
        problem = marble_parameters.positions_problem(positions)
        if problem:
            k, sentence = problem
            raise self.error(written[min(k, len(written) - 1)], sentence)
        return positions

    # -- shapes: each (shape, its material's name token, whether it has (u, v)) ---
    def shape_fields(self, st: Tree) -> tuple[dict[str, Tree], Token]:
        """A shape block's keys and its material's name token (required)."""
        kind = str(st.data)
        f = self.fields(st, f"'{kind}' block")
        if "material" not in f:
            raise self.error(st, f"{kind} has no 'material'; add material \"name\"")
        return f, f["material"].children[0]

    def sphere(self, st: Tree) -> tuple[Sphere, Token, bool]:
        f, name_tok = self.shape_fields(st)
        d = Sphere("")
        center = self.point_of(f, "center", d.center)
        radius = d.radius
        if "radius" in f:
            tok = f["radius"].children[0]
            radius = self.number(tok)
            self.refuse(tok, rules.radius_problem(radius))
        return Sphere(_name(name_tok), center, radius, pos=_pos_of(st)), name_tok, True

    def plane(self, st: Tree) -> tuple[Plane, Token, bool]:
        """``plane { point <> normal <> material "m" }``: a zero normal is refused at its
        vector."""
        f, name_tok = self.shape_fields(st)
        d = Plane("")
        point, normal = self.point_of(f, "point", d.point), self.point_of(f, "normal", d.normal)
        problem = rules.normal_problem(normal)
        if problem:
            raise self.error(f["normal"].children[0], f"{problem}, found {_vector_text(normal)}")
        return Plane(_name(name_tok), point, normal, pos=_pos_of(st)), name_tok, False

    def box(self, st: Tree) -> tuple[Box, Token, bool]:
        """``box { min <> max <> transform { … } material "m" }``: corners out of order
        are refused at ``max`` (else ``min``); the transform is a marble's."""
        f, name_tok = self.shape_fields(st)
        d = Box("")
        lo, hi = self.point_of(f, "min", d.min), self.point_of(f, "max", d.max)
        problem = rules.box_problem(lo, hi)
        if problem:
            raise self.error(f.get("max") or f["min"], f"{problem}, found min "
                                                       f"{_vector_text(lo)} max {_vector_text(hi)}")
        steps = self.transform(f["transform"]) if "transform" in f else ()
        return Box(_name(name_tok), lo, hi, steps, pos=_pos_of(st)), name_tok, False

    def mesh(self, st: Tree) -> tuple[Mesh, Token, bool]:
        """``mesh { file "…" transform { … } material "m" }``: the file, relative to the
        scene file, is checked at its string — a PLY or OBJ name, then what
        mesh_header.mesh_facts says of it (a regular file there, within the size limit,
        in the image maps' words; its header; each sentence after ``mesh file 'NAME':``)
        — and its triangles counted toward the scene's limit; the mesh is refused at its
        file string when they pass it."""
        f, name_tok = self.shape_fields(st)
        if "file" not in f:
            raise self.error(st, "mesh has no 'file'; write mesh { file \"models/vase.ply\" "
                                 "material \"m\" }")
        tok = f["file"].children[0]
        name = _name(tok)
        self.file_name(tok, "a mesh")
        if not name.lower().endswith(MESH_FORMATS):
            raise self.error(tok, rules.mesh_format_problem(name))
        path = os.path.normpath(os.path.join(self.folder, name))
        facts = self.meshes_read.get(path)       # a file used by several meshes: read once
        if facts is None:
            from mimarble.scene import mesh_header           # here: only meshes need it
            try:
                facts = self.meshes_read[path] = mesh_header.mesh_facts(path)
            except mesh_header.MeshFileError as e:
                raise self.error(tok, f"mesh file '{rules.shortened(name, 256)}': {e}") from None
        self.triangles += facts.triangles
        problem = rules.mesh_triangles_problem(self.triangles)
        if problem:
            raise self.error(tok, problem)
        steps = self.transform(f["transform"]) if "transform" in f else ()
        # Its position is the file string's, where every error about the file points.
        mesh = Mesh(_name(name_tok), name, path, steps, pos=Pos(tok.line, tok.column),
                    digest=facts.digest)
        return mesh, name_tok, facts.has_uv
