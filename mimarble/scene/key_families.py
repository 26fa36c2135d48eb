"""The families of a scene's keys — the marbles (``marble.K``, ``carrara.K``,
``stone.diffuse.K``, their ramps and ramp stops), the camera, the lights, the image, the
environment —
each a :class:`KeyFamily`: the keys a scene has, a new value applied to a scene, and
where the value's text stands in the file it was parsed from (for rewrite.py).

A family is one class here and one entry in ``keys.FAMILIES``; the builder records the
node's :class:`~mimarble.scene.nodes.Source` (``source=``) for its :meth:`KeyFamily.places`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

from mimarble.parameters import (COLOURS, INTEGER, NUMBER, PARAMETERS, SWEEPABLE, Parameter,
                                 positions_problem)
from .channels import EXPRESSIONS, MarbleChannel, Mix, walk
from .key_values import COLOUR, VECTOR, KeyPathError, Value, current_text, vector_text
from .limits import MAX_IMAGE_SAMPLES
from .model import Camera, FrozenMap, Image, Light, samples_per_axis
from .nodes import Source


@dataclasses.dataclass(frozen=True)
class Key:
    """One value a user can tune, by its key path.

    ========== ==============================================================================
    path       ``stone.diffuse.period``, ``carrara.ramp.2``, ``camera.fov``
    group      what it belongs to, as the scene names it: ``every marble``,
               ``texture "carrara"``, ``material "stone"``, ``material "stone", diffuse``,
               ``camera``, ``light 0``, ``image``
    parameter  its row: for a marble's key, the parameter table's (mimarble/parameters.py:
               kind, default, range, choices, doc; ``ramp`` for the ramp and its stops);
               for the others, the row declared here (kind ``vector`` or ``colour``, or
               the table's kinds)
    value      its current value as the model holds it (of the group's first marble);
               a ramp: (colours, positions or None); a stop: (position or None, colour)
    text       the current value in the value syntax (key_values.py)
    stop       N of a ramp stop ``….ramp.N``, else None
    count      how many marbles it sets (1 for other keys)
    ========== ==============================================================================
    """

    path: str
    group: str
    parameter: Parameter
    value: object
    stop: int | None = None
    count: int = 1
    #: The family that knows the key, and what the key names in the scene (its own form).
    family: KeyFamily = dataclasses.field(default=None, compare=False, repr=False)
    target: object = dataclasses.field(default=None, compare=False, repr=False)

    @property
    def text(self) -> str:
        """The current value in the value syntax (key_values.py): what ``--set`` takes."""
        return current_text(self.parameter, self.value, self.stop)


@dataclasses.dataclass(frozen=True)
class Place:
    """Where a key's value stands in the text: the value ``name`` of the block whose
    ``source`` it is (None: the file has no such block; ``statement`` is then the one to
    write, ``camera``, ``image``)."""

    source: Source | None
    name: str
    statement: str = ""
    #: The node the block was read into (a marble: its ramp's old values, kept as written).
    node: object = None


class KeyFamily:
    """A family of keys. Subclasses give :meth:`keys`, :meth:`apply` and :meth:`places`;
    a new family — the environment's ``environment.intensity``, say — is::

        class EnvironmentKeys(KeyFamily):
            ROW = Parameter("intensity", NUMBER, 1.0, at_least=0.0, doc="…")

            def keys(self, scene):
                if scene.environment is not None:
                    yield self._key("environment.intensity", "environment", self.ROW,
                                    scene.environment.intensity)

            def apply(self, scene, key, value):
                return dataclasses.replace(scene, environment=dataclasses.replace(
                    scene.environment, intensity=value.value))

            def places(self, scene, key):
                return [Place(scene.environment.source, "intensity")]

    and one entry in ``keys.FAMILIES``; its builder gives the node
    ``source=source_of(st, f)`` (build_values.py), and its model class a ``source`` field
    (``_source()``, nodes.py), as the camera's."""

    def keys(self, scene) -> Iterator[Key]:
        """Every key of this family that ``scene`` has."""
        raise NotImplementedError

    def apply(self, scene, key: Key, value: Value):
        """``scene`` with ``key`` set to ``value`` (read and checked by its kind)."""
        raise NotImplementedError

    def places(self, scene, key: Key) -> list[Place]:
        """Where the value of ``key`` stands in the text ``scene`` was parsed from."""
        raise NotImplementedError

    def find(self, scene, path: str) -> Key | None:
        """The key ``path`` of ``scene``, or None (:meth:`keys`, searched)."""
        return next((key for key in self.keys(scene) if key.path == path), None)

    def written(self, key: Key, value: Value) -> str:
        """The text a value is written as at its place."""
        return value.text

    def diagnosis(self, scene, path: str) -> str | None:
        """Why ``path``, which no key of the scene has, looks like one of this family's
        that the scene lacks (``light 3 does not exist``), or None."""
        return None

    def summary(self, keys: list[Key]) -> list[str]:
        """The family's keys in short, for the sentence of an unknown key: one entry per
        group, ``prefix.{a|b}``."""
        groups: dict[str, list[str]] = {}
        for key in keys:
            prefix, _, name = key.path.rpartition(".")
            groups.setdefault(prefix, []).append(name)
        return [f"{prefix}.{'|'.join(names)}" for prefix, names in groups.items()]

    def _key(self, path, group, parameter, value, stop=None, count=1, target=None) -> Key:
        return Key(path, group, parameter, value, stop, count, self, target)


# ---------------------------------------------------------------------------
# Marbles

#: Words a key path starts with that are no material's or texture's name: a material or
#: texture of such a name is written ``material.NAME`` / ``texture.NAME``.
RESERVED = ("marble", "camera", "light", "image", "material", "texture", "environment")


def _identity(node):
    """What makes two marble nodes the same marble of the file: their position in it (kept
    through edits), else the object."""
    return ("pos", node.pos) if node.pos is not None else ("id", id(node))


#: The channels a key names, a material's and its subsurface's.
CHANNELS = ("ambient", "diffuse", "specular", "albedo", "reflectance", "density")


def material_channels(material) -> dict:
    """A material's channels that hold values, by the name a key gives them: ambient,
    diffuse, specular, and its subsurface's albedo, reflectance, density."""
    channels = dict(material.channels())
    if material.subsurface is not None:
        channels.update(material.subsurface.channels())
    return channels


def _marbles(roots) -> list:
    """The distinct marbles within ``roots`` (channels), in walk order."""
    seen, out = set(), []
    for root in roots:
        for c in walk(root):
            if isinstance(c, MarbleChannel) and _identity(c) not in seen:
                seen.add(_identity(c))
                out.append(c)
    return out


def _rebuilt(channel, change, memo: dict):
    """``channel`` with ``change`` (marble → marble, or None to keep it) applied to its
    marbles; a channel used twice (a named texture) is rebuilt once (``memo``, by object)."""
    found = memo.get(id(channel))
    if found is not None:
        return found[1]
    out = channel
    if isinstance(channel, MarbleChannel):
        out = change(channel) or channel
    elif isinstance(channel, Mix):
        a, b = _rebuilt(channel.a, change, memo), _rebuilt(channel.b, change, memo)
        w = channel.weight if isinstance(channel.weight, float) else \
            _rebuilt(channel.weight, change, memo)
        if a is not channel.a or b is not channel.b or w is not channel.weight:
            out = dataclasses.replace(channel, a=a, b=b, weight=w)
    elif isinstance(channel, EXPRESSIONS):
        operands = tuple(_rebuilt(c, change, memo) for c in channel.operands)
        if any(x is not y for x, y in zip(operands, channel.operands)):
            out = dataclasses.replace(channel, operands=operands)
    memo[id(channel)] = (channel, out)          # the channel kept alive: its id stays its own
    return out


#: Groups of a kind (textures, materials) named in an unknown key's sentence at most.
SHOWN = 8


class MarbleKeys(KeyFamily):
    """``marble.K`` (every marble, in expressions, named textures and subsurfaces too),
    ``TEXTURE.K`` (a named texture's marbles, wherever it is used), ``MATERIAL.K`` and
    ``MATERIAL.CHANNEL.K`` (a material's marbles, or one channel's: this material's copy
    alone). K is a sweepable row of the parameter table, ``ramp`` (the whole ramp) or
    ``ramp.N`` (its stop N, from 0)."""

    ROWS = tuple(p for p in PARAMETERS if p.name in SWEEPABLE)
    RAMP = next(p for p in PARAMETERS if p.kind == COLOURS)

    def groups(self, scene):
        """(label, key prefix, selection) of each group a key can name."""
        yield "every marble", "marble", ("all",)
        for name in scene.textures:
            prefix = f"texture.{name}" if name in scene.materials or name in RESERVED else name
            yield f'texture "{name}"', prefix, ("texture", name)
        for name, material in scene.materials.items():
            prefix = f"material.{name}" if name in RESERVED else name
            yield f'material "{name}"', prefix, ("material", name)
            for channel in material_channels(material):
                yield f'material "{name}", {channel}', f"{prefix}.{channel}", \
                    ("channel", name, channel)

    def selected(self, scene, selection) -> list:
        """The distinct marbles a selection names."""
        kind = selection[0]
        if kind == "all":
            roots = [c for m in scene.materials.values() for c in material_channels(m).values()]
            roots += list(scene.textures.values())
        elif kind == "texture":
            roots = [scene.textures[selection[1]]]
        elif kind == "material":
            roots = list(material_channels(scene.materials[selection[1]]).values())
        else:
            roots = [material_channels(scene.materials[selection[1]])[selection[2]]]
        return _marbles(roots)

    def keys(self, scene):
        for group, prefix, selection in self.groups(scene):
            yield from self.group_keys(scene, group, prefix, selection)

    def find(self, scene, path):
        # Only the groups whose prefix the path starts with are listed (a sweep's frames
        # each look up their keys: 10 000 frames).
        for group, prefix, selection in self.groups(scene):
            if path.startswith(prefix + "."):
                for key in self.group_keys(scene, group, prefix, selection):
                    if key.path == path:
                        return key
        return None

    def group_keys(self, scene, group, prefix, selection):
        """The keys of one group (none when it holds no marble)."""
        marbles = self.selected(scene, selection)
        if not marbles:
            return
        first, count = marbles[0], len(marbles)
        for p in self.ROWS:
            yield self._key(f"{prefix}.{p.name}", group, p, getattr(first, p.name),
                            count=count, target=selection)
        yield self._key(f"{prefix}.ramp", group, self.RAMP,
                        (first.ramp, first.ramp_positions), count=count, target=selection)
        for n in range(min(len(m.ramp) for m in marbles)):
            position = None if first.ramp_positions is None else first.ramp_positions[n]
            yield self._key(f"{prefix}.ramp.{n}", group, self.RAMP,
                            (position, first.ramp[n]), stop=n, count=count,
                            target=selection)

    def change(self, key: Key, value: Value):
        """The marble → marble change of ``key`` set to ``value``."""
        name = key.parameter.name
        if name != "ramp":
            return lambda m: dataclasses.replace(m, **{name: value.value})
        if key.stop is None:
            colours, positions = value.value
            return lambda m: dataclasses.replace(m, ramp=colours, ramp_positions=positions)
        n, (position, rgb) = key.stop, value.value

        def stop(m):
            count = len(m.ramp)
            if n >= count:
                raise KeyPathError(f"{key.path}: a ramp there has {count} colours (stops "
                                   f"0..{count - 1})")
            colours = m.ramp[:n] + (rgb,) + m.ramp[n + 1:]
            positions = m.ramp_positions
            if position is not None:
                positions = list(positions if positions is not None else evenly_spaced(count))
                positions[n] = position
                problem = positions_problem(tuple(positions), key.path)
                if problem:
                    raise KeyPathError(f"{key.path}: {problem[1]}")
                positions = tuple(positions)
            return dataclasses.replace(m, ramp=colours, ramp_positions=positions)
        return stop

    def apply(self, scene, key: Key, value: Value):
        change, selection = self.change(key, value), key.target
        memo: dict = {}
        if selection[0] in ("all", "texture"):
            chosen = None if selection[0] == "all" else \
                {_identity(m) for m in self.selected(scene, selection)}
            names = list(scene.materials)

            def each(m):
                return change(m) if chosen is None or _identity(m) in chosen else None
            textures = FrozenMap((name, _rebuilt(c, each, memo))
                                 for name, c in scene.textures.items())
        else:                                   # this material's copy alone
            names, each, textures = [selection[1]], change, scene.textures
        materials = dict(scene.materials)
        for name in names:
            material = materials[name]
            wanted = selection[2] if selection[0] == "channel" else None
            own = {k: _rebuilt(c, each, memo) for k, c in material.channels().items()
                   if wanted in (None, k)}
            if material.subsurface is not None:
                inside = {k: _rebuilt(c, each, memo)
                          for k, c in material.subsurface.channels().items()
                          if wanted in (None, k)}
                own["subsurface"] = dataclasses.replace(material.subsurface, **inside)
            materials[name] = dataclasses.replace(material, **own)
        return dataclasses.replace(scene, materials=FrozenMap(materials), textures=textures)

    def places(self, scene, key: Key) -> list[Place]:
        seen, places = set(), []
        for m in self.selected(scene, key.target):
            if m.source is None:
                raise KeyPathError(f"{key.path}: a marble there was not read from text")
            if m.source.block not in seen:
                seen.add(m.source.block)
                places.append(Place(m.source, key.parameter.name, node=m))
        return places

    def diagnosis(self, scene, path: str) -> str | None:
        parts = path.split(".")
        if len(parts) not in (2, 3) or parts[0] in RESERVED:
            return None
        name = parts[0]
        if name not in scene.materials and name not in scene.textures:
            return (f"no material or texture {name!r} (materials: "
                    f"{', '.join(scene.materials) or 'none'}; textures: "
                    f"{', '.join(scene.textures) or 'none'})")
        if len(parts) == 3 and name in scene.materials:
            if parts[1] not in CHANNELS:
                return f"{parts[1]!r} is not a channel ({', '.join(CHANNELS)})"
            if parts[1] not in material_channels(scene.materials[name]):
                return f"material {name!r} has no {parts[1]}"
        return None

    def summary(self, keys: list[Key]) -> list[str]:
        prefixes: dict[str, list[str]] = {}
        for key in keys:
            if key.parameter.name == "ramp" and key.stop is None:
                prefix = key.path.removesuffix(".ramp")
                kind = key.group.split(" ", 1)[0] if key.group != "every marble" else ""
                prefixes.setdefault(kind, []).append(f"{prefix}.K")
        rows = ", ".join(p.name for p in self.ROWS)
        return [(f"{kind} " if kind else "") + ", ".join(names[:SHOWN]) +
                (f" and {len(names) - SHOWN} more" if len(names) > SHOWN else "")
                for kind, names in prefixes.items()] + \
            [f"K: {rows}, ramp (whole) or ramp.N (stop N)"] * bool(prefixes)


def evenly_spaced(count: int) -> tuple:
    """The positions of a ramp without its own: k/(K−1) (one colour: 0)."""
    return tuple(k / (count - 1) for k in range(count)) if count > 1 else (0.0,)


# ---------------------------------------------------------------------------
# The camera, the lights, the image

_CAMERA, _LIGHT, _IMAGE = Camera(), Light((0.0, 0.0, 0.0)), Image()


@dataclasses.dataclass(frozen=True)
class KeyRow(Parameter):
    """A row for a key that is no marble parameter: the table's fields, and the kinds
    ``vector`` and ``colour`` said in words too."""

    @property
    def requirement(self) -> str:
        if self.kind == VECTOR:
            return "must be three finite numbers 'x y z'"
        if self.kind == COLOUR:
            return "must be a colour '#rrggbb' or 'r g b', each component ≥ 0"
        return super().requirement


#: The rows of the keys that are no marble's: declared here, once.
FOV = KeyRow("fov", NUMBER, _CAMERA.fov, above=0.0, below=180.0,
             doc="The camera's full vertical field of view, in degrees.")
EYE = KeyRow("eye", VECTOR, _CAMERA.eye, doc="Where the camera is.")
LOOKAT = KeyRow("lookat", VECTOR, _CAMERA.lookat, doc="The point seen at the image's centre.")
UP = KeyRow("up", VECTOR, _CAMERA.up, doc="The camera's up direction, not along the view.")
INTENSITY = KeyRow("intensity", NUMBER, 1.0, at_least=0.0,
                   doc="A light's colour as one grey level (r = g = b).")
COLOR = KeyRow("color", COLOUR, _LIGHT.color, doc="A light's colour, linear RGB (or #rrggbb).")
POSITION = KeyRow("position", VECTOR, None, doc="Where a light is (an area light's centre).")
SAMPLES = KeyRow("samples", INTEGER, _IMAGE.samples, bounds=(1, MAX_IMAGE_SAMPLES),
                 doc="Samples per pixel, a square n·n (whitted mode's n×n grid).")


class CameraKeys(KeyFamily):
    """``camera.fov``, ``camera.eye``, ``camera.lookat``, ``camera.up``."""

    ROWS = (FOV, EYE, LOOKAT, UP)

    def keys(self, scene):
        for p in self.ROWS:
            yield self._key(f"camera.{p.name}", "camera", p, getattr(scene.camera, p.name))

    def apply(self, scene, key, value):
        return dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, **{
            key.parameter.name: value.value}))

    def places(self, scene, key):
        return [Place(scene.camera.source, key.parameter.name, "camera")]


class LightKeys(KeyFamily):
    """``light.N.intensity`` (its colour as one grey; its value: the colour's mean),
    ``light.N.color``, ``light.N.position``: light N of the file, from 0."""

    ROWS = (INTENSITY, COLOR, POSITION)

    def keys(self, scene):
        for n, light in enumerate(scene.lights):
            for p in self.ROWS:
                value = sum(light.color) / 3 if p is INTENSITY else getattr(light, p.name)
                yield self._key(f"light.{n}.{p.name}", f"light {n}", p, value, target=n)

    def apply(self, scene, key, value):
        lights = list(scene.lights)
        name = key.parameter.name
        held = (value.value,) * 3 if name == "intensity" else value.value
        lights[key.target] = dataclasses.replace(lights[key.target], **{
            "color" if name == "intensity" else name: held})
        return dataclasses.replace(scene, lights=tuple(lights))

    def places(self, scene, key):
        name = "color" if key.parameter.name == "intensity" else key.parameter.name
        return [Place(scene.lights[key.target].source, name)]

    def written(self, key, value):
        return vector_text((value.value,) * 3) if key.parameter is INTENSITY else value.text

    def diagnosis(self, scene, path):
        parts = path.split(".")
        if len(parts) == 3 and parts[0] == "light" and parts[1].isdigit() \
                and int(parts[1]) >= len(scene.lights):
            return f"light {parts[1]} does not exist (the scene has {len(scene.lights)})"
        return None

    def summary(self, keys):
        count = len({k.target for k in keys})
        names = "|".join(p.name for p in self.ROWS)
        return [f"light.N.{names} (N 0..{count - 1})"] if count else []


class ImageKeys(KeyFamily):
    """``image.samples``: a square n·n (whitted mode's n×n grid)."""

    def keys(self, scene):
        yield self._key("image.samples", "image", SAMPLES, scene.image.samples)

    def apply(self, scene, key, value):
        try:
            samples_per_axis(value.value)
        except ValueError as e:
            raise KeyPathError(f"{key.path}: {e}") from None
        image = dataclasses.replace(scene.image, samples=value.value)
        return dataclasses.replace(scene, image=image)

    def places(self, scene, key):
        return [Place(scene.image.source, "samples", "image")]


# ---------------------------------------------------------------------------
# The environment

ENVIRONMENT_INTENSITY = KeyRow("intensity", NUMBER, 1.0, at_least=0.0,
                               doc="The environment's radiance, scaled (path mode's sky, "
                                   "whitted mode's background).")
ROTATE = KeyRow("rotate", VECTOR, (0.0, 0.0, 0.0),
                doc="The environment image turned: degrees about x, then y, then z.")


class EnvironmentKeys(KeyFamily):
    """``environment.intensity``, and an image's ``environment.rotate`` (a colour is the
    same in every direction: it has no rotation)."""

    def keys(self, scene):
        environment = scene.environment
        if environment is None:
            return
        yield self._key("environment.intensity", "environment", ENVIRONMENT_INTENSITY,
                        environment.intensity)
        if environment.file is not None:
            yield self._key("environment.rotate", "environment", ROTATE, environment.rotate)

    def apply(self, scene, key, value):
        return dataclasses.replace(scene, environment=dataclasses.replace(scene.environment, **{
            key.parameter.name: value.value}))

    def places(self, scene, key):
        return [Place(scene.environment.source, key.parameter.name, "environment")]

    def diagnosis(self, scene, path):
        if not path.startswith("environment."):
            return None
        if scene.environment is None:
            return "the scene has no environment"
        if path == "environment.rotate" and scene.environment.file is None:
            return "a colour environment is the same in every direction: it has no rotate"
        return None
