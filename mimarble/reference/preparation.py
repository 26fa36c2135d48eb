"""The scene prepared for the reference tracer: shapes and lights as float64 arrays, the camera's rays.

:func:`prepare` reads a :class:`~mimarble.scene.model.Scene` once into a
:class:`PreparedScene` (spheres, planes, boxes and the meshes' triangle hierarchy, the
lights and the fixed sample patterns of the area lights, each shape's material and
object-space transform), checking what only a render needs (mesh files, uv for image
maps); :func:`camera_rays` and :func:`sample_positions` give the primary rays of the
rendering model's camera at n×n stratum centres (docs/rendering-model.md; :mod:`.tracer`
sums the model up).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mimarble.scene import geometry
from mimarble.scene.errors import SceneError
from mimarble.scene.limits import MAX_MESH_TRIANGLES
from mimarble.meshes.facts import mesh_facts
from mimarble.meshes.limits import MeshFileError
from mimarble.scene.model import Scene, in_object_space, samples_per_axis
from mimarble.scene.rules import shortened
from mimarble.scene.shapes import SHAPE_KINDS, kind_of

from .channels import needs_uv
from .environment import EnvironmentLookup
from mimarble.meshes.arrays import read_mesh
from .vertex_normals import angle_weighted_normals, placed_normals
from .shapes import REFERENCE_SHAPES, from_world_rows, normalize_rows
from .triangles import TriangleBVH

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
    # (keyword, first, count, arrays) of each kind present that reference/shapes.py
    # intersects (planes, boxes), in the scene's order; ``first`` is the global shape
    # index of its shape 0 (spheres come first, then planes, boxes, meshes: SHAPE_KINDS).
    kinds: tuple = ()
    meshes: "MeshArrays | None" = None
    from_world: np.ndarray | None = None       # (n, 3, 4): object_to_world⁻¹, when needed
    environment: "EnvironmentLookup | None" = None   # the scene's, loaded: misses see it

    @property
    def spheres_only(self) -> bool:
        return not self.kinds and self.meshes is None


@dataclass(frozen=True)
class MeshArrays:
    """Every mesh's triangles in world space, one hierarchy: ``triangles`` index
    ``positions`` (and ``uv``, NaN rows for a mesh without texture coordinates; and
    ``normals``, the unit world vertex normals of the smooth meshes, NaN rows for the
    flat ones: vertex_normals.py); ``triangle_shape`` is each triangle's global shape
    index, ``smooth`` whether it is a smooth mesh's (None: no mesh is)."""

    bvh: TriangleBVH
    positions: np.ndarray          # (V, 3) world
    triangles: np.ndarray          # (T, 3) int64
    triangle_shape: np.ndarray     # (T,) int64
    uv: np.ndarray | None          # (V, 2), or None when no mesh has texture coordinates
    normals: np.ndarray | None = None   # (V, 3), or None when no mesh is smooth
    smooth: np.ndarray | None = None    # (T,) bool, or None when no mesh is smooth


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
        if mesh.smooth:             # incomplete normals (an OBJ's): the parser's refusal
            problem = mesh_facts(mesh.location).normals_problem
            if problem:
                raise refused(mesh, problem)
        total += len(data.triangles)
        if total > MAX_MESH_TRIANGLES:
            raise refused(mesh, over(total))
        out.append(data)
    return tuple(out)


def _mesh_arrays(scene: Scene, meshes: tuple, first: int) -> MeshArrays | None:
    """The meshes' vertices placed in the world, p_world = M·(p, 1) in float64, and one
    hierarchy over all their triangles; ``first`` is mesh 0's global shape index."""
    if not scene.meshes:
        return None
    positions, triangles, shape, uvs, normals, smooth = [], [], [], [], [], []
    offset = 0
    for k, (mesh, data) in enumerate(zip(scene.meshes, meshes)):
        m = np.array(geometry.object_to_world(mesh), dtype=np.float64)
        placed = data.positions @ m[:3, :3].T + m[:3, 3]
        positions.append(placed)
        triangles.append(data.triangles + offset)
        shape.append(np.full(len(data.triangles), first + k, dtype=np.int64))
        uvs.append(data.uv if data.uv is not None else np.full((len(data.positions), 2), np.nan))
        is_smooth = mesh.is_smooth(data.normals is not None)
        smooth.append(np.full(len(data.triangles), is_smooth))
        normals.append(np.full((len(data.positions), 3), np.nan) if not is_smooth
                       else placed_normals(data.normals, m) if data.normals is not None
                       else angle_weighted_normals(placed, data.triangles))
        offset += len(data.positions)
    positions = np.concatenate(positions)
    triangles = np.concatenate(triangles)
    corners = positions[triangles]                       # (T, 3, 3)
    bvh = TriangleBVH(corners[:, 0], corners[:, 1], corners[:, 2])
    del corners
    uv = np.concatenate(uvs) if any(d.uv is not None for d in meshes) else None
    smooth = np.concatenate(smooth)
    return MeshArrays(bvh=bvh, positions=positions, triangles=triangles,
                      triangle_shape=np.concatenate(shape), uv=uv,
                      normals=np.concatenate(normals) if smooth.any() else None,
                      smooth=smooth if smooth.any() else None)


def _check_uv(scene: Scene, meshes: tuple) -> None:
    """A material with an image map shades only shapes with (u, v): spheres and meshes
    whose file has texture coordinates (the parser says so at the shape; a scene built in
    Python hears it here)."""
    has_uv = {f"mesh_{k}": data.uv is not None for k, data in enumerate(meshes)}
    for shape_id, shape in scene.shapes():
        if kind_of(shape).without_uv is None or has_uv.get(shape_id):
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
    return from_world_rows([shape for _, shape in scene.shapes()])


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
    first, kinds, count = {}, [], 0
    for kind in SHAPE_KINDS:               # each kind's first global index, in the scene's order
        shapes, arrays = getattr(scene, kind.plural), REFERENCE_SHAPES[kind.keyword].arrays
        first[kind.keyword] = count
        if shapes and arrays is not None:
            kinds.append((kind.keyword, count, len(shapes), arrays(scene, shapes)))
        count += len(shapes)
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
        kinds=tuple(kinds),
        meshes=_mesh_arrays(scene, meshes, first["mesh"]),
        from_world=_object_space(scene, tuple(channels)),
        environment=None if scene.environment is None else EnvironmentLookup(scene.environment,
                                                                            scene.source),
    )


def as_prepared(scene) -> PreparedScene:
    """``scene`` if it is a :class:`PreparedScene` already, else :func:`prepare` of it."""
    return scene if isinstance(scene, PreparedScene) else prepare(scene)


# ---------------------------------------------------------------------------
# Camera and sampling

def camera_basis(camera, aspect: float):
    """(eye, f, r, u, tan_half, aspect) of the pinhole camera, float64."""
    eye = np.array(camera.eye, dtype=np.float64)
    f = normalize_rows(np.array(camera.lookat, dtype=np.float64) - eye)
    r = normalize_rows(np.cross(f, np.array(camera.up, dtype=np.float64)))
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
    return eye, normalize_rows(d)


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
