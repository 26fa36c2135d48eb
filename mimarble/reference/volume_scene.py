"""A translucent scene as the reference's random walk reads it: which scenes it renders, its spheres and their majorants, its lights' radiance and intensity.

The majorant σ̄ of a sphere's medium bounds its density channel from above by interval
arithmetic (:func:`channel_interval`, :func:`density_bound`); the area lights are
spheres and rectangles of radiance I/area (:func:`area_radiance`), the point lights
points of intensity I·π·d² (:func:`point_intensity`); the walk itself is
:mod:`.volume`'s.
"""

from __future__ import annotations

import math

import numpy as np

from mimarble.scene import geometry
from mimarble.scene.albedo_grid import albedo_grid, medium_holders
from mimarble.scene.band_limit import band_limited
from mimarble.scene.model import (
    Add,
    ColorChannel,
    ImageChannel,
    MarbleChannel,
    Mix,
    Multiply,
    RectangleArea,
    Scene,
    Sphere,
    SphereArea,
    in_object_space,
)
from mimarble.scene.shapes import SHAPE_KINDS

from .channels import channel_color
from .subsurface_reflectance import diffuse_fresnel_reflectance, single_scattering_albedo

__all__ = ["channel_interval", "density_bound", "area_radiance", "point_intensity", "walk_problem",
           "WalkSpheres", "WalkLights"]


#: Grid nodes evaluated at a time when an albedo grid is made (bounds the temporaries).
GRID_CHUNK = 1 << 16


# ---------------------------------------------------------------------------
# The majorant: bounds of a channel by interval arithmetic

def channel_interval(channel) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi), each (3,): every value of each colour component of ``channel`` lies in
    [lo, hi]. A colour is its value; a marble is its ramp at a clamped t, a convex
    combination of its ramp colours, so within their smallest and largest component; a sum
    adds the intervals, a product takes the extremes of the four corner products, a mix
    a·(1 − w) + b·w combines those (a number w as a point interval). Image maps are refused
    (ValueError): they have no value off a surface."""
    if isinstance(channel, ColorChannel):
        v = np.array(channel.rgb, dtype=np.float64)
        return v, v.copy()
    if isinstance(channel, MarbleChannel):
        ramp = np.array(channel.ramp, dtype=np.float64).reshape(-1, 3)
        return ramp.min(axis=0), ramp.max(axis=0)
    if isinstance(channel, ImageChannel):
        raise ValueError(f"an image map ({channel.location!r}) has no value inside a volume: "
                         f"a subsurface's albedo and density must be colours, marbles or "
                         f"expressions of them")
    if isinstance(channel, Add):
        parts = [channel_interval(c) for c in channel.operands]
        return sum(p[0] for p in parts), sum(p[1] for p in parts)
    if isinstance(channel, Multiply):
        lo, hi = channel_interval(channel.operands[0])
        for c in channel.operands[1:]:
            lo, hi = _product(lo, hi, *channel_interval(c))
        return lo, hi
    if isinstance(channel, Mix):
        a, b = channel_interval(channel.a), channel_interval(channel.b)
        if isinstance(channel.weight, float):
            w = (np.full(3, channel.weight), np.full(3, channel.weight))
        else:
            w = channel_interval(channel.weight)
        keep = _product(*a, 1.0 - w[1], 1.0 - w[0])
        take = _product(*b, *w)
        return keep[0] + take[0], keep[1] + take[1]
    raise TypeError(f"unknown channel type {type(channel).__name__}")


def _product(alo, ahi, blo, bhi):
    corners = np.stack([alo * blo, alo * bhi, ahi * blo, ahi * bhi])
    return corners.min(axis=0), corners.max(axis=0)


def density_bound(subsurface) -> float:
    """An upper bound of the density d = max(0, mean of the density channel's components)
    of a subsurface (1 without a density channel): max(0, mean of the components' upper
    bounds). The majorant is this over the mean free path."""
    if subsurface.density is None:
        return 1.0
    hi = channel_interval(subsurface.density)[1]
    return max(0.0, float(hi.sum()) / 3.0)


# ---------------------------------------------------------------------------
# Lights

def area_radiance(light, lookat) -> np.ndarray:
    """The radiance (3,) path mode gives an area light (``light.area``), so that its
    radiant intensity towards the look-at point is the path-mode point light's I·π·d²
    (d = |position − lookat|): a sphere of radius R shows the disk π·R² to every
    direction, so L = I·d²/R²; a rectangle of edges a₁, a₂ (area S = |a₁ × a₂|), one-sided
    towards the look-at point, has intensity S·L·cos θ₀ there, so L = I·π·d²/(S·cos θ₀)
    (cos θ₀ = 1 where the look-at point is not in front of it)."""
    color = np.array(light.color, dtype=np.float64)
    position = np.array(light.position, dtype=np.float64)
    look = np.array(lookat, dtype=np.float64)
    d2 = float(np.sum((position - look) ** 2))
    area = light.area
    if isinstance(area, SphereArea):
        return color * d2 / area.radius ** 2
    normal = np.cross(np.array(area.axis1, dtype=np.float64), np.array(area.axis2, dtype=np.float64))
    size = float(np.linalg.norm(normal))
    facing = abs(float(normal @ (look - position))) / (size * math.sqrt(d2)) if d2 > 0 else 1.0
    facing = facing if facing > 0 else 1.0
    return color * math.pi * d2 / (size * facing)


def point_intensity(light, lookat) -> np.ndarray:
    """The radiant intensity (3,) path mode gives a point light of colour I, in W/sr:
    I·π·d², d = |position − lookat|. Derived from the model: a Lambertian surface of
    reflectance kd at the look-at point, lit at angle θ, receives the irradiance
    E = intensity·cos θ/d² and shows the radiance kd·E/π; whitted mode shows kd·I·cos θ
    there (the paper's unattenuated light), so intensity = I·π·d²."""
    d2 = float(np.sum((np.array(light.position, dtype=np.float64)
                       - np.array(lookat, dtype=np.float64)) ** 2))
    return np.array(light.color, dtype=np.float64) * math.pi * d2


def _rectangle(light, lookat):
    """(centre, to_local (3×3: world offset → (s, t, height)), unit normal towards the
    look-at point) of a rectangle light: p = c + s·a₁/2 + t·a₂/2 for s, t ∈ [−1, 1]."""
    a1 = np.array(light.area.axis1, dtype=np.float64)
    a2 = np.array(light.area.axis2, dtype=np.float64)
    c = np.array(light.position, dtype=np.float64)
    n = np.cross(a1, a2)
    n /= np.linalg.norm(n)
    if n @ (np.array(lookat, dtype=np.float64) - c) < 0:
        n = -n
    frame = np.stack([a1 / 2, a2 / 2, n], axis=1)       # columns: local → world
    return c, np.linalg.inv(frame), n


# ---------------------------------------------------------------------------
# Scene checks and arrays

def walk_problem(scene: Scene) -> str | None:
    """Why the walk cannot render ``scene`` (one sentence), or None."""
    others = [kind.plural for kind in SHAPE_KINDS if kind.cls is not Sphere
              and getattr(scene, kind.plural)]
    if others:
        return (f"render_translucent renders translucent spheres only; this scene has "
                f"{' and '.join(others)}")
    if scene.environment is not None and any(light.area is not None for light in scene.lights):
        return ("render_translucent renders an environment with point lights only: with an "
                "environment, path mode's camera sees the area lights, which the walk's "
                "camera rays pass through")
    eye = np.array(scene.camera.eye, dtype=np.float64)
    spheres = scene.spheres
    for k, sphere in enumerate(spheres):
        material = scene.materials[sphere.material]
        if material.subsurface is None:
            return (f'render_translucent renders translucent spheres only; sphere_{k} has the '
                    f'material "{material.name}", which has no subsurface')
        c, r = np.array(sphere.center, dtype=np.float64), sphere.radius
        if np.linalg.norm(eye - c) <= r * (1.0 + 1e-9):
            return f"the eye is inside (or on) sphere_{k}: the walk starts every path outside"
        for j in range(k):
            other = spheres[j]
            if np.linalg.norm(c - np.array(other.center)) <= (r + other.radius) * (1.0 + 1e-9):
                return (f"sphere_{j} and sphere_{k} overlap or touch: each translucent sphere "
                        f"must lie outside the others")
        for m, light in enumerate(scene.lights):
            if light.area is None:
                if np.linalg.norm(np.array(light.position, dtype=np.float64) - c) <= r * (1.0 + 1e-9):
                    return (f"the point light light_{m} is inside (or on) sphere_{k}: each "
                            f"translucent sphere must lie clear of the lights")
                continue
            if _light_meets(light, c, r):
                return (f"the area light light_{m} meets sphere_{k}: each translucent sphere "
                        f"must lie clear of the lights")
    return None


def _light_meets(light, c, r) -> bool:
    """Whether the area light's shape comes within r (times 1 + 1e-9) of the point c."""
    position = np.array(light.position, dtype=np.float64)
    reach = r * (1.0 + 1e-9)
    if isinstance(light.area, SphereArea):
        return bool(np.linalg.norm(c - position) <= reach + light.area.radius)
    centre, to_local, normal = _rectangle(light, light.position)
    s, t, _ = to_local @ (c - centre)
    if abs(s) <= 1.0 and abs(t) <= 1.0:          # c lies over the parallelogram: its plane
        return bool(abs(float((c - centre) @ normal)) <= reach)
    a1, a2 = np.array(light.area.axis1) / 2, np.array(light.area.axis2) / 2
    corners = [centre + i * a1 + j * a2 for i, j in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    for k in range(4):                           # else the nearest point is on an edge
        p, q = corners[k], corners[(k + 1) % 4]
        w = np.clip(float((c - p) @ (q - p)) / float((q - p) @ (q - p)), 0.0, 1.0)
        if np.linalg.norm(c - (p + w * (q - p))) <= reach:
            return True
    return False


class WalkSpheres:
    """The translucent spheres as arrays, with their media."""

    def __init__(self, scene: Scene):
        spheres = scene.spheres
        # Band-limited to each mean free path as path mode's walk (mimarble/scene/band_limit.py).
        subs = [band_limited(scene.materials[s.material].subsurface) for s in spheres]
        self.centers = np.array([s.center for s in spheres], dtype=np.float64).reshape(-1, 3)
        self.radii = np.array([s.radius for s in spheres], dtype=np.float64)
        self.ior = np.array([s.ior for s in subs], dtype=np.float64)
        self.mfp = np.array([s.mean_free_path for s in subs], dtype=np.float64)
        self.majorant = np.array([density_bound(s) for s in subs]) / self.mfp
        self.albedo = [s.albedo for s in subs]
        self.reflectance = [s.reflectance for s in subs]      # (else None: the albedo's)
        self.fresnel_mean = [None if s.reflectance is None else diffuse_fresnel_reflectance(s.ior)
                             for s in subs]
        self.density = [s.density for s in subs]
        self.object_space = [any(in_object_space(ch) for ch in s.channels().values())
                             for s in subs]
        self.from_world = np.linalg.inv(np.array([geometry.object_to_world(s) for s in spheres],
                                                 dtype=np.float64).reshape(-1, 4, 4))[:, :3, :]
        # The albedo grid of each sphere's medium (mimarble/scene/albedo_grid.py), over the
        # spheres that share it as path mode's translator shares it: every sphere of the
        # material, or with object-space marbles those of the same placement.
        self.grids = [albedo_grid(sub, medium_holders(
            spheres, s.material, geometry.object_to_world(s) if self.object_space[k] else None))
            for k, (s, sub) in enumerate(zip(spheres, subs))]
        self._grid_albedo = [None] * len(spheres)          # made when first read

    def coefficients(self, s: int, p: np.ndarray):
        """(σ_t/σ̄ (k,), albedo (k, 3)) of sphere s's medium at world points p (k, 3): the
        albedo channel clamped to [0, 1], or the reflectance channel's inversion
        (:mod:`.subsurface_reflectance`)."""
        obj = None
        if self.object_space[s]:
            m = self.from_world[s]
            obj = p @ m[:, :3].T + m[:, 3]
        albedo = self._albedo(s, p, obj) if self.grids[s] is None else self._from_grid(s, p)
        if self.density[s] is None:
            ratio = np.ones(len(p))
        else:
            d = np.maximum(channel_color(self.density[s], p, object_points=obj).mean(axis=1), 0.0)
            # σ_t/σ̄ = d/bound(d) ≤ 1 (the bound holds; min() only absorbs rounding)
            ratio = np.minimum(d / (self.majorant[s] * self.mfp[s]), 1.0)
        return ratio, albedo


    def _albedo(self, s: int, p: np.ndarray, obj) -> np.ndarray:
        """α (k, 3) of sphere s's medium evaluated at world points p (object points obj)."""
        if self.reflectance[s] is not None:
            return single_scattering_albedo(
                channel_color(self.reflectance[s], p, object_points=obj), self.fresnel_mean[s])
        return np.clip(channel_color(self.albedo[s], p, object_points=obj), 0.0, 1.0)

    def _from_grid(self, s: int, p: np.ndarray) -> np.ndarray:
        """α (k, 3) at world points p by trilinear interpolation of sphere s's grid of α at
        its nodes (made at the first call, GRID_CHUNK nodes at a time): u = (p − origin)/h
        clamped to [0, n − 1] per axis, the cell of ⌊u⌋ (the last one at the far face),
        weights u − ⌊u⌋ and their complements."""
        grid = self.grids[s]
        if self._grid_albedo[s] is None:
            nx, ny, nz = grid.counts
            index = np.arange(grid.nodes)
            ijk = np.stack([index % nx, (index // nx) % ny, index // (nx * ny)], axis=1)
            nodes = np.asarray(grid.origin) + grid.spacing * ijk
            if self.object_space[s]:
                m = self.from_world[s]
                to_object = lambda q: q @ m[:, :3].T + m[:, 3]   # noqa: E731
            else:
                to_object = lambda q: None                       # noqa: E731
            self._grid_albedo[s] = np.concatenate([
                self._albedo(s, nodes[a:a + GRID_CHUNK], to_object(nodes[a:a + GRID_CHUNK]))
                for a in range(0, len(nodes), GRID_CHUNK)])
        counts = np.asarray(grid.counts)
        u = np.clip((p - np.asarray(grid.origin)) / grid.spacing, 0.0, counts - 1.0)
        cell = np.minimum(np.floor(u).astype(np.int64), counts - 2)
        f = u - cell
        values = self._grid_albedo[s]
        out = np.zeros((len(p), 3))
        for dx in (0, 1):
            for dy in (0, 1):
                for dz in (0, 1):
                    w = (f[:, 0] if dx else 1.0 - f[:, 0]) * (f[:, 1] if dy else 1.0 - f[:, 1]) \
                        * (f[:, 2] if dz else 1.0 - f[:, 2])
                    node = (cell[:, 0] + dx) + counts[0] * ((cell[:, 1] + dy)
                                                            + counts[1] * (cell[:, 2] + dz))
                    out += w[:, None] * values[node]
        return out


class WalkLights:
    """The lights as arrays: point lights (position, intensity: :func:`point_intensity`),
    area lights' spheres (centre, radius, radiance) and rectangles (centre, to_local,
    normal, radiance)."""

    def __init__(self, scene: Scene):
        lookat = scene.camera.lookat
        self.spheres = [(np.array(l.position, dtype=np.float64), l.area.radius,
                         area_radiance(l, lookat))
                        for l in scene.lights if isinstance(l.area, SphereArea)]
        self.rectangles = [_rectangle(l, lookat) + (area_radiance(l, lookat),)
                           for l in scene.lights if isinstance(l.area, RectangleArea)]
        self.points = [(np.array(l.position, dtype=np.float64), point_intensity(l, lookat))
                       for l in scene.lights if l.area is None]
