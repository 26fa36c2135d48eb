"""The fast preview of translucent spheres in float64: the reference for preview mode
(Mitsuba's ``path`` + ``subsurface_preview``), independent of Mitsuba.

The model (docs/rendering-model.md, "The fast preview"): a translucent material is a
surface, the random walk's local limit. At a point p of a sphere, η its ``ior``, F(μ) the
exact Fresnel reflectance for light from outside (:func:`.volume.fresnel_dielectric`),
F̄ = ∫₀¹ F(μ) 2μ dμ (:func:`.subsurface_reflectance.diffuse_fresnel_reflectance`), μᵢ the
cosine of the arriving direction:

* with probability F(μᵢ) the mirror direction, weight 1 (the polished coat);
* else a diffuse reflection of value f = (1 − F(μᵢ))·A(p)·(1 − F(μₒ))/((1 − F̄)π), drawn
  cosine-distributed about the normal, so its weight over the branch's probability is
  A(p)·(1 − F(μₒ))/(1 − F̄);
* A(p) per component: from a ``reflectance`` C, clamp((C − F̄)/(1 − F̄), 0, 1); from an
  ``albedo`` α, van de Hulst's fit (:func:`.subsurface_reflectance.spherical_albedo`),
  both of the channel at p (a ``space object`` channel at p in the sphere's object space).

**Light**: as :mod:`.volume`'s walk (its scene rules and lights are the same code): the
ambient or the environment met by a path that leaves the scene (camera rays see the
environment, never the ambient), area lights met after a mirror reflection, and — at
each diffuse vertex — **next-event estimation** of every point and area light by a shadow
ray (:func:`.volume_lights.exit_lighting` with the lobe A·(1 − F(μₗ))·μₗ/((1 − F̄)π), the
diffuse branch's f over its probability 1 − F(μᵢ)); an area light that the path leaving a
diffuse vertex then meets counts nothing (it was estimated). Mitsuba's ``path`` instead
combines light sampling and BSDF sampling by MIS: the same expectation.

**Depth** as Mitsuba's ``path`` counts it (default ``contract.PREVIEW_MAX_DEPTH``, preview
mode's: direct light only): the k-th surface vertex estimates the lights and continues
only if k < ``max_depth``, so light reaches the camera over at most ``max_depth``
segments. No Russian roulette (``path``'s starts at depth 5, past path mode's 4).

Scenes: those :func:`.volume.render_translucent` renders (translucent spheres, pairwise
disjoint, the eye outside), refused in the same sentences. Vectorised over the live paths
of a batch, one vertex per step; seeded by ``np.random.default_rng(seed)``.
"""

from __future__ import annotations

import math

import numpy as np

from mimarble.contract import PREVIEW_MAX_DEPTH, T_MIN_REL

from .channels import channel_color
from .intersection import sphere_roots
from .subsurface_reflectance import (diffuse_fresnel_reflectance, spherical_albedo,
                                     spherical_albedo_seen)
from .volume import (CHUNK_PATHS, checked_walk_arguments, cosine_about, exit_lobe, sky_radiance,
                     fresnel_dielectric, nearer_lights, pixel_means)
from .volume_lights import exit_lighting
from .volume_scene import WalkLights, WalkSpheres

__all__ = ["render_preview"]


def render_preview(scene, spp: int, seed: int = 0, *, max_depth: int = PREVIEW_MAX_DEPTH,
                   chunk_paths: int = CHUNK_PATHS, variance: bool = False):
    """Preview mode's image of a scene of translucent spheres (module docstring) -> float64
    (H, W, 3), linear, each pixel the mean of ``spp`` paths at uniform random positions in
    it. ``max_depth`` ≥ 1 as Mitsuba's ``path``; with ``variance=True`` returns
    ``(image, sample_variance)``, each pixel's unbiased variance of one sample."""
    checked_walk_arguments(scene, spp, max_depth, None, chunk_paths)
    spheres = WalkSpheres(scene)
    lights = WalkLights(scene)
    sky = sky_radiance(scene)
    rng = np.random.default_rng(seed)
    return pixel_means(scene, int(spp), rng, chunk_paths, variance,
                       lambda o, d: _paths(spheres, lights, sky, o, d, rng, int(max_depth)))


def _returned(spheres, s: int, p: np.ndarray) -> np.ndarray:
    """A (k, 3) of sphere s's subsurface at its surface points p (k, 3) (module docstring)."""
    obj = None
    if spheres.object_space[s]:
        m = spheres.from_world[s]
        obj = p @ m[:, :3].T + m[:, 3]
    if spheres.reflectance[s] is not None:
        colour = channel_color(spheres.reflectance[s], p, object_points=obj)
        return spherical_albedo_seen(colour, spheres.fresnel_mean[s])
    return spherical_albedo(channel_color(spheres.albedo[s], p, object_points=obj))


def _paths(spheres, lights, sky, o, d, rng, max_depth):
    """Every path's radiance (n, 3) along the camera rays (o, d)."""
    n = len(d)
    value = np.zeros((n, 3))
    beta = np.ones((n, 3))
    depth = np.zeros(n, dtype=np.int64)          # surface vertices so far
    left = np.full(n, -1, dtype=np.int64)        # the sphere of the last vertex
    diffuse = np.zeros(n, dtype=bool)            # the last vertex was the diffuse lobe
    mean = np.array([diffuse_fresnel_reflectance(e) for e in spheres.ior])
    exit_scale = 1.0 / (1.0 - mean)
    sampled_lights = bool(lights.points or lights.spheres or lights.rectangles)

    def lobe(cos_l, k):
        return exit_lobe(cos_l, spheres.ior[k], exit_scale[k])

    live = np.arange(n)
    while live.size:
        oo, dd = o[live], d[live]
        best = np.full(live.size, np.inf)
        which = np.full(live.size, -1, dtype=np.int64)        # sphere, -1 escape, -2 light
        scale = T_MIN_REL * (1.0 + np.max(np.abs(oo), axis=1))
        for s in range(len(spheres.radii)):
            tn, _ = sphere_roots(oo, dd, spheres.centers[s], spheres.radii[s])
            t = np.where((tn > scale) & (left[live] != s), tn, np.inf)        # NaN: a miss
            closer = t < best
            best, which = np.where(closer, t, best), np.where(closer, s, which)
        camera = depth[live] == 0
        best, which, emitted = nearer_lights(lights, oo, dd, scale, camera, best, which)
        escape = which == -1
        if callable(sky):
            value[live[escape]] += beta[live[escape]] * sky(dd[escape])
        else:
            value[live[escape]] += np.where(camera[escape, None], 0.0, beta[live[escape]] * sky)
        counted = (which == -2) & ~diffuse[live]
        value[live[counted]] += beta[live[counted]] * emitted[counted]

        hit = np.flatnonzero(which >= 0)
        j, s = live[hit], which[hit]
        depth[j] += 1
        go_on = depth[j] < max_depth              # else the vertex ends the path, unlit
        j, s, hit = j[go_on], s[go_on], hit[go_on]
        p = oo[hit] + best[hit, None] * dd[hit]
        normal = p - spheres.centers[s]
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        p = spheres.centers[s] + spheres.radii[s, None] * normal          # on the surface
        cos_i = np.clip(-np.einsum("ij,ij->i", dd[hit], normal), 0.0, 1.0)
        f_i, _ = fresnel_dielectric(cos_i, spheres.ior[s])
        mirror = rng.random(j.size) < f_i
        lobe_dir = cosine_about(rng, normal)
        albedo = np.zeros((j.size, 3))
        for k in np.unique(s):
            here = np.flatnonzero(s == k)
            albedo[here] = _returned(spheres, int(k), p[here])
        lit = ~mirror
        if sampled_lights and lit.any():
            value[j[lit]] += beta[j[lit]] * albedo[lit] * exit_lighting(
                spheres, lights, p[lit], normal[lit], s[lit], lobe, rng)
        f_o, _ = fresnel_dielectric(np.einsum("ij,ij->i", lobe_dir, normal), spheres.ior[s])
        beta[j] *= np.where(mirror[:, None], 1.0,
                            albedo * ((1.0 - f_o) * exit_scale[s])[:, None])
        new = np.where(mirror[:, None], dd[hit] + 2.0 * cos_i[:, None] * normal, lobe_dir)
        o[j] = p
        d[j] = new / np.linalg.norm(new, axis=1, keepdims=True)
        left[j] = s
        diffuse[j] = lit
        live = j[np.any(beta[j] > 0.0, axis=1)]
    return value
