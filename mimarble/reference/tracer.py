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
  (:data:`T_MIN_REL` = 1e-6); miss → background. Spheres by the numerically stable
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
evaluated by :mod:`.channels`; :func:`channel_color` is re-exported here.

Everything is vectorised over batches of rays; Python loops run over spheres,
planes, boxes, lights, channels and chunks only (the triangles of all meshes are one
hierarchy). Imports NumPy, the standard library, :mod:`mimarble.scene` (the model, its
geometry and mesh files' checks) and this package's own channels, marble, noise, mesh
files and triangles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mimarble.scene import geometry
from mimarble.scene.errors import SceneError
from mimarble.scene.limits import MAX_MESH_TRIANGLES
from mimarble.meshes.facts import mesh_facts
from mimarble.meshes.limits import MeshFileError
from mimarble.scene.model import Scene, in_object_space, samples_per_axis
from mimarble.scene.rules import shortened

from .channels import channel_color, needs_uv, sphere_uv
from mimarble.meshes.arrays import read_mesh
from .triangles import TriangleBVH

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
]

#: Primary rays accept hits at t > T_MIN_REL·(1 + max_k |origin_k|).
T_MIN_REL = 1e-6
#: Shadow rays start at p + ε·n with ε = EPS_REL·(1 + max_k |p_k|).
EPS_REL = 1e-4
#: Rays traced per batch (rounded down to whole pixels, at least one pixel).
CHUNK_RAYS = 65536
#: The material components, in the order of the shading formula.
SLOTS = ("ambient", "diffuse", "specular")


# ---------------------------------------------------------------------------
# Scene preparation

@dataclass(frozen=True)
class PreparedScene:
    """The scene as arrays, with every distinct channel listed once.

    ``slot_channel[m, s]`` is the index in ``channels`` of material m's
    component ``SLOTS[s]``, or -1 when the component is absent.
    """

    scene: Scene
    centers: np.ndarray            # (S, 3)
    radii: np.ndarray              # (S,)
    sphere_material: np.ndarray    # (S,) int, index into materials
    materials: tuple               # (M,) Material
    channels: tuple                # distinct Channel values
    slot_channel: np.ndarray       # (M, 3) int
    shininess: np.ndarray          # (M,)
    light_positions: np.ndarray    # (L, 3)
    light_colors: np.ndarray       # (L, 3)
    ambient: np.ndarray            # (3,)
    background: np.ndarray         # (3,)
    light_areas: tuple = ()        # (L,) None, or area_samples' pattern of an area light
    shape_material: np.ndarray | None = None   # (n,) int: every shape's, scene.shapes() order
    planes: "PlaneArrays | None" = None
    boxes: "BoxArrays | None" = None
    meshes: "MeshArrays | None" = None
    from_world: np.ndarray | None = None       # (n, 3, 4): object_to_world⁻¹, when needed

    @property
    def first_plane(self) -> int:
        """The global shape index of plane 0 (spheres come first, then planes, boxes, meshes)."""
        return len(self.radii)

    @property
    def first_box(self) -> int:
        return self.first_plane + (0 if self.planes is None else len(self.planes.radius))

    @property
    def spheres_only(self) -> bool:
        return self.planes is None and self.boxes is None and self.meshes is None


@dataclass(frozen=True)
class PlaneArrays:
    """Planes: a point, the unit normal, and the disk they are rendered as (centre, radius:
    geometry.plane_disk)."""

    point: np.ndarray              # (P, 3)
    normal: np.ndarray             # (P, 3)
    centre: np.ndarray             # (P, 3)
    radius: np.ndarray             # (P,)


@dataclass(frozen=True)
class BoxArrays:
    """Boxes: corners in object space, and world → object (M⁻¹, float64: rows 3×4)."""

    lo: np.ndarray                 # (B, 3)
    hi: np.ndarray                 # (B, 3)
    from_world: np.ndarray         # (B, 3, 4)


@dataclass(frozen=True)
class MeshArrays:
    """Every mesh's triangles in world space, one hierarchy: ``triangles`` index
    ``positions`` (and ``uv``, NaN rows for a mesh without texture coordinates);
    ``triangle_shape`` is each triangle's global shape index."""

    bvh: TriangleBVH
    positions: np.ndarray          # (V, 3) world
    triangles: np.ndarray          # (T, 3) int64
    triangle_shape: np.ndarray     # (T,) int64
    uv: np.ndarray | None          # (V, 2), or None when no mesh has texture coordinates


def _from_world(shapes) -> np.ndarray:
    """object_to_world(shape)⁻¹ of each shape (:func:`mimarble.scene.geometry.object_to_world`),
    inverted in float64, as rows 3×4: (n, 3, 4)."""
    if not shapes:
        return np.zeros((0, 3, 4))
    placed = np.array([geometry.object_to_world(shape) for shape in shapes], dtype=np.float64)
    return np.linalg.inv(placed)[:, :3, :]


def read_meshes(scene: Scene) -> tuple:
    """Every mesh file of the scene read (:func:`.mesh_file.read_mesh`), in scene order, as
    the scene language checks them (meshes.facts.mesh_facts: PLY faces triangles, OBJ
    indices from 1), each file once. The PLY headers are checked against
    MAX_MESH_TRIANGLES together before any body is read; an OBJ, whose lines are its
    header, is refused the line it passes the limit, and the scene once the files read so
    far pass it. A file that cannot be read, or the mesh past the limit, is a SceneError
    at that mesh's file string (``mesh file 'NAME': …``)."""
    def refused(mesh, reason):
        return SceneError.in_file(scene.source, mesh.pos,
                                  f"mesh file '{shortened(mesh.file, 256)}': {reason}")

    def over(total):
        return (f"the scene's meshes hold {total} triangles or more, past the "
                f"{MAX_MESH_TRIANGLES} a scene's meshes hold")

    total = 0
    for mesh in scene.meshes:              # PLY headers first: nothing large is read yet
        if mesh.location.lower().endswith(".ply"):
            try:
                total += mesh_facts(mesh.location).triangles
            except MeshFileError as e:
                raise refused(mesh, str(e)) from None
            if total > MAX_MESH_TRIANGLES:
                raise refused(mesh, over(total))
    read: dict = {}
    out, total = [], 0
    for mesh in scene.meshes:
        if mesh.location not in read:
            try:
                read[mesh.location] = read_mesh(mesh.location, relative=False)
            except MeshFileError as e:
                raise refused(mesh, str(e)) from None
        data = read[mesh.location]
        total += len(data.triangles)
        if total > MAX_MESH_TRIANGLES:
            raise refused(mesh, over(total))
        out.append(data)
    return tuple(out)


def _plane_arrays(scene: Scene) -> PlaneArrays | None:
    if not scene.planes:
        return None
    disks = [geometry.plane_disk(scene, plane) for plane in scene.planes]
    normal = np.array([pl.normal for pl in scene.planes], dtype=np.float64)
    return PlaneArrays(point=np.array([pl.point for pl in scene.planes], dtype=np.float64),
                       normal=_normalize(normal),
                       centre=np.array([c for c, _ in disks], dtype=np.float64),
                       radius=np.array([r for _, r in disks], dtype=np.float64))


def _box_arrays(scene: Scene) -> BoxArrays | None:
    if not scene.boxes:
        return None
    return BoxArrays(lo=np.array([b.min for b in scene.boxes], dtype=np.float64),
                     hi=np.array([b.max for b in scene.boxes], dtype=np.float64),
                     from_world=_from_world(scene.boxes))


def _mesh_arrays(scene: Scene, meshes: tuple, first: int) -> MeshArrays | None:
    """The meshes' vertices placed in the world, p_world = M·(p, 1) in float64, and one
    hierarchy over all their triangles; ``first`` is mesh 0's global shape index."""
    if not scene.meshes:
        return None
    positions, triangles, shape, uvs = [], [], [], []
    offset = 0
    for k, (mesh, data) in enumerate(zip(scene.meshes, meshes)):
        m = np.array(geometry.object_to_world(mesh), dtype=np.float64)
        positions.append(data.positions @ m[:3, :3].T + m[:3, 3])
        triangles.append(data.triangles + offset)
        shape.append(np.full(len(data.triangles), first + k, dtype=np.int64))
        uvs.append(data.uv if data.uv is not None else np.full((len(data.positions), 2), np.nan))
        offset += len(data.positions)
    positions = np.concatenate(positions)
    triangles = np.concatenate(triangles)
    corners = positions[triangles]                       # (T, 3, 3)
    bvh = TriangleBVH(corners[:, 0], corners[:, 1], corners[:, 2])
    del corners
    uv = np.concatenate(uvs) if any(d.uv is not None for d in meshes) else None
    return MeshArrays(bvh=bvh, positions=positions, triangles=triangles,
                      triangle_shape=np.concatenate(shape), uv=uv)


def _check_uv(scene: Scene, meshes: tuple) -> None:
    """A material with an image map shades only shapes with (u, v): spheres and meshes
    whose file has texture coordinates (the parser says so at the shape; a scene built in
    Python hears it here)."""
    has_uv = {f"mesh_{k}": data.uv is not None for k, data in enumerate(meshes)}
    for shape_id, shape in scene.shapes():
        if shape_id.startswith("sphere_") or has_uv.get(shape_id):
            continue
        material = scene.material_of(shape)
        if any(needs_uv(c) for c in material.channels().values()):
            why = "its file has no texture coordinates" if shape_id in has_uv else \
                "it has no texture coordinates"
            raise SceneError.in_file(scene.source, shape.pos,
                                     f'the material "{shortened(material.name)}" of {shape_id} '
                                     f"reads an image map, which needs (u, v), and {why}")


def _object_space(scene: Scene, channels: tuple) -> np.ndarray | None:
    """object_to_world(shape)⁻¹ of every shape (rows 3×4), when a channel has a marble in
    object space."""
    if not any(in_object_space(ch) for ch in channels):
        return None
    return _from_world([shape for _, shape in scene.shapes()])


def prepare(scene: Scene, meshes: tuple | None = None) -> PreparedScene:
    """Arrays for :func:`hit` and :func:`shade`; equal channels are deduplicated.
    ``meshes``: the scene's mesh files already read (:func:`read_meshes`), else read here.
    A material with a subsurface that a shape uses is refused (SceneError at its
    ``subsurface``): this is whitted mode's renderer; path mode's translucent spheres are
    :func:`mimarble.reference.volume.render_translucent`'s."""
    used = {shape.material for _, shape in scene.shapes()}
    for material in scene.materials.values():
        if material.subsurface is not None and material.name in used:
            raise SceneError.in_file(
                scene.source, material.subsurface.pos,
                f'material "{material.name}" has a subsurface, which the reference tracer '
                f"renders in path mode only, from Python: "
                f"mimarble.reference.render_translucent(scene, spp)")
    names = list(scene.materials)
    materials = tuple(scene.materials[n] for n in names)
    index = {n: k for k, n in enumerate(names)}
    channels: list = []
    seen: dict = {}
    slot_channel = np.full((len(materials), 3), -1, dtype=np.int64)
    for m, mat in enumerate(materials):
        for s, slot in enumerate(SLOTS):
            ch = getattr(mat, slot)
            if ch is None:
                continue
            if ch not in seen:          # frozen dataclasses: equal by value (pos excluded)
                seen[ch] = len(channels)
                channels.append(ch)
            slot_channel[m, s] = seen[ch]
    spheres = scene.spheres
    lights = scene.lights
    meshes = read_meshes(scene) if meshes is None else tuple(meshes)
    _check_uv(scene, meshes)
    first_mesh = len(spheres) + len(scene.planes) + len(scene.boxes)
    return PreparedScene(
        scene=scene,
        centers=np.array([s.center for s in spheres], dtype=np.float64).reshape(-1, 3),
        radii=np.array([s.radius for s in spheres], dtype=np.float64),
        sphere_material=np.array([index[s.material] for s in spheres], dtype=np.int64),
        materials=materials,
        channels=tuple(channels),
        slot_channel=slot_channel,
        shininess=np.array([m.shininess for m in materials], dtype=np.float64),
        light_positions=np.array([l.position for l in lights], dtype=np.float64).reshape(-1, 3),
        light_colors=np.array([l.color for l in lights], dtype=np.float64).reshape(-1, 3),
        ambient=np.array(scene.ambient, dtype=np.float64),
        background=np.array(scene.image.background, dtype=np.float64),
        light_areas=tuple(None if l.area is None else area_samples(l, scene.camera.lookat)
                          for l in lights),
        shape_material=np.array([index[shape.material] for _, shape in scene.shapes()],
                                dtype=np.int64),
        planes=_plane_arrays(scene),
        boxes=_box_arrays(scene),
        meshes=_mesh_arrays(scene, meshes, first_mesh),
        from_world=_object_space(scene, tuple(channels)),
    )


def _as_prepared(scene) -> PreparedScene:
    return scene if isinstance(scene, PreparedScene) else prepare(scene)


# ---------------------------------------------------------------------------
# Camera and sampling

def _normalize(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def camera_basis(camera, aspect: float):
    """(eye, f, r, u, tan_half, aspect) of the pinhole camera, float64."""
    eye = np.array(camera.eye, dtype=np.float64)
    f = _normalize(np.array(camera.lookat, dtype=np.float64) - eye)
    r = _normalize(np.cross(f, np.array(camera.up, dtype=np.float64)))
    u = np.cross(r, f)
    tan_half = math.tan(math.radians(camera.fov) / 2.0)
    return eye, f, r, u, tan_half, float(aspect)


def camera_rays(scene: Scene, x, y):
    """Primary rays through film positions x, y (arrays in [0, 1], y down).

    Returns (origin (3,), unit directions (N, 3)).
    """
    eye, f, r, u, tan_half, aspect = camera_basis(scene.camera, scene.image.aspect)
    x = np.asarray(x, dtype=np.float64).reshape(-1, 1)
    y = np.asarray(y, dtype=np.float64).reshape(-1, 1)
    d = f + ((2.0 * x - 1.0) * (tan_half * aspect)) * r + ((1.0 - 2.0 * y) * tan_half) * u
    return eye, _normalize(d)


def sample_positions(width: int, height: int, n: int, first_pixel: int = 0, stop_pixel: int | None = None):
    """Film positions of the n×n stratum centres of pixels [first_pixel, stop_pixel).

    Pixels are numbered row-major from the top-left (pixel = row·width + column);
    each pixel's n² samples are contiguous, sample (a, b) at index b·n + a:
    x = (column + (a + ½)/n)/width, y = (row + (b + ½)/n)/height.
    """
    if stop_pixel is None:
        stop_pixel = width * height
    pix = np.arange(first_pixel, stop_pixel, dtype=np.int64)
    col = (pix % width).astype(np.float64)
    row = (pix // width).astype(np.float64)
    sub = np.arange(n * n, dtype=np.int64)
    a = ((sub % n) + 0.5) / n
    b = ((sub // n) + 0.5) / n
    x = (col[:, None] + a[None, :]) / width
    y = (row[:, None] + b[None, :]) / height
    return x.ravel(), y.ravel()


# ---------------------------------------------------------------------------
# Intersection

def _roots(o, d, center, radius):
    """Both roots t_near ≤ t_far of |o + t d − c| = r for unit d (NaN where none).

    Stable form: b = (o−c)·d, disc = r² − |(o−c) − b d|² (no cancellation in
    b² − c), c' = (|o−c| − r)(|o−c| + r), q = −(b + sign(b)√disc), roots q and c'/q.
    """
    oc = o - center
    b = np.einsum("...k,...k->...", oc, d)
    e = oc - b[..., None] * d
    disc = radius * radius - np.einsum("...k,...k->...", e, e)
    lo = np.sqrt(np.einsum("...k,...k->...", oc, oc))
    c = (lo - radius) * (lo + radius)
    with np.errstate(invalid="ignore", divide="ignore"):
        sq = np.sqrt(disc)                       # NaN where the ray misses
        q = -(b + np.copysign(sq, b))
        t1 = q
        t2 = np.where(q != 0.0, c / q, -b)       # q == 0 only for a tangent ray at b = 0
    return np.minimum(t1, t2), np.maximum(t1, t2)


def intersect_spheres(centers, radii, o, d, t_min):
    """Closest hit over all spheres with t > t_min: (t (N,), sphere index (N,), -1 / inf on a miss)."""
    d = np.asarray(d, dtype=np.float64)
    n = d.shape[0]
    best_t = np.full(n, np.inf)
    best_i = np.full(n, -1, dtype=np.int64)
    t_min = np.broadcast_to(np.asarray(t_min, dtype=np.float64), (n,))
    for s in range(len(radii)):
        tn, tf = _roots(o, d, centers[s], radii[s])
        t = np.where(tn > t_min, tn, np.where(tf > t_min, tf, np.inf))   # NaN compares False
        closer = t < best_t
        best_t = np.where(closer, t, best_t)
        best_i = np.where(closer, s, best_i)
    return best_t, best_i


def shadow_hit(centers, radii, o, d, t_max):
    """The paper's ``shadowHit``: does any sphere meet the ray at t in (0, t_max)?

    o, d: (N, 3) origins and unit directions; t_max: (N,). Any hit, early out:
    once a ray is blocked, the remaining spheres are not tested for it.
    Returns a bool (N,).
    """
    o = np.asarray(o, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    t_max = np.asarray(t_max, dtype=np.float64)
    blocked = np.zeros(d.shape[0], dtype=bool)
    live = np.arange(d.shape[0])
    for s in range(len(radii)):
        if live.size == 0:
            break
        tn, tf = _roots(o[live], d[live], centers[s], radii[s])
        tm = t_max[live]
        hit_s = ((tn > 0.0) & (tn < tm)) | ((tf > 0.0) & (tf < tm))
        blocked[live[hit_s]] = True
        live = live[~hit_s]
    return blocked


def intersect_planes(planes: PlaneArrays, o, d, t_lo, t_hi):
    """Closest plane hit with t_lo < t < t_hi within each plane's disk: (t (N,), plane index
    (N,)), inf / −1 on a miss. t = n·(p₀ − o)/(n·d) (inf or NaN, so missed, where the ray
    runs along the plane); kept where |o + t·d − centre| ≤ radius."""
    d = np.asarray(d, dtype=np.float64)
    o = np.broadcast_to(np.asarray(o, dtype=np.float64), d.shape)
    best_t = np.array(np.broadcast_to(t_hi, (d.shape[0],)), dtype=np.float64)
    best_i = np.full(d.shape[0], -1, dtype=np.int64)
    for k in range(len(planes.radius)):
        n = planes.normal[k]
        with np.errstate(invalid="ignore", divide="ignore"):
            t = ((planes.point[k] - o) @ n) / (d @ n)
        rel = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - planes.centre[k]
        inside = np.einsum("ij,ij->i", rel, rel) <= planes.radius[k] ** 2
        better = inside & (t > t_lo) & (t < best_t)
        best_t = np.where(better, t, best_t)
        best_i = np.where(better, k, best_i)
    best_t[best_i < 0] = np.inf
    return best_t, best_i


def intersect_boxes(boxes: BoxArrays, o, d, t_lo, t_hi):
    """Closest box hit with t_lo < t < t_hi: (t (N,), box index (N,), axis (N,) of the face
    hit in object space), inf / −1 on a miss. In the box's object space, o' = M⁻¹·(o, 1),
    d' = M⁻¹·(d, 0) (not unit: the same t); per axis the slab (lo_k − o'_k)/d'_k …
    (hi_k − o'_k)/d'_k, near = the largest entry, far = the smallest exit; the hit is near
    when it is past t_lo, else far (a ray from inside sees the inside), on the face of the
    axis that set it."""
    d = np.asarray(d, dtype=np.float64)
    o = np.broadcast_to(np.asarray(o, dtype=np.float64), d.shape)
    best_t = np.array(np.broadcast_to(t_hi, (d.shape[0],)), dtype=np.float64)
    best_i = np.full(d.shape[0], -1, dtype=np.int64)
    best_axis = np.zeros(d.shape[0], dtype=np.int64)
    for k in range(len(boxes.lo)):
        m = boxes.from_world[k]
        ob = o @ m[:, :3].T + m[:, 3]
        db = d @ m[:, :3].T
        with np.errstate(invalid="ignore", divide="ignore"):
            t0 = (boxes.lo[k] - ob) / db
            t1 = (boxes.hi[k] - ob) / db
        enter, leave = np.minimum(t0, t1), np.maximum(t0, t1)
        near, far = enter.max(axis=1), leave.min(axis=1)
        from_near = near > t_lo
        t = np.where(from_near, near, far)
        axis = np.where(from_near, enter.argmax(axis=1), leave.argmin(axis=1))
        better = (near <= far) & (t > t_lo) & (t < best_t)      # NaN compares False
        best_t = np.where(better, t, best_t)
        best_i = np.where(better, k, best_i)
        best_axis = np.where(better, axis, best_axis)
    best_t[best_i < 0] = np.inf
    return best_t, best_i, best_axis


def occluded(prep: PreparedScene, o, d, t_max):
    """``shadowHit`` over every shape: does any shape meet the ray at t in (0, t_max)?
    Spheres first (:func:`shadow_hit`), then planes, boxes and the meshes (any hit), each
    testing only the rays no earlier shape blocked. Returns a bool (N,)."""
    blocked = shadow_hit(prep.centers, prep.radii, o, d, t_max)
    if prep.spheres_only:
        return blocked
    o, d = np.asarray(o, dtype=np.float64), np.asarray(d, dtype=np.float64)
    t_max = np.asarray(t_max, dtype=np.float64)
    live = np.flatnonzero(~blocked)
    tests = []
    if prep.planes is not None:
        tests.append(lambda oo, dd, tm: intersect_planes(prep.planes, oo, dd, 0.0, tm)[1] >= 0)
    if prep.boxes is not None:
        tests.append(lambda oo, dd, tm: intersect_boxes(prep.boxes, oo, dd, 0.0, tm)[1] >= 0)
    if prep.meshes is not None:
        tests.append(prep.meshes.bvh.any_hit)
    for test in tests:
        if live.size == 0:
            break
        hit_s = test(o[live], d[live], t_max[live])
        blocked[live[hit_s]] = True
        live = live[~hit_s]
    return blocked


# ---------------------------------------------------------------------------
# Area lights: their fixed sample patterns

@dataclass(frozen=True)
class AreaSamples:
    """An area light's pattern: ``offsets`` (N, 2) of sample k = b·n + a; for a rectangle
    ``edges`` (axis1, axis2), for a sphere ``radius`` and its frame (``w0``, ``f``)."""

    kind: str                       # "rectangle" or "sphere"
    center: np.ndarray              # (3,)
    offsets: np.ndarray             # (N, 2)
    color: np.ndarray               # (3,) each sample's: the light's colour / N
    edges: np.ndarray | None = None     # (2, 3), a rectangle's
    radius: float = 0.0
    w0: np.ndarray | None = None    # (3,) a sphere's: unit, centre towards the look-at
    f: np.ndarray | None = None     # (3,) a sphere's: unit, perpendicular to w0


def _stratum_centres(n: int):
    """(a, b) of sample k = b·n + a, as float arrays, centres (a + ½)/n, (b + ½)/n."""
    k = np.arange(n * n)
    return ((k % n) + 0.5) / n, ((k // n) + 0.5) / n


def _concentric_disk(u, v):
    """Shirley & Chiu's concentric map of [−1, 1]² onto the unit disk: r = u,
    φ = (π/4)·v/u where |u| > |v|, else r = v, φ = π/2 − (π/4)·u/v; (0, 0) stays."""
    u, v = np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
    wide = np.abs(u) > np.abs(v)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(wide, u, v)
        phi = np.where(wide, (np.pi / 4) * (v / u), np.pi / 2 - (np.pi / 4) * (u / v))
    centre = (u == 0.0) & (v == 0.0)
    x = np.where(centre, 0.0, r * np.cos(phi))
    y = np.where(centre, 0.0, r * np.sin(phi))
    return np.stack([x, y], axis=-1)


def area_samples(light, lookat) -> AreaSamples:
    """The fixed part of an area light's n×n pattern (docs/rendering-model.md, "Area
    lights"). A sphere's frame: w0 = normalize(lookat − centre) ((0, 0, −1) if they
    coincide); f = the world axis of w0's smallest |component| (the first of equals),
    minus its part along w0, normalised."""
    area = light.area
    n = samples_per_axis(area.samples)
    centre = np.array(light.position, dtype=np.float64)
    color = np.array(light.color, dtype=np.float64) / (n * n)
    a, b = _stratum_centres(n)
    if hasattr(area, "axis1"):
        return AreaSamples("rectangle", centre, np.stack([a - 0.5, b - 0.5], axis=-1), color,
                           edges=np.array([area.axis1, area.axis2], dtype=np.float64))
    w0 = np.array(lookat, dtype=np.float64) - centre
    norm = np.linalg.norm(w0)
    w0 = w0 / norm if norm > 0 else np.array([0.0, 0.0, -1.0])
    f = np.eye(3)[int(np.argmin(np.abs(w0)))]
    f = f - np.dot(f, w0) * w0
    return AreaSamples("sphere", centre, _concentric_disk(2.0 * a - 1.0, 2.0 * b - 1.0), color,
                       radius=float(area.radius), w0=w0, f=f / np.linalg.norm(f))


def area_sample_points(pattern: AreaSamples, p: np.ndarray) -> np.ndarray:
    """The sample points seen from hit points p (k, 3): (N, k, 3). A rectangle's are the
    same for every p; a sphere's disk faces each p: centre + R·(x·t + y·b), w the unit
    vector from the centre to p, t = normalize(f − (f·w)·w) (w0 in place of f where
    |f − (f·w)·w|² ≤ 1e-12), b = w × t; the centre itself where p is the centre."""
    p = np.asarray(p, dtype=np.float64).reshape(-1, 3)
    if pattern.kind == "rectangle":
        points = pattern.center + pattern.offsets @ pattern.edges          # (N, 3)
        return np.broadcast_to(points[:, None, :], (len(points), len(p), 3))
    rel = p - pattern.center
    length2 = np.einsum("ij,ij->i", rel, rel)
    away = length2 > 0.0
    w = rel / np.sqrt(np.where(away, length2, 1.0))[:, None]
    t = pattern.f - np.einsum("ij,j->i", w, pattern.f)[:, None] * w
    near = np.einsum("ij,ij->i", t, t) <= 1e-12
    t[near] = pattern.w0 - np.einsum("ij,j->i", w[near], pattern.w0)[:, None] * w[near]
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(w, t)
    e1 = np.where(away[:, None], pattern.radius * t, 0.0)
    e2 = np.where(away[:, None], pattern.radius * b, 0.0)
    x, y = pattern.offsets[:, 0], pattern.offsets[:, 1]
    return pattern.center + x[:, None, None] * e1[None] + y[:, None, None] * e2[None]


@dataclass
class HitRecord:
    """What :func:`hit` passes back for a batch of rays (the paper's hit record).

    Arrays over the rays that hit (``index`` gives their positions in the
    batch): distance ``t``, point ``p``, unit normal ``n`` facing the viewer
    (two-sided), view vector ``v`` = −d, the shape hit (``shape``: its index in
    ``scene.shapes()`` order; ``sphere``: the sphere's index, −1 for other shapes;
    ``triangle``: a mesh's triangle in the scene's hierarchy, −1 for other shapes, with
    ``bary`` its barycentrics (b₁, b₂) of vertices 1 and 2), the material hit, and, once
    :func:`fill_channels` has run, the channel colours ``colors[slot]``
    ((k, 3), or None when no hit material has that component).
    """

    count: int                      # rays in the batch
    index: np.ndarray               # (k,) positions of the hitting rays
    t: np.ndarray                   # (k,)
    p: np.ndarray                   # (k, 3)
    n: np.ndarray                   # (k, 3)
    v: np.ndarray                   # (k, 3)
    sphere: np.ndarray              # (k,)
    material: np.ndarray            # (k,)
    shape: np.ndarray | None = None     # (k,) global shape index
    triangle: np.ndarray | None = None  # (k,) −1 off meshes
    bary: np.ndarray | None = None      # (k, 2)
    colors: dict = field(default_factory=dict)


def closest_hit(prep: PreparedScene, o, d) -> HitRecord:
    """Geometry of the closest hit of each ray over every shape (no colours yet)."""
    o = np.asarray(o, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    t_min = T_MIN_REL * (1.0 + np.max(np.abs(o), axis=-1))
    t, s = intersect_spheres(prep.centers, prep.radii, o, d, t_min)
    if not prep.spheres_only:
        return _closest_of_all(prep, o, d, t_min, t, s)
    idx = np.nonzero(s >= 0)[0]
    t, s = t[idx], s[idx]
    dd = d[idx]
    oo = o[idx] if o.ndim == 2 else o
    p = oo + t[:, None] * dd
    n = (p - prep.centers[s]) / prep.radii[s][:, None]
    v = -dd
    flip = np.einsum("ij,ij->i", n, v) < 0.0
    n[flip] = -n[flip]
    return HitRecord(count=d.shape[0], index=idx, t=t, p=p, n=n, v=v, sphere=s,
                     material=prep.sphere_material[s], shape=s,
                     triangle=np.full(len(s), -1, dtype=np.int64), bary=np.zeros((len(s), 2)))


def _closest_of_all(prep: PreparedScene, o, d, t_min, t, s) -> HitRecord:
    """closest_hit past the spheres (their t, s given): planes, boxes, meshes; the point
    p = o + t·d and each kind's normal as in the spheres-only path."""
    n_rays = d.shape[0]
    shape = s.copy()                                  # global index; spheres' are theirs
    axis = np.zeros(n_rays, dtype=np.int64)
    tri = np.full(n_rays, -1, dtype=np.int64)
    bary = np.zeros((n_rays, 2))
    if prep.planes is not None:
        tp, ip = intersect_planes(prep.planes, o, d, t_min, t)
        closer = ip >= 0
        t, shape = np.where(closer, tp, t), np.where(closer, prep.first_plane + ip, shape)
    if prep.boxes is not None:
        tb, ib, ab = intersect_boxes(prep.boxes, o, d, t_min, t)
        closer = ib >= 0
        t, shape = np.where(closer, tb, t), np.where(closer, prep.first_box + ib, shape)
        axis = np.where(closer, ab, axis)
    if prep.meshes is not None:
        tm, it, b1, b2 = prep.meshes.bvh.closest(o, d, t_min, t)
        closer = it >= 0
        t = np.where(closer, tm, t)
        shape = np.where(closer, prep.meshes.triangle_shape[np.maximum(it, 0)], shape)
        tri = np.where(closer, it, -1)
        bary = np.where(closer[:, None], np.stack([b1, b2], axis=1), 0.0)
    idx = np.nonzero(shape >= 0)[0]
    t, shape, axis, tri, bary = t[idx], shape[idx], axis[idx], tri[idx], bary[idx]
    dd = d[idx]
    oo = o[idx] if o.ndim == 2 else o
    p = oo + t[:, None] * dd
    n = np.empty_like(p)
    sphere = np.where(shape < prep.first_plane, shape, -1)
    on = sphere >= 0
    n[on] = (p[on] - prep.centers[sphere[on]]) / prep.radii[sphere[on]][:, None]
    if prep.planes is not None:
        on = (shape >= prep.first_plane) & (shape < prep.first_box)
        n[on] = prep.planes.normal[shape[on] - prep.first_plane]
    if prep.boxes is not None:
        on = (shape >= prep.first_box) & (shape < prep.first_box + len(prep.boxes.lo))
        # The face's object normal ±e_k to the world by (M⁻¹)ᵀ: row k of M⁻¹'s linear part.
        n[on] = _normalize(prep.boxes.from_world[shape[on] - prep.first_box, axis[on], :3])
    on = tri >= 0
    if on.any():
        corners = prep.meshes.positions[prep.meshes.triangles[tri[on]]]     # (k, 3, 3)
        n[on] = _normalize(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
    v = -dd
    flip = np.einsum("ij,ij->i", n, v) < 0.0
    n[flip] = -n[flip]
    return HitRecord(count=n_rays, index=idx, t=t, p=p, n=n, v=v, sphere=sphere,
                     material=prep.shape_material[shape], shape=shape, triangle=tri, bary=bary)


def hit_uv(prep: PreparedScene, rec: HitRecord) -> np.ndarray:
    """(u, v) of every hit (k, 2): a sphere's Mitsuba sphere (u, v) from its centre and
    radius; a mesh's vertex texture coordinates interpolated, (1 − b₁ − b₂)·uv₀ + b₁·uv₁ +
    b₂·uv₂ (as Mitsuba's mesh interpolates them); NaN for shapes without (u, v)
    (prepare refuses image maps on them)."""
    if prep.spheres_only:
        return sphere_uv(rec.p, prep.centers[rec.sphere], prep.radii[rec.sphere])
    uv = np.full((rec.index.size, 2), np.nan)
    on = rec.sphere >= 0
    uv[on] = sphere_uv(rec.p[on], prep.centers[rec.sphere[on]], prep.radii[rec.sphere[on]])
    on = rec.triangle >= 0
    if on.any() and prep.meshes.uv is not None:
        corner = prep.meshes.uv[prep.meshes.triangles[rec.triangle[on]]]     # (k, 3, 2)
        b1, b2 = rec.bary[on, 0:1], rec.bary[on, 1:2]
        uv[on] = (1.0 - b1 - b2) * corner[:, 0] + b1 * corner[:, 1] + b2 * corner[:, 2]
    return uv


def object_points(prep: PreparedScene, rec: HitRecord) -> np.ndarray:
    """Every hit point in the object space of the shape hit, object_to_world(shape)⁻¹·p
    (k, 3), float64 (needs ``prep.from_world``: a scene with an object-space marble)."""
    m = prep.from_world[rec.shape]                                           # (k, 3, 4)
    return np.einsum("kij,kj->ki", m[:, :, :3], rec.p) + m[:, :, 3]


def fill_channels(prep: PreparedScene, rec: HitRecord, needed: dict) -> HitRecord:
    """Evaluate the channel colours into ``rec.colors`` ("passing back").

    ``needed[slot]`` is a bool (k,) mask of the hits where that component's
    value is used (elsewhere it is left 0). Each distinct channel is evaluated
    once, on the union of the points where any slot of any material uses it;
    image maps read the hit shape's (u, v) (:func:`hit_uv`), ``space object`` marbles
    the hit point in the hit shape's object space (:func:`object_points`).
    """
    k = rec.index.size
    slot_ch = prep.slot_channel[rec.material] if k else np.empty((0, 3), dtype=np.int64)
    want = {}                                   # channel index -> bool mask (k,)
    for s, slot in enumerate(SLOTS):
        mask = needed.get(slot)
        if mask is None:
            continue
        for c in np.unique(slot_ch[mask, s]):
            if c < 0:
                continue
            m = mask & (slot_ch[:, s] == c)
            want[c] = want[c] | m if c in want else m
    uv = hit_uv(prep, rec) if any(needs_uv(prep.channels[c]) for c in want) else None
    local = object_points(prep, rec) if prep.from_world is not None else None
    values = {}
    for c, m in want.items():
        full = np.zeros((k, 3))
        full[m] = channel_color(prep.channels[c], rec.p[m], None if uv is None else uv[m],
                                None if local is None else local[m])
        values[c] = full
    for s, slot in enumerate(SLOTS):
        mask = needed.get(slot)
        if mask is None or not any(c in values for c in np.unique(slot_ch[mask, s])):
            rec.colors[slot] = None
            continue
        out = np.zeros((k, 3))
        for c in np.unique(slot_ch[mask, s]):
            if c >= 0:
                m = mask & (slot_ch[:, s] == c)
                out[m] = values[c][m]
        rec.colors[slot] = out
    return rec


def hit(prep: PreparedScene, o, d) -> HitRecord:
    """Closest hit with every present channel's colour at every hit point."""
    prep = _as_prepared(prep)
    rec = closest_hit(prep, o, d)
    everywhere = np.ones(rec.index.size, dtype=bool)
    return fill_channels(prep, rec, {slot: everywhere for slot in SLOTS})


# ---------------------------------------------------------------------------
# Shading

def shade(prep: PreparedScene, rec: HitRecord) -> np.ndarray:
    """Radiance of every ray of the batch (N, 3): background on a miss, else the formula.

    Computes visibility first, so that channels are evaluated only where used:
    ka where A ≠ 0, kd and ks where at least one light is visible.
    """
    out = np.broadcast_to(prep.background, (rec.count, 3)).copy()
    k = rec.index.size
    if k == 0:
        return out
    p, n, v = rec.p, rec.n, rec.v
    eps = EPS_REL * (1.0 + np.max(np.abs(p), axis=1))
    p_shadow = p + eps[:, None] * n

    lights = []                                 # (l_index, visible mask, n·l, n·h)
    areas = []                                  # (Σ I·n·l, Σ I·(n·h)^s) over visible samples
    any_visible = np.zeros(k, dtype=bool)
    shin = prep.shininess[rec.material]
    for li in range(len(prep.light_positions)):
        pattern = prep.light_areas[li] if prep.light_areas else None
        if pattern is not None:
            sums = _area_light(prep, pattern, p, n, v, p_shadow, shin)
            if sums is not None:
                areas.append(sums[1:])
                any_visible |= sums[0]
            continue
        lp = prep.light_positions[li]
        l_hat = _normalize(lp - p)
        ndotl = np.einsum("ij,ij->i", n, l_hat)
        front = np.nonzero(ndotl > 0.0)[0]
        visible = np.zeros(k, dtype=bool)
        if front.size:
            seg = lp - p_shadow[front]
            dist = np.linalg.norm(seg, axis=1)
            blocked = occluded(prep, p_shadow[front], seg / dist[:, None], dist)
            visible[front[~blocked]] = True
        if not visible.any():
            continue
        h_hat = _normalize(l_hat + v)
        ndoth = np.einsum("ij,ij->i", n, h_hat)
        lights.append((li, visible, ndotl, ndoth))
        any_visible |= visible

    needed = {}
    if np.any(prep.ambient != 0.0):
        needed["ambient"] = np.ones(k, dtype=bool)
    if lights or areas:
        needed["diffuse"] = any_visible
        needed["specular"] = any_visible
    fill_channels(prep, rec, needed)
    ka, kd, ks = (rec.colors.get(s) for s in SLOTS)

    L = np.zeros((k, 3))
    if ka is not None:
        L += ka * prep.ambient
    if kd is not None or ks is not None:
        for diffuse_sum, specular_sum in areas:
            if kd is not None:
                L += kd * diffuse_sum
            if ks is not None:
                L += ks * specular_sum
        for li, visible, ndotl, ndoth in lights:
            term = np.zeros((k, 3))
            if kd is not None:
                term += kd * np.maximum(0.0, ndotl)[:, None]
            if ks is not None:
                term += ks * (np.maximum(0.0, ndoth) ** shin)[:, None]
            L += np.where(visible[:, None], prep.light_colors[li] * term, 0.0)
    out[rec.index] = L
    return out


def _area_light(prep: PreparedScene, pattern: AreaSamples, p, n, v, p_shadow, shin):
    """An area light's samples at hit points p, each a point light of colour I/N:
    (visible to some sample (k,), Σ_s V_s·I_s·max(0, n·l̂_s) (k, 3),
    Σ_s V_s·I_s·max(0, n·ĥ_s)^shininess (k, 3)), or None when no sample is visible."""
    k = len(p)
    seen = np.zeros(k, dtype=bool)
    diffuse_sum = np.zeros(k)
    specular_sum = np.zeros(k)
    for lp in area_sample_points(pattern, p):        # (k, 3) each
        l_hat = _normalize(lp - p)
        ndotl = np.einsum("ij,ij->i", n, l_hat)
        front = np.nonzero(ndotl > 0.0)[0]
        if front.size == 0:
            continue
        seg = lp[front] - p_shadow[front]
        dist = np.linalg.norm(seg, axis=1)
        blocked = occluded(prep, p_shadow[front], seg / dist[:, None], dist)
        lit = front[~blocked]
        if lit.size == 0:
            continue
        seen[lit] = True
        diffuse_sum[lit] += ndotl[lit]
        ndoth = np.einsum("ij,ij->i", n[lit], _normalize(l_hat[lit] + v[lit]))
        specular_sum[lit] += np.maximum(0.0, ndoth) ** shin[lit]
    if not seen.any():
        return None
    return seen, diffuse_sum[:, None] * pattern.color, specular_sum[:, None] * pattern.color


def trace(scene, o, d) -> np.ndarray:
    """Radiance along rays (o (3,) or (N, 3), unit d (N, 3)) -> (N, 3)."""
    prep = _as_prepared(scene)
    d = np.asarray(d, dtype=np.float64).reshape(-1, 3)
    return shade(prep, closest_hit(prep, o, d))


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
        rad = shade(prep, closest_hit(prep, eye, d))
        out[p0:p1] = rad.reshape(p1 - p0, ns, 3).mean(axis=1)
        if progress is not None:
            progress(p1 * ns, H * W * ns)
    return out.reshape(H, W, 3)
