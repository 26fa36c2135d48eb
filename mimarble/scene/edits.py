"""Edits of a scene model: a new immutable scene with one thing changed.

The scene model (mimarble/scene/model.py) is frozen dataclasses, so every edit is a
``dataclasses.replace`` down to the field that changes; the rest of the scene is
shared, not copied. The edits here are the ones several parts of mimarble make:

* the image size — the command line's ``--width``/``--height``
  (:func:`with_image_size`) and the gallery's, tests' and benchmark's square
  sizes (:func:`resized`);
* the marbles — every marble changed alike (:func:`with_marbles`: the benchmark's
  filters and octave counts), or replaced by a constant colour
  (:func:`with_constant_colours`: the benchmark's texture-free timing);
* the camera — narrowed until the first sphere fills the frame
  (:func:`filling_the_view`);
* one value named by a key path (:func:`with_value`, the keys of ``mimarble
  sweep --set``):

  - ``marble.K`` — K of every marble; ``MATERIAL.K`` — of the marbles of one
    material; ``MATERIAL.CHANNEL.K`` — of the marbles in one channel (inside
    expressions too). K is a sweepable marble parameter
    (``marble_parameters.SWEEPABLE``), its value checked by the parameter table.
  - ``camera.fov``; ``image.samples``; ``light.N.intensity`` (light N's colour, grey).

Neither Dr.Jit nor Mitsuba is imported, nor NumPy at module level: the command line
edits the scene before they load, so that a mistake is answered at once.
"""

from __future__ import annotations

import dataclasses
import math

from mimarble import parameters as marble_parameters
from mimarble import scene as scene_language
from mimarble.scene.rules import spp_problem

#: The channels of a material, as ``MATERIAL.CHANNEL.K`` names them.
CHANNELS = ("ambient", "diffuse", "specular")


class KeyPathError(ValueError):
    """A key path the scene does not have, or a value it cannot take there. The message
    starts with the key path (``camera.fov: 200.0 must be below 180 degrees``)."""


# ---------------------------------------------------------------------------
# Image size

def with_image_size(scene, width: int | None = None, height: int | None = None,
                    spp: int | None = None):
    """The scene at ``width`` × ``height`` pixels (None: the scene's own). The camera's
    fov is the full vertical angle (docs/scene-language.md), so a new height shows the
    same view at another resolution and a new width crops or extends it sideways.

    ``spp``: the samples per pixel the render will take in place of the image's own
    (``--spp``, ``render(spp=…)``). With a new size it becomes the image's ``samples``, so
    that the sample limit is checked on what will be rendered: 16384² at 1 spp of a
    ``samples 4`` scene is within it. ValueError (the model's sentence) when the size or
    the samples are past it."""
    size = {name: value for name, value in (("width", width), ("height", height))
            if value is not None}
    if not size:
        return scene
    if spp is not None:
        problem = spp_problem(spp, size.get("width", scene.image.width),
                              size.get("height", scene.image.height))
        if problem:
            raise ValueError(problem)
        size["samples"] = spp
    return dataclasses.replace(scene, image=dataclasses.replace(scene.image, **size))


def resized(scene, size: int):
    """The same scene at size×size pixels (the paper's images are square)."""
    return with_image_size(scene, size, size)


# ---------------------------------------------------------------------------
# Marbles

def with_marbles(scene, **changes):
    """The scene with ``changes`` applied to every marble channel of every material
    (inside channel expressions too: ``scene.replace_marbles``)."""
    materials = {}
    for name, material in scene.materials.items():
        channels = {k: scene_language.replace_marbles(c, **changes)
                    for k, c in material.channels().items()}
        materials[name] = dataclasses.replace(material, **channels)
    return dataclasses.replace(scene, materials=scene_language.FrozenMap(materials))


def with_constant_colours(scene):
    """Every marble channel replaced by a constant colour (its ramp keys' mean): the same
    shading work without the texture — for timing only (top-level marbles: the
    benchmark's targets scene, fig11a, has no expressions)."""
    import numpy as np
    materials = {}
    for name, material in scene.materials.items():
        channels = {k: scene_language.ColorChannel(tuple(np.mean(c.ramp, axis=0).tolist()))
                    for k, c in material.channels().items()
                    if isinstance(c, scene_language.MarbleChannel)}
        materials[name] = dataclasses.replace(material, **channels)
    return dataclasses.replace(scene, materials=scene_language.FrozenMap(materials))


# ---------------------------------------------------------------------------
# Camera

def filling_the_view(scene):
    """The camera's fov narrowed until the first sphere just fills the frame: the full
    angle 2·asin(r / d) the sphere of radius r subtends from the eye at distance d."""
    import numpy as np
    sphere = scene.spheres[0]
    distance = float(np.linalg.norm(np.subtract(scene.camera.eye, sphere.center)))
    fov = 2 * np.degrees(np.arcsin(min(sphere.radius / distance, 1.0)))
    return dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, fov=float(fov)))


# ---------------------------------------------------------------------------
# One value by key path

def with_value(scene, key: str, value):
    """The scene with the value at key path ``key`` set to ``value`` (the module
    docstring lists the keys); :class:`KeyPathError` for a key the scene does not have
    or a value it cannot take there — by the key's own rule, or by the scene model's
    (its constructors check every value by the parser's rules: ``image.samples`` within
    the sample limit, a light's intensity within float32's range, a fov that is not 0 in
    single precision), so that a sweep checks every frame's values, before it renders
    any, by calling this (``sweeps.frames``)."""
    try:
        return _with_value(scene, key, value)
    except KeyPathError:
        raise
    except (TypeError, ValueError) as e:       # the model's rule, in the parser's words
        raise KeyPathError(f"{key}: {e}") from None


def _with_value(scene, key: str, value):
    """:func:`with_value`, with the model's own errors left to it to word."""
    parts = key.split(".")
    if parts[0] == "camera" and parts[1:] == ["fov"]:
        fov = _number(key, value, above=0.0)
        if not fov < 180.0:
            raise KeyPathError(f"{key}: fov {value!r} must be below 180 degrees")
        return dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, fov=fov))
    if parts[0] == "image" and parts[1:] == ["samples"]:
        samples = _integer(key, value)
        try:
            scene_language.model.samples_per_axis(samples)
        except ValueError as e:
            raise KeyPathError(f"{key}: {e}") from None
        return dataclasses.replace(scene, image=dataclasses.replace(scene.image, samples=samples))
    if parts[0] == "light" and len(parts) == 3 and parts[2] == "intensity":
        lights = list(scene.lights)
        k = _index(key, parts[1], len(lights), "light")
        grey = _number(key, value, at_least=0.0)
        lights[k] = dataclasses.replace(lights[k], color=(grey, grey, grey))
        return dataclasses.replace(scene, lights=tuple(lights))
    return _with_marble_value(scene, key, parts, value)


def _with_marble_value(scene, key: str, parts: list[str], value):
    """``with_value`` for ``marble.K``, ``MATERIAL.K`` and ``MATERIAL.CHANNEL.K``."""
    name = parts[-1]
    if name not in marble_parameters.SWEEPABLE or len(parts) not in (2, 3):
        raise KeyPathError(f"{key}: unknown key; use marble.K, MATERIAL.K, MATERIAL.CHANNEL.K "
                           f"(K one of {', '.join(marble_parameters.SWEEPABLE)}), camera.fov, "
                           f"image.samples or light.N.intensity")
    try:
        change = {name: marble_parameters.checked(marble_parameters.BY_NAME[name], value, key,
                                                  text=True)}
    except marble_parameters.ParameterError as e:
        raise KeyPathError(str(e)) from None
    materials = dict(scene.materials)
    targets = list(materials) if parts[0] == "marble" and len(parts) == 2 else [parts[0]]
    for material_name in targets:
        if material_name not in materials:
            raise KeyPathError(f"{key}: no material {material_name!r} "
                               f"(materials: {', '.join(materials) or 'none'})")
        material = materials[material_name]
        channels = material.channels()
        if len(parts) == 3:
            if parts[1] not in CHANNELS:
                raise KeyPathError(f"{key}: {parts[1]!r} is not a channel ({', '.join(CHANNELS)})")
            if parts[1] not in channels:
                raise KeyPathError(f"{key}: material {material_name!r} has no {parts[1]}")
            channels = {parts[1]: channels[parts[1]]}
        if parts[0] != "marble" and not _has_marble(channels):
            raise KeyPathError(f"{key}: no marble there to change")
        materials[material_name] = dataclasses.replace(
            material, **{k: scene_language.replace_marbles(c, **change) for k, c in channels.items()})
    if parts[0] == "marble" and not any(_has_marble(m.channels()) for m in materials.values()):
        raise KeyPathError(f"{key}: the scene has no marble to change")
    return dataclasses.replace(scene, materials=scene_language.FrozenMap(materials))


def _has_marble(channels) -> bool:
    """Whether any of ``channels`` (name → channel) holds a marble, inside expressions too."""
    return any(isinstance(c, scene_language.MarbleChannel)
               for ch in channels.values() for c in scene_language.walk(ch))


def _number(key, value, above: float | None = None, at_least: float | None = None) -> float:
    """``value`` as a float: finite, and ``> above`` / ``≥ at_least`` where given."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise KeyPathError(f"{key}: {value!r} is not a finite number")
    if above is not None and not value > above:
        raise KeyPathError(f"{key}: {value!r} must be > {above:g}")
    if at_least is not None and not value >= at_least:
        raise KeyPathError(f"{key}: {value!r} must be ≥ {at_least:g}")
    return float(value)


def _integer(key, value) -> int:
    """``value`` as an int: a finite number with no fractional part."""
    number = _number(key, value)
    if not number.is_integer():
        raise KeyPathError(f"{key}: {value!r} is not an integer")
    return int(number)


def _index(key, text, count, what) -> int:
    """``text`` as an index into ``count`` things called ``what``."""
    if not text.isdigit() or int(text) >= count:
        raise KeyPathError(f"{key}: {what} {text} does not exist (the scene has {count})")
    return int(text)
