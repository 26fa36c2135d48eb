"""A float64 random walk through translucent spheres: the reference for path mode's
``subsurface`` (Mitsuba's ``volpath`` + ``subsurface_boundary`` + a medium), independent of Mitsuba.

It renders the scene model in **path mode** (docs/rendering-model.md, "Path mode"),
restricted to what translucent scenes need:

* **Shapes**: spheres whose material has a ``subsurface`` (:class:`mimarble.scene.Subsurface`),
  pairwise disjoint, the eye outside them all; anything else is refused (ValueError).
* **Boundary** (docs/rendering-model.md, "Translucent materials"): η = ``ior`` (inside over
  outside); F(μ) the exact unpolarised Fresnel reflectance for light from outside at
  cosine μ, F = (r_s² + r_p²)/2, r_s = (μ − η μₜ)/(μ + η μₜ), r_p = (η μ − μₜ)/(η μ + μₜ),
  μₜ = √(1 − (1 − μ²)/η²) (:func:`fresnel_dielectric`); F̄ = ∫₀¹ F(μ) 2μ dμ
  (:func:`~mimarble.reference.subsurface_reflectance.diffuse_fresnel_reflectance`). A path
  meeting a sphere from outside reflects in the mirror direction with probability F(μᵢ), else enters in a direction
  cosine-distributed about the inward normal; both keep the weight. A walk meeting it from
  inside always leaves, cosine-distributed about the outward normal, its weight times
  W(μₒ) = (1 − F(μₒ))/(1 − F̄) (mean 1 over the cosine distribution). No refraction, no
  internal reflection; the radiance scale 1/η² of a crossing is left out, as the walk's
  entries and exits pair up.
* **Inside**: σ_t(p) = d(p)/``mean_free_path`` (d the density channel's mean of its three
  components, at least 0; 1 without a density channel), albedo α(p) the albedo channel's
  RGB clamped to [0, 1], isotropic phase function. Sampled by **delta tracking** with the
  majorant σ̄ = bound(d)/``mean_free_path``, bound(d) an upper bound of the density
  computed here by interval arithmetic on the channel (:func:`~.volume_scene.channel_interval`: a colour
  is its value, a marble lies between its ramp colours' smallest and largest component,
  sums, products and mixes combine the intervals): a tentative collision at distance
  −ln(1 − u)/σ̄ is real with probability σ_t(p)/σ̄ (then the weight is multiplied by α(p)
  and the direction drawn uniformly on the sphere), else null (the path goes on, weight
  unchanged). Channels are evaluated by :func:`mimarble.reference.channels.channel_color`
  at the world point, a ``space object`` marble at the point in the sphere's object space
  (``geometry.object_to_world(sphere)⁻¹·p``). (Image maps have no value off a surface:
  the model refuses them in a subsurface.)
* **Light**: the global ambient A as a constant environment of radiance A (seen by every
  ray that leaves the scene, except camera rays: ``hide_emitters``) — or the scene's
  ``environment`` in its place (path mode's sky: :mod:`.environment`'s lookup along the
  ray, seen by camera rays too, as Mitsuba's integrator then hides no emitter; a scene
  with an environment and area lights is refused, since its camera rays would see the
  lights); spherical and
  rectangular area lights as emitting shapes (black, they end the path) of the radiance
  that path mode gives them (:func:`~.volume_scene.area_radiance`, the rule of
  ``mimarble.mitsuba.translate.lights.area_light_dict`` re-derived from the model): a sphere of
  radius R emits L = I·d²/R² (d the distance from its centre to the camera's look-at
  point), so that its radiant intensity π·R²·L is the path-mode point light's I·π·d²; a
  rectangle of area S emits L = I·π·d²/(S·cos θ₀) on the side facing the look-at point
  only (θ₀ the look-at point's angle from its normal; cos θ₀ = 1 where that is ≤ 0).
  Camera rays pass through area lights (``hide_emitters`` skips them, as Mitsuba's
  ``skip_area_emitters``); later rays that meet one add its radiance on its emitting side
  and end. **Next-event estimation at exits** (:mod:`.volume_lights`): where a walk leaves
  a sphere, each point light (intensity I·π·d², :func:`point_intensity`, the rule of
  ``point_light_dict``) and each area light (one sampled direction or point) is reached
  by a shadow ray, weighed by the exit lobe f = (1 − F(cos θ_l))/((1 − F̄)π) times
  cos θ_l; a shadow ray stops at another sphere or any area light's shape. An area light
  that the path leaving an exit then meets counts nothing (it was estimated; it still
  ends the path); the sky is still reached by meeting it. volpath does the same next-event
  estimation, combining it with the paths that meet area lights and the sky by MIS: the
  same expectation. A point light inside a sphere is refused.
* **Path depth**, ``max_depth`` in the meaning of Mitsuba's ``volpath``: every
  non-null event is one vertex — a reflection, an entry or an exit at a boundary, a real
  collision in a medium (a null collision is none) — and a path with k vertices adds its
  light (the environment it escapes to, the area light it meets, the lights estimated
  at the exit that is its k-th vertex) iff k < ``max_depth``;
  a path whose real event brings it to k = ``max_depth`` ends there. So 1 renders only
  what the camera sees directly (nothing: emitters are hidden), 2 the mirror reflection
  of the environment, 3 also light straight through a sphere (in, out), 4 single
  scattering; −1 no limit. In volpath.cpp: the loop runs while depth < max_depth, a
  real medium collision increments depth (and its lighting is skipped once depth reaches
  max_depth), a non-null BSDF sample increments it, and an emitter met on a surface is
  counted at the depth the path has then.
* :data:`MAX_DEPTH` = ``contract.VOLPATH_MAX_DEPTH`` is this module's default, path
  mode's ``volpath``'s too. A marble's albedo is high (0.99–0.999) and its mean free path
  short beside the object, so light leaves after hundreds of collisions: a low cap loses
  light, the more the whiter the marble, while the tests' spheres (mean free path
  0.25–0.3, albedo ≤ 0.97) lose nothing at 64. The cost grows with the cap only where
  light does travel that far. The light kept and the time at each cap:
  docs/benchmarks.md, "Walk length and sampler against Cycles".
* **Russian roulette** (unbiased): after a real event that leaves a path at depth
  k > ``rr_depth`` (default ``contract.ROULETTE_DEPTH`` = 5, Mitsuba's ``rr_depth``), the path
  survives with probability q = min(max_c β_c, q_max) (β its RGB weight) and its weight
  becomes β/q. With a finite ``max_depth`` q_max = 1: a roulette never lifts a weight's
  largest component above 1 (the exits' W ≤ 1/(1 − F̄) aside), so the variance stays
  bounded. With
  ``max_depth`` −1, q_max = ``contract.ROULETTE_MAX`` = 0.95 (Mitsuba's), which ends every path
  with probability 1 (in a part of a sphere of density 0 too) at the price of weights
  (α/0.95)^k that grow where the albedo α exceeds 0.95: in an optically thick, nearly
  white medium their variance is so large that an image converges very slowly. Mitsuba's
  volpath has that roulette at any ``max_depth`` (q = min(max β·η², 0.95); η = 1 with
  ``subsurface_boundary``), which is why path mode turns it off where an albedo may
  pass 0.95 (``contract.VOLPATH_RR_DEPTH`` = max_depth; measured in docs/benchmarks.md,
  "Russian roulette on white marble"). ``rr_depth=None`` turns this walk's roulette off (then
  ``max_depth`` must be finite).
* **Pixels**: ``spp`` samples per pixel at uniform random positions in the pixel
  (Mitsuba's ``independent`` sampler with a ``box`` filter), the pixel their plain mean.
  The camera is the model's pinhole (:func:`mimarble.reference.tracer.camera_rays`).

Vectorised: the paths of a batch (about :data:`CHUNK_PATHS`, whole pixels) advance
together, one event each per step (live paths only); Python loops run over steps,
spheres and lights. Seeded: ``np.random.default_rng(seed)``, batches in order, so one seed
gives one image. Imports NumPy, the standard library, :mod:`mimarble.scene` and this
package's channels, tracer (the camera, the roots of a ray and a sphere) and
:mod:`.volume_lights`.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from mimarble.scene.model import Scene
from mimarble.scene.rules import spp_problem

from mimarble.contract import ROULETTE_DEPTH, ROULETTE_MAX, T_MIN_REL, VOLPATH_MAX_DEPTH

from .intersection import sphere_roots    # both roots, the stable quadratic
from .environment import EnvironmentLookup
from .preparation import camera_rays
from .subsurface_reflectance import diffuse_fresnel_reflectance
from .volume_lights import orthonormal_basis, exit_lighting
from .volume_scene import WalkLights, WalkSpheres, walk_problem

__all__ = [
    "MAX_DEPTH",
    "CHUNK_PATHS",
    "render_translucent",
    "fresnel_dielectric",
    "checked_walk_arguments",
    "sky_radiance",
    "exit_lobe",
    "cosine_about",
]

#: Mitsuba volpath's ``max_depth`` for path mode, and this walk's default (module docstring).
MAX_DEPTH = VOLPATH_MAX_DEPTH
#: Paths traced per batch (whole pixels, at least one pixel).
CHUNK_PATHS = 1 << 17


# ---------------------------------------------------------------------------
# Optics

def fresnel_dielectric(cos_i, eta):
    """(F, cos θₜ) of a smooth dielectric, unpolarised, for cos θᵢ ∈ [0, 1] (arrays) and
    η = n_beyond/n_before (array or scalar). Past the critical angle F = 1, cos θₜ = 0."""
    cos_i = np.clip(np.asarray(cos_i, dtype=np.float64), 0.0, 1.0)
    eta = np.asarray(eta, dtype=np.float64)
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    total = sin2_t >= 1.0
    cos_t = np.sqrt(np.maximum(1.0 - sin2_t, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
        rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
        f = 0.5 * (rs * rs + rp * rp)
    # 0/0 only at grazing incidence with cos θₜ = 0 too: everything is reflected.
    f = np.where(total | ~np.isfinite(f), 1.0, f)
    return f, np.where(total, 0.0, cos_t)


def exit_lobe(cos_l, eta, exit_scale):
    """The exit lobe's f·cos θ_l = (1 − F(cos θ_l))/((1 − F̄)π)·cos θ_l, 0 where cos θ_l ≤ 0
    (``exit_scale`` = 1/(1 − F̄))."""
    cos_l = np.clip(cos_l, 0.0, 1.0)
    return (1.0 - fresnel_dielectric(cos_l, eta)[0]) * exit_scale / math.pi * cos_l


def cosine_about(rng, n):
    """One direction per row of the unit normals n (k, 3), cosine-distributed about it
    (Malley: a uniform point of the unit disk lifted to the hemisphere)."""
    k = len(n)
    radius = np.sqrt(rng.random(k))
    phi = 2.0 * math.pi * rng.random(k)
    x, y = radius * np.cos(phi), radius * np.sin(phi)
    z = np.sqrt(np.maximum(1.0 - x * x - y * y, 0.0))
    t, b = orthonormal_basis(n)
    return x[:, None] * t + y[:, None] * b + z[:, None] * n


def _uniform_sphere(rng, k):
    """k directions uniform on the unit sphere (the isotropic phase function's sample)."""
    z = 1.0 - 2.0 * rng.random(k)
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = 2.0 * math.pi * rng.random(k)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


# ---------------------------------------------------------------------------
# The walk

def checked_walk_arguments(scene, spp, max_depth, rr_depth, chunk_paths):
    """Refuse arguments the walk cannot take, each in one sentence (TypeError, ValueError).

    ============  =====================================================================
    scene         a :class:`~mimarble.scene.Scene` the walk can render (:func:`walk_problem`)
    spp           samples per pixel: an integer within the image's sample limit
    max_depth     an integer ≥ 1, or −1 for no limit (then ``rr_depth`` must not be None)
    rr_depth      Russian roulette's first depth, an integer ≥ 0, or None for none
    chunk_paths   the paths of a batch, an integer ≥ 1
    ============  =====================================================================
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"render_translucent: {scene!r:.80} is not a scene (mimarble.scene.Scene)")
    if isinstance(spp, bool) or not isinstance(spp, numbers.Integral):
        raise TypeError(f"render_translucent: spp must be an integer, found {spp!r:.40}")
    problem = spp_problem(int(spp), scene.image.width, scene.image.height)
    if problem:
        raise ValueError(f"render_translucent: {problem}")
    if isinstance(max_depth, bool) or not isinstance(max_depth, numbers.Integral) \
            or not (max_depth >= 1 or max_depth == -1):
        raise ValueError(f"render_translucent: max_depth must be an integer ≥ 1, or -1 for no "
                         f"limit, found {max_depth!r:.40}")
    if rr_depth is not None and (isinstance(rr_depth, bool) or not isinstance(rr_depth, numbers.Integral)
                                 or rr_depth < 0):
        raise ValueError(f"render_translucent: rr_depth must be an integer ≥ 0 or None, found "
                         f"{rr_depth!r:.40}")
    if rr_depth is None and max_depth == -1:
        raise ValueError("render_translucent: without Russian roulette (rr_depth None) max_depth "
                         "must be finite, or a path trapped by total internal reflection never ends")
    if isinstance(chunk_paths, bool) or not isinstance(chunk_paths, numbers.Integral) \
            or chunk_paths < 1:
        raise ValueError(f"render_translucent: chunk_paths must be an integer ≥ 1, found "
                         f"{chunk_paths!r:.40}")
    problem = walk_problem(scene)
    if problem:
        raise ValueError(problem)


def render_translucent(scene: Scene, spp: int, seed: int = 0, *, max_depth: int = MAX_DEPTH,
                       rr_depth: int | None = ROULETTE_DEPTH, chunk_paths: int = CHUNK_PATHS,
                       variance: bool = False, steps: dict | None = None):
    """Path mode's image of a scene of translucent spheres (module docstring) -> float64
    (H, W, 3), linear, each pixel the mean of ``spp`` random walks.

    ``seed`` seeds ``np.random.default_rng``; ``max_depth`` is volpath's (−1: no limit);
    ``rr_depth`` starts the Russian roulette (None: none). With ``variance=True`` returns
    ``(image, sample_variance)``: the second, (H, W, 3), is each pixel's unbiased variance
    of one sample (so the pixel mean's variance is it / spp; 0 at spp 1). ``steps``, a dict,
    gains the delta tracking's counts: ``paths``, ``real`` and ``null`` collisions (the
    majorant's efficiency is real / (real + null)); if it holds a list ``depths``, each
    batch appends its paths' vertex counts (volpath's depth where each ended), in the
    order of their lanes (pixel by pixel, a pixel's samples together).
    """
    checked_walk_arguments(scene, spp, max_depth, rr_depth, chunk_paths)
    spheres = WalkSpheres(scene)
    lights = WalkLights(scene)
    ambient = sky_radiance(scene)
    rng = np.random.default_rng(seed)
    depth_cap = math.inf if max_depth == -1 else int(max_depth)
    roulette = math.inf if rr_depth is None else int(rr_depth)
    q_max = ROULETTE_MAX if max_depth == -1 else 1.0
    return pixel_means(scene, int(spp), rng, chunk_paths, variance,
                       lambda o, d: _walk(spheres, lights, ambient, o, d, rng, depth_cap,
                                          roulette, q_max, steps))


def pixel_means(scene, spp: int, rng, chunk_paths: int, variance: bool, paths):
    """The image (H, W, 3) of ``spp`` samples a pixel at uniform random positions in it,
    each the value of ``paths(o, d)`` ((n, 3) from the camera rays' origins and directions,
    both (n, 3)), traced in batches of about ``chunk_paths`` samples (whole pixels); with
    ``variance`` also each pixel's unbiased variance of one sample (0 at spp 1)."""
    width, height = scene.image.width, scene.image.height
    pixels = width * height
    total = np.zeros((pixels, 3))
    square = np.zeros((pixels, 3))
    per_chunk = max(1, int(chunk_paths) // spp)
    for first in range(0, pixels, per_chunk):
        pix = np.arange(first, min(first + per_chunk, pixels))
        pixel = np.repeat(pix, spp)
        x = ((pixel % width) + rng.random(len(pixel))) / width
        y = ((pixel // width) + rng.random(len(pixel))) / height
        eye, d = camera_rays(scene, x, y)
        value = paths(np.broadcast_to(eye, d.shape).copy(), d)
        for c in range(3):
            total[:, c] += np.bincount(pixel, value[:, c], minlength=pixels)
            square[:, c] += np.bincount(pixel, value[:, c] ** 2, minlength=pixels)
    mean = total / spp
    image = mean.reshape(height, width, 3)
    if not variance:
        return image
    spread = np.maximum(square - spp * mean * mean, 0.0) / (spp - 1) if spp > 1 \
        else np.zeros_like(mean)
    return image, spread.reshape(height, width, 3)


def nearer_lights(lights, oo, dd, scale, camera, best, which):
    """(best, which, emitted): the rays (oo, dd) that meet an area light's shape (beyond
    ``scale``, camera rays — ``camera`` true — never: hide_emitters) nearer than ``best``
    get its distance, ``which`` −2 and the radiance it sends them (a rectangle's on its
    emitting side only, else 0); ``emitted`` (n, 3) is 0 elsewhere."""
    emitted = np.zeros((len(dd), 3))
    for c, radius, radiance in lights.spheres:
        tn, _ = sphere_roots(oo, dd, c, radius)
        t = np.where((tn > scale) & ~camera, tn, np.inf)
        closer = t < best
        best = np.where(closer, t, best)
        which = np.where(closer, -2, which)
        emitted = np.where(closer[:, None], radiance, emitted)
    for c, to_local, normal, radiance in lights.rectangles:
        facing = dd @ normal
        with np.errstate(invalid="ignore", divide="ignore"):
            t = ((c - oo) @ normal) / facing
            local = (oo + t[:, None] * dd - c) @ to_local.T
        inside_rect = (np.abs(local[:, 0]) <= 1.0) & (np.abs(local[:, 1]) <= 1.0)
        t = np.where((t > scale) & inside_rect & ~camera, t, np.inf)
        closer = t < best
        best = np.where(closer, t, best)
        which = np.where(closer, -2, which)
        # one-sided: it emits towards its normal, to rays arriving against it
        emitted = np.where(closer[:, None], np.where((facing < 0)[:, None], radiance, 0.0),
                           emitted)
    return best, which, emitted


def sky_radiance(scene):
    """What a path that leaves the scene meets: the ambient A (an RGB array), or the
    scene's environment's radiance along its direction (a function of (N, 3) unit
    directions)."""
    if scene.environment is None:
        return np.array(scene.ambient, dtype=np.float64)
    return EnvironmentLookup(scene.environment, scene.source).radiance


def _walk(spheres, lights, ambient, o, d, rng, depth_cap, roulette, q_max, steps=None):
    """Every path's contribution (n, 3), the walks of rays (o, d) from the camera (``steps``:
    counts added, see :func:`render_translucent`)."""
    n = len(d)
    if steps is not None:
        steps["paths"] = steps.get("paths", 0) + n
    value = np.zeros((n, 3))
    beta = np.ones((n, 3))
    depth = np.zeros(n, dtype=np.int64)
    medium = np.full(n, -1, dtype=np.int64)      # the sphere whose inside the path is in
    left = np.full(n, -1, dtype=np.int64)        # the sphere the path last left outwards
    live = np.arange(n)
    t_min = T_MIN_REL
    exit_scale = 1.0 / (1.0 - np.array([diffuse_fresnel_reflectance(e) for e in spheres.ior]))
    sampled_lights = bool(lights.points or lights.spheres or lights.rectangles)
    exited = np.zeros(n, dtype=bool)             # the path's last vertex is an exit
    while live.size:
        inside = medium[live] >= 0
        ended = np.zeros(live.size, dtype=bool)   # ended by a light, an escape or absorption
        event = np.zeros(live.size, dtype=bool)   # a real event (depth += 1) happened

        # ---- outside: the nearest sphere or light, or the environment
        out = np.flatnonzero(~inside)
        if out.size:
            idx = live[out]
            oo, dd = o[idx], d[idx]
            best = np.full(out.size, np.inf)
            which = np.full(out.size, -1, dtype=np.int64)     # sphere hit, or -2 - light
            scale = t_min * (1.0 + np.max(np.abs(oo), axis=1))
            for s in range(len(spheres.radii)):
                tn, _ = sphere_roots(oo, dd, spheres.centers[s], spheres.radii[s])
                t = np.where((tn > scale) & (left[idx] != s), tn, np.inf)   # NaN: miss
                closer = t < best
                best, which = np.where(closer, t, best), np.where(closer, s, which)
            camera = depth[idx] == 0                  # hide_emitters: camera rays see no light
            best, which, emitted = nearer_lights(lights, oo, dd, scale, camera, best, which)
            escape = which == -1
            if callable(ambient):                     # an environment: seen by every ray
                value[idx[escape]] += beta[idx[escape]] * ambient(dd[escape])
            else:
                value[idx[escape]] += np.where(camera[escape, None], 0.0,
                                               beta[idx[escape]] * ambient)
            # an area light met by a path leaving an exit was estimated there (volume_lights):
            # it ends the path, black
            lit = which == -2
            counted = lit & ~exited[idx]
            value[idx[counted]] += beta[idx[counted]] * emitted[counted]
            ended[out[escape | lit]] = True

            hit = np.flatnonzero(which >= 0)
            if hit.size:
                s = which[hit]
                j = idx[hit]
                p = oo[hit] + best[hit, None] * dd[hit]
                normal = (p - spheres.centers[s]) / spheres.radii[s, None]
                normal /= np.linalg.norm(normal, axis=1, keepdims=True)
                p = spheres.centers[s] + spheres.radii[s, None] * normal     # on the surface
                cos_i = np.clip(-np.einsum("ij,ij->i", dd[hit], normal), 0.0, 1.0)
                # from outside: the mirror with probability F(μᵢ), else in, cosine about −n
                f, _ = fresnel_dielectric(cos_i, spheres.ior[s])
                reflect = rng.random(hit.size) < f
                new = np.where(reflect[:, None], dd[hit] + 2.0 * cos_i[:, None] * normal,
                               cosine_about(rng, -normal))
                o[j] = p
                d[j] = new / np.linalg.norm(new, axis=1, keepdims=True)
                medium[j] = np.where(reflect, -1, s)
                left[j] = np.where(reflect, s, -1)
                exited[j] = False
                event[out[hit]] = True

        # ---- inside a sphere: delta tracking to the next collision or the boundary
        ins = np.flatnonzero(inside)
        if ins.size:
            idx = live[ins]
            s = medium[idx]
            oo, dd = o[idx], d[idx]
            c, r = spheres.centers[s], spheres.radii[s]
            # the far root: o is inside (or on) the sphere; NaN only for a ray leaving it
            # tangentially from its surface, which meets the wall at once
            t_exit = np.nan_to_num(np.maximum(sphere_roots(oo, dd, c, r)[1], 0.0), nan=0.0)
            sigma = spheres.majorant[s]
            with np.errstate(divide="ignore"):
                t_free = np.where(sigma > 0, -np.log1p(-rng.random(ins.size)) / sigma, np.inf)
            collide = t_free < t_exit

            wall = np.flatnonzero(~collide)
            if wall.size:
                j, sw = idx[wall], s[wall]
                p = oo[wall] + t_exit[wall, None] * dd[wall]
                outward = (p - c[wall]) / r[wall, None]
                outward /= np.linalg.norm(outward, axis=1, keepdims=True)
                p = c[wall] + r[wall, None] * outward
                # from inside: always out, cosine about n, weight W(μₒ) = (1 − F(μₒ))/(1 − F̄)
                new = cosine_about(rng, outward)
                f, _ = fresnel_dielectric(np.einsum("ij,ij->i", new, outward), spheres.ior[sw])
                beta[j] *= ((1.0 - f) * exit_scale[sw])[:, None]
                near = depth[j] + 1 < depth_cap          # volpath: no light at the last vertex
                if sampled_lights and near.any():
                    value[j[near]] += beta[j[near]] * exit_lighting(
                        spheres, lights, p[near], outward[near], sw[near],
                        lambda cos_l, k: exit_lobe(cos_l, spheres.ior[k], exit_scale[k]), rng)
                exited[j] = True
                o[j] = p
                d[j] = new
                medium[j] = -1
                left[j] = sw
                event[ins[wall]] = True

            hits = np.flatnonzero(collide)
            if hits.size:
                j = idx[hits]
                p = oo[hits] + t_free[hits, None] * dd[hits]
                o[j] = p
                real = np.zeros(hits.size, dtype=bool)
                u = rng.random(hits.size)
                for k in np.unique(s[hits]):
                    here = np.flatnonzero(s[hits] == k)
                    ratio, albedo = spheres.coefficients(int(k), p[here])
                    chosen = u[here] < ratio
                    real[here[chosen]] = True
                    beta[j[here[chosen]]] *= albedo[chosen]
                if steps is not None:
                    steps["real"] = steps.get("real", 0) + int(real.sum())
                    steps["null"] = steps.get("null", 0) + int((~real).sum())
                scattered = j[real]
                d[scattered] = _uniform_sphere(rng, scattered.size)
                event[ins[hits[real]]] = True

        # ---- depth, absorption and roulette after a real event
        ev = np.flatnonzero(event)
        if ev.size:
            j = live[ev]
            depth[j] += 1
            stop = depth[j] >= depth_cap
            stop |= ~np.any(beta[j] > 0.0, axis=1)       # absorbed (albedo 0)
            play = ~stop & (depth[j] > roulette)
            if play.any():
                k = j[play]
                q = np.minimum(beta[k].max(axis=1), q_max)
                survive = rng.random(k.size) < q
                beta[k[survive]] /= q[survive, None]
                lost = np.flatnonzero(play)[~survive]
                stop[lost] = True
            ended[ev[stop]] = True
        live = live[~ended]
    if steps is not None and "depths" in steps:    # each path's vertices, in lane order
        steps["depths"].append(depth)
    return value
