"""The scene builder's materials and their channels: named textures (resolved in the order
they use each other, cycles refused), colours, marbles (by the parameter table's rules),
image maps, expressions (``add``, ``multiply``, ``mix``) within the depth and size limits,
and a material's ``subsurface``.
"""

from __future__ import annotations

from lark import Token, Tree

from mimarble import parameters as marble_parameters
from mimarble import presets
from mimarble.parameters import BOOLEAN, CHOICE, COLOURS, PARAMETERS, Parameter, ParameterError
from mimarble.scene import rules
from .build_values import ValueReader, pos_of, source_of, unquoted
from .image_header import image_file_sentence
from .model import (SPACES, Add, ColorChannel, ImageChannel, MarbleChannel, Material, Mix,
                    Multiply, Pos, Subsurface, walk)
from .model import depth as depth_of
from .model import size as size_of


class MaterialBuilder(ValueReader):
    """Materials, named textures and channels. ``definitions``: the texture definitions by
    name (the first of a name); ``resolved``: the channels of those built so far;
    ``folder``: where image maps are found."""

    definitions: dict[str, Tree]
    resolved: dict[str, object]
    folder: str

    # -- named textures ---------------------------------------------------------
    def texture_definition(self, st: Tree) -> None:
        """``texture "NAME" { CHANNEL }``: its name (the material name rule; unique: a
        second definition is refused at its name), and its channel, resolved."""
        name_tok = st.children[0]
        name = unquoted(name_tok)
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
        name = unquoted(name_tok)
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
        first = unquoted(name_tok)
        order: list[str] = []
        walked = set(self.resolved)
        stack = [(first, self.uses(first))]           # the path walked, each its uses left
        on_path = {first}
        while stack:
            current, uses = stack[-1]
            for use in uses:
                used = unquoted(self.known(use))
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
        if unquoted(name_tok) not in self.definitions:
            raise self.error(name_tok, f"unknown texture {rules.shortened(name_tok)} (defined: "
                                       f"{rules.listed_names(self.definitions)})")
        return name_tok

    def material(self, st: Tree) -> Material:
        name_tok = st.children[0]
        name = unquoted(name_tok)
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
        return Material(name, shininess=shininess, subsurface=subsurface, pos=pos_of(st),
                        **channels)

    def subsurface(self, st: Tree, block: str) -> Subsurface:
        """``subsurface { reflectance CH | albedo CH  mean_free_path X density CH ior X }``:
        mean_free_path and exactly one of albedo / reflectance required (neither, or both,
        refused at the ``subsurface`` keyword), each key at most once; the numbers by their
        rules (rules.py) at the number, the channels read as any channel is (depth, size,
        named textures) but with no image map in them, directly or through a texture
        (:meth:`volume_channel`); the keys checked in the order written."""
        f = self.fields(st, "'subsurface' block")
        example = "write subsurface { reflectance color < 0.9 0.9 0.9 > mean_free_path 0.2 }"
        if "albedo" not in f and "reflectance" not in f:
            raise self.error(st, f"subsurface has no 'albedo' or 'reflectance'; {example} "
                                 f"(reflectance: the colour seen; albedo: the single-"
                                 f"scattering albedo)")
        if "albedo" in f and "reflectance" in f:      # refused at the second written
            first, second = (key for key in f if key in ("albedo", "reflectance"))
            at = f[first].meta
            raise self.error(f[second], f"subsurface has both '{first}' (at {at.line}:"
                                        f"{at.column}) and '{second}'; give one: reflectance, "
                                        f"the colour seen, or albedo, the single-scattering "
                                        f"albedo")
        if "mean_free_path" not in f:
            raise self.error(st, f"subsurface has no 'mean_free_path'; {example}")
        values = {}             # ior absent: the model's default
        for key, tree in f.items():
            if key in ("albedo", "reflectance", "density"):
                values[key] = self.volume_channel(tree, f"{key} of the subsurface of {block}")
                continue
            tok = tree.children[0]
            if key == "grid":
                values[key] = self.switch(tok, key)
                continue
            values[key] = self.number(tok)
            problem = (rules.mean_free_path_problem if key == "mean_free_path"
                       else rules.ior_problem)(values[key])
            self.refuse(tok, problem)
        return Subsurface(pos=pos_of(st), **values)

    def volume_channel(self, key: Tree, what: str):
        """The channel after a subsurface's ``albedo``, ``reflectance`` or ``density`` (bare). A
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
            return ColorChannel(self.color(ch.children[0], what), pos=pos_of(ch))
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
            return Mix(a, b, weight, pos=pos_of(st))
        if len(operands) < 2:
            raise self.error(st, f"'{kind}' needs two or more channels, found {len(operands)}")
        channels = tuple(self.channel_of(c, inside, depth + 1) for c in operands)
        self.sized(st, channels)
        return (Add if kind == "add" else Multiply)(channels, pos=pos_of(st))

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
        name, path = self.found_file(tok, "an image", image_file_sentence)
        # Its position is the file string's, where every error about the file points.
        return ImageChannel(name, path, pos=Pos(tok.line, tok.column))

    def marble(self, st: Tree) -> MarbleChannel:
        """``marble { … }``: each key given, read as its kind is written and checked by
        its row of the parameter table; the error is at the value, in the table's words."""
        f = self.fields(st, "'marble' block")
        values = {}
        preset = self.marble_preset(st, f["preset"]) if "preset" in f else None
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
        if preset is not None:          # the preset's values, those written on top
            values = presets.resolved(preset, values)
        return MarbleChannel(**values, transform=steps, space=space, pos=pos_of(st),
                             source=source_of(st, f))

    def marble_preset(self, st: Tree, key: Tree) -> str:
        """``preset "NAME"``: the name of a preset of the library (mimarble/presets.py),
        written first in the marble block; an unknown one is refused at its name, with
        the closest one named."""
        first = next(c for c in st.children if isinstance(c, Tree))
        if first is not key:
            raise self.error(key, "'preset' comes first in a marble block, then the values "
                                  "that override it: marble { preset \"carrara\" period 1.5 }")
        (tok,) = key.children
        name = unquoted(tok)
        try:
            presets.preset(name)
        except presets.PresetError as e:
            raise self.error(tok, str(e)) from None
        return name

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
