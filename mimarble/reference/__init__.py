"""The reference tracer: the paper's ray tracer rebuilt in float64 NumPy.

The project's ground truth for the Mitsuba path. It shares nothing with it but
the parsed scene model (:mod:`mimarble.scene`, with its geometry and its checks of mesh
files): its own Perlin noise (Shirley's sum-of-ω form, :mod:`.noise`), its own marble
(:mod:`.marble`), its own camera, intersection of spheres, planes and boxes, ``shadowHit``
and shading (:mod:`.tracer`), its own mesh file reader (:mod:`.mesh_file`) and triangle
hierarchy (:mod:`.triangles`), its own
random walk through translucent spheres for path mode's ``subsurface`` (:mod:`.volume`), its own
channel expressions, sphere (u, v) and image maps (:mod:`.channels`, :mod:`.image_map`:
Pillow decodes, the sRGB curve and bilinear lookup are here). Its modules import only
NumPy, Pillow, the standard library, ``mimarble.scene`` and ``mimarble.runtime.progress``
(which loads tqdm only when a bar is asked for).

    >>> from mimarble import scene, reference
    >>> img = reference.render(scene.load("scenes/fig11a.scene"), spp=1)   # (500, 500, 3) float64

The rendering contract both renderers follow is docs/rendering-model.md.
"""

from __future__ import annotations

import os

from mimarble.runtime.progress import report   # NumPy-free, Mitsuba-free: tqdm only when asked
from mimarble.scene.python_numbers import plain_number
from mimarble.scene import Scene, SceneError, load
from mimarble.scene.image_header import check_image_maps
from mimarble.scene.rules import spp_problem

from mimarble.reference import image_map, marble, noise, tracer, triangles
from mimarble.meshes import arrays as mesh_file
from .marble import marble_color, ramp, stripe
from mimarble.meshes.arrays import MeshData, read_mesh
from .noise import fractal, fractal3, noise3
from .tracer import (
    EPS_REL,
    T_MIN_REL,
    HitRecord,
    camera_rays,
    closest_hit,
    hit,
    occluded,
    prepare,
    sample_positions,
    shade,
    shadow_hit,
    trace,
)
from .triangles import TriangleBVH
from . import volume
from .volume import render_translucent
from .tracer import render as _render

__all__ = [
    "render",
    "render_translucent",
    "volume",
    "noise",
    "marble",
    "tracer",
    "mesh_file",
    "triangles",
    "read_mesh",
    "MeshData",
    "TriangleBVH",
    "occluded",
    "noise3",
    "fractal",
    "fractal3",
    "stripe",
    "ramp",
    "marble_color",
    "prepare",
    "camera_rays",
    "sample_positions",
    "closest_hit",
    "hit",
    "shadow_hit",
    "shade",
    "trace",
    "HitRecord",
    "T_MIN_REL",
    "EPS_REL",
]


def render(scene: Scene | str | os.PathLike, spp: int | None = None, progress=False):
    """Render a scene (model, or path to a scene file) -> float64 (H, W, 3), linear.

    ``spp=None`` uses ``scene.image.samples``; spp must be a perfect square n².
    ``progress``: False or None for none; True for a tqdm bar on stderr, shown
    once the render has taken :data:`mimarble.runtime.progress.DELAY_S` and only when stderr is a
    terminal; or a callable ``progress(samples_done, samples_total)``, called
    before the first batch of rays and after each one. A NumPy scalar ``spp`` is the
    Python number it holds (mimarble/scene/python_numbers.py).
    """
    spp = plain_number(spp)
    if isinstance(scene, (str, os.PathLike)):
        scene = load(scene)
    elif not isinstance(scene, Scene):
        raise TypeError(f"reference.render: {scene!r:.80} is not a scene: give a scene "
                        f"file's path or a mimarble.scene.Scene")
    spp = scene.image.samples if spp is None else spp
    problem = spp_problem(spp, scene.image.width, scene.image.height)
    if problem:
        raise ValueError(f"reference.render: {problem}")
    # Headers first, in the parser's words (a scene built in Python was not parsed):
    # nothing is decoded from a file the parser would refuse.
    check_image_maps(scene)
    for channel in scene.image_maps():      # decoded now: a bad file is a SceneError at it
        try:
            image_map.load_image(channel.location)
        except ValueError as e:   # "image file '/abs/path': reason" → at the file string
            reason = str(e).split("': ", 1)[-1]
            raise SceneError.undecodable_image(scene, channel, reason) from None
    return _render(scene, spp=spp, progress=report(progress, "reference"))
