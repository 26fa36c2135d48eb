"""The paper's ray tracer rebuilt in float64 NumPy: the project's ground truth.

The rendering contract is docs/rendering-model.md; this module follows it to
the letter (the Mitsuba ``whitted`` integrator follows the same contract).
In short:

* **Camera**: f = normalize(lookat − eye), r = normalize(f × up), u = r × f;
  film position (x, y) ∈ [0, 1]² (x right, y down, (0, 0) the top-left corner)
  gives the direction normalize(f + (2x − 1)·tan(fov/2)·aspect·r + (1 − 2y)·tan(fov/2)·u)
  from the eye; ``fov`` is the full vertical angle, aspect = W/H.
* **Sampling**: n×n samples per pixel (spp = n²) at the stratum centres
  x = (i + (a + ½)/n)/W, y = (j + (b + ½)/n)/H; the pixel is their plain mean.
* **Intersection**: the closest hit over every shape with t > T_MIN_REL·(1 + max_k |o_k|)
  (:data:`T_MIN_REL` = 1e-6); miss → background, or the scene's environment along the
  ray (:mod:`.environment`, Mitsuba's ``envmap`` lookup). Spheres by the numerically stable
  quadratic; planes t = n·(p₀ − o)/(n·d), kept only within the disk
  :func:`mimarble.scene.geometry.plane_disk` (|p − centre| ≤ radius); boxes by the slab
  test in the box's object space (o and d taken there by the inverse of its transform,
  in float64; t is the same parameter in both spaces), the normal of the face hit
  carried back by the inverse transpose and normalised; meshes (their vertices placed in
  the world by the transform, in float64) by the hierarchy of :mod:`.triangles`, the
  normal the world triangle's own (flat shading). Every normal faces the viewer
  (two-sided).
* **Shading** (two-sided normal, all lights, no falloff)::

      L = ka(p)⊙A + Σ_l V(p,l)·I_l⊙(kd(p)·max(0, n·l̂) + ks(p)·max(0, n·ĥ)^shininess)

  with V(p,l) = 1 iff n·l̂ > 0 and no shape meets the open segment from
  p' = p + ε·n, ε = EPS_REL·(1 + max_k |p_k|) (:data:`EPS_REL` = 1e-4), to
  the light (the paper's ``shadowHit``: any hit, early out).
* **Area lights** (:func:`area_samples`, :func:`area_sample_points`): n×n point lights
  of colour I/n², at the stratum centres of the rectangle (position + s·axis1 + t·axis2,
  s, t = (a + ½)/n − ½) or, for a sphere, of the concentric-mapped unit disk of radius R
  facing each shaded point; each is a light of the formula above.

The **hit record** (:class:`HitRecord`) is the paper's "passing back" (§3.1):
the hit routine returns where and what was hit (which shape: its index in
``scene.shapes()`` order), and the record carries the material's channel colours
ka, kd, ks at the hit point back to the shader, each distinct channel evaluated once
per batch and only where its value is used. A channel reads the world point p, a
``space object`` marble the point in the hit shape's object space,
object_to_world(shape)⁻¹·p (:func:`mimarble.scene.geometry.object_to_world`), and an
image map the shape's (u, v): a sphere's (:func:`.channels.sphere_uv`), or a mesh's
vertex texture coordinates interpolated with the hit's barycentrics.

Channels (colours, marbles, image maps and their sums, products and mixes) are
evaluated by :mod:`.channels`; :func:`channel_color` is re-exported here. The tracer is
three modules and this one: :mod:`.preparation` (the scene as arrays, the camera's rays),
:mod:`.intersection` (hits and the hit record), :mod:`.shading` (the formula); here are
:func:`trace` and :func:`render`, and every name of the three is importable from here.

Everything is vectorised over batches of rays; Python loops run over spheres,
planes, boxes, lights, channels and chunks only (the triangles of all meshes are one
hierarchy). Imports NumPy, the standard library, :mod:`mimarble.scene` (the model, its
geometry and mesh files' checks) and this package's own channels, marble, noise, mesh
files and triangles.
"""


from __future__ import annotations

import numpy as np

from mimarble.contract import EPS_REL, T_MIN_REL
from mimarble.scene.model import Scene, samples_per_axis

from .channels import channel_color
from .intersection import (HitRecord, closest_hit, fill_channels, hit, hit_uv, intersect_spheres,
                           object_points, occluded, shadow_hit)
from .preparation import (SLOTS, AreaSamples, MeshArrays, PreparedScene, as_prepared,
                          area_sample_points, area_samples, camera_basis, camera_rays, prepare,
                          read_meshes, sample_positions)
from .shading import shade
from .shapes import BoxArrays, PlaneArrays, intersect_boxes, intersect_planes

__all__ = [
    "T_MIN_REL",
    "EPS_REL",
    "CHUNK_RAYS",
    "SLOTS",
    "PreparedScene",
    "HitRecord",
    "prepare",
    "camera_basis",
    "camera_rays",
    "sample_positions",
    "intersect_spheres",
    "closest_hit",
    "shadow_hit",
    "occluded",
    "read_meshes",
    "area_samples",
    "area_sample_points",
    "hit",
    "channel_color",
    "shade",
    "trace",
    "render",
    # and the rest of the three modules' public names
    "AreaSamples",
    "BoxArrays",
    "MeshArrays",
    "PlaneArrays",
    "fill_channels",
    "hit_uv",
    "intersect_boxes",
    "intersect_planes",
    "object_points",
]

#: Rays traced per batch (rounded down to whole pixels, at least one pixel).
CHUNK_RAYS = 65536


def trace(scene, o, d) -> np.ndarray:
    """Radiance along rays (o (3,) or (N, 3), unit d (N, 3)) -> (N, 3)."""
    prep = as_prepared(scene)
    d = np.asarray(d, dtype=np.float64).reshape(-1, 3)
    return shade(prep, closest_hit(prep, o, d), d)


# ---------------------------------------------------------------------------
# The image

def render(scene: Scene, spp: int | None = None, chunk_rays: int = CHUNK_RAYS,
           progress=None) -> np.ndarray:
    """Render ``scene`` -> float64 (H, W, 3) linear RGB, not clamped.

    ``spp`` (default ``scene.image.samples``) must be a perfect square n²:
    n×n stratum centres per pixel, averaged. Rays are traced in batches of
    about ``chunk_rays`` (whole pixels), so memory stays bounded.
    ``progress``, if given, is called as ``progress(samples_done, samples_total)``
    before the first batch (0 done) and after each one.
    """
    prep = prepare(scene)
    img = scene.image
    n = samples_per_axis(img.samples if spp is None else spp)
    W, H = int(img.width), int(img.height)
    ns = n * n
    pixels_per_chunk = max(1, int(chunk_rays) // ns)
    out = np.empty((H * W, 3), dtype=np.float64)
    if progress is not None:
        progress(0, H * W * ns)
    for p0 in range(0, H * W, pixels_per_chunk):
        p1 = min(H * W, p0 + pixels_per_chunk)
        x, y = sample_positions(W, H, n, p0, p1)
        eye, d = camera_rays(scene, x, y)
        rad = shade(prep, closest_hit(prep, eye, d), d)
        out[p0:p1] = rad.reshape(p1 - p0, ns, 3).mean(axis=1)
        if progress is not None:
            progress(p1 * ns, H * W * ns)
    return out.reshape(H, W, 3)
