"""Next-event estimation where the reference's walk leaves a translucent sphere: point lights, spherical and rectangular area lights, through shadow rays.

At an exit point p (outward normal n) the light that leaves towards the direction l is
f(l)·cos θ_l times the radiance arriving from l, f the boundary's exit lobe
(:mod:`.volume`). Each light is estimated with one shadow ray a path:

* a **point light** of intensity I at distance r: f·cos θ_l·I/r² (a delta light, no
  sampling);
* a **sphere** of radius R and radiance L, centre at distance D: a direction drawn
  uniformly in the cone it subtends (pdf 1/(2π(1 − cos θ_max)), sin θ_max = R/D), weighed
  f·cos θ_l·L/pdf;
* a **rectangle** of area S and radiance L on the side its normal m faces: a point q drawn
  uniformly on it (pdf 1/S), weighed f·cos θ_l·L·cos θ_q/r² · S, cos θ_q = −l·m the
  angle at which l leaves its emitting side (0 behind it).

A shadow ray is blocked by any other translucent sphere and by every area light's shape
(black to light from behind, and opaque) before the sampled point; the exit's own sphere
is convex, so a ray leaving it outwards does not meet it again. The walk then counts no
area light that the path leaving this exit meets by chance (that light is estimated
here); the sky it still gets by meeting it. Imports NumPy and this package's
ray–sphere roots only.
"""

from __future__ import annotations

import math

import numpy as np

from mimarble.contract import T_MIN_REL

from .intersection import sphere_roots    # both roots, the stable quadratic


def exit_lighting(spheres, lights, p, n, s, lobe, rng) -> np.ndarray:
    """(k, 3): the light of every point and area light of ``lights`` (volume_scene.WalkLights)
    leaving the exit points p (k, 3) of spheres s (k,) with outward normals n, one sample a
    light (module docstring). ``lobe(cos θ_l, s)`` is the exit lobe's f·cos θ_l (0 where
    cos θ_l ≤ 0)."""
    total = np.zeros((len(p), 3))
    scale = T_MIN_REL * (1.0 + np.max(np.abs(p), axis=1))
    for position, intensity in lights.points:
        to = position - p
        r = np.linalg.norm(to, axis=1)
        ell = to / r[:, None]
        seen = _unblocked(spheres, lights, p, ell, r, s, scale)
        weight = lobe(np.einsum("ij,ij->i", ell, n), s) / (r * r)
        total += np.where(seen, weight, 0.0)[:, None] * intensity
    for k, (centre, radius, radiance) in enumerate(lights.spheres):
        ell, r, inverse_pdf = _toward_sphere(rng, p, centre, radius)
        seen = _unblocked(spheres, lights, p, ell, r, s, scale, skip_sphere=k)
        weight = lobe(np.einsum("ij,ij->i", ell, n), s) * inverse_pdf
        total += np.where(seen, weight, 0.0)[:, None] * radiance
    for k, (centre, to_local, normal, radiance) in enumerate(lights.rectangles):
        frame = np.linalg.inv(to_local)                   # columns a₁/2, a₂/2, m
        area = 4.0 * float(np.linalg.norm(np.cross(frame[:, 0], frame[:, 1])))
        u = rng.uniform(-1.0, 1.0, (len(p), 2))
        q = centre + u[:, :1] * frame[:, 0] + u[:, 1:] * frame[:, 1]
        to = q - p
        r = np.linalg.norm(to, axis=1)
        ell = to / r[:, None]
        cos_q = np.maximum(-(ell @ normal), 0.0)          # it emits towards its normal
        seen = _unblocked(spheres, lights, p, ell, r, s, scale, skip_rectangle=k)
        weight = lobe(np.einsum("ij,ij->i", ell, n), s) * cos_q * area / (r * r)
        total += np.where(seen, weight, 0.0)[:, None] * radiance
    return total


def _toward_sphere(rng, p, centre, radius):
    """(unit directions (k, 3), distances to the sphere's near side (k,), 1/pdf (k,)):
    directions uniform in the cone of half-angle θ_max, sin θ_max = R/D, about the
    direction to the centre; 1 − cos θ_max = sin²θ_max/(1 + cos θ_max), without the
    cancellation of 1 − cos for a small sphere."""
    axis = centre - p
    distance = np.linalg.norm(axis, axis=1)
    axis = axis / distance[:, None]
    sin2 = np.minimum((radius / distance) ** 2, 1.0)
    cos_max = np.sqrt(1.0 - sin2)
    spread = sin2 / (1.0 + cos_max)                           # 1 − cos θ_max
    one_minus_cos = spread * rng.random(len(p))               # 1 − cos θ, uniform
    cos_t = 1.0 - one_minus_cos
    sin_t = np.sqrt(np.maximum(one_minus_cos * (2.0 - one_minus_cos), 0.0))
    phi = 2.0 * math.pi * rng.random(len(p))
    t, b = orthonormal_basis(axis)
    ell = (sin_t * np.cos(phi))[:, None] * t + (sin_t * np.sin(phi))[:, None] * b \
        + cos_t[:, None] * axis
    near, _ = sphere_roots(p, ell, centre, radius)
    # a direction at the cone's rim grazes the sphere: its root may round to NaN
    near = np.where(np.isfinite(near), near, distance * cos_max)
    return ell, near, 2.0 * math.pi * spread


def orthonormal_basis(n):
    """Two unit vectors completing each row of the unit normals n to an orthonormal frame
    (Duff et al.'s branchless construction)."""
    sign = np.where(n[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    bb = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    return t, bb


def _unblocked(spheres, lights, p, ell, r, s, scale, skip_sphere=-1, skip_rectangle=-1):
    """Whether the shadow rays p + t·ell, t ∈ (scale, r·(1 − 10⁻⁹)), meet no other
    translucent sphere than s and no area light's shape but the one sampled."""
    reach = r * (1.0 - 1e-9)
    seen = np.ones(len(p), dtype=bool)
    for k in range(len(spheres.radii)):
        tn, _ = sphere_roots(p, ell, spheres.centers[k], spheres.radii[k])
        seen &= ~((s != k) & (tn > scale) & (tn < reach))     # NaN: a miss
    for k, (centre, radius, _) in enumerate(lights.spheres):
        if k != skip_sphere:
            tn, _ = sphere_roots(p, ell, centre, radius)
            seen &= ~((tn > scale) & (tn < reach))
    for k, (centre, to_local, normal, _) in enumerate(lights.rectangles):
        if k != skip_rectangle:
            with np.errstate(invalid="ignore", divide="ignore"):
                t = ((centre - p) @ normal) / (ell @ normal)
                local = (p + t[:, None] * ell - centre) @ to_local.T
            seen &= ~((t > scale) & (t < reach) & (np.abs(local[:, 0]) <= 1.0)
                      & (np.abs(local[:, 1]) <= 1.0))
    return seen
