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
  sweep --set``: the registry of a scene's keys, keys.py, re-exported here).

Neither Dr.Jit nor Mitsuba is imported, nor NumPy at module level: the command line
edits the scene before they load, so that a mistake is answered at once.
"""

from __future__ import annotations

import dataclasses

from mimarble import scene as scene_language
from mimarble.scene.key_values import KeyPathError
from mimarble.scene.rules import spp_problem

__all__ = ["KeyPathError", "with_value", "with_image_size", "resized", "with_marbles",
           "with_constant_colours", "filling_the_view"]


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
# One value by key path

def with_value(scene, key: str, value):
    """The scene with the value at key path ``key`` set to ``value``: the key registry's
    (mimarble/scene/keys.py, :func:`~mimarble.scene.keys.with_value`), imported when first
    called — the command line imports this module for :func:`with_image_size` before it
    parses, and a file that fails to parse builds no scene model."""
    from mimarble.scene.keys import with_value as registry_with_value
    return registry_with_value(scene, key, value)


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
