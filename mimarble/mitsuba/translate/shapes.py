"""Each kind of shape as Mitsuba sees it: its shape dict, its reach for the clip planes, its float32 range checks.

:data:`MITSUBA_SHAPES` holds one :class:`MitsubaShape` per kind of
:data:`~mimarble.scene.shape_kinds.SHAPE_KINDS`, by keyword: a sphere → ``sphere``, a
plane → ``disk`` (the disk it is rendered as, ``geometry.plane_disk``), a box →
``cube``, a mesh → ``ply``/``obj`` (:func:`shape_dict`). A bounded kind's reach and
float32 checks default to those of its eight world corners (``shape.corners()``), so a
new kind needs its dict alone. :func:`clip_planes` and :func:`float32_range_problems`
walk the kinds in the scene's order; the translator (scene_dict.py) places each shape
under the id ``Scene.shapes()`` gives it.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mimarble.contract import FLOAT32_EPSILON, T_MIN_REL
from mimarble.scene import geometry, model
from mimarble.scene.rules import cross
from mimarble.scene.shape_kinds import SHAPE_KINDS, kind_of

# The reference tracer accepts hits from t = T_MIN_REL·(1 + max|eye_k|) on.
_NEAREST_HIT_REL = T_MIN_REL


def _box_distance(point, corners) -> float:
    """The distance from ``point`` to the axis-aligned box around ``corners`` (0 inside)."""
    gaps = [max(min(c[i] for c in corners) - point[i], 0.0, point[i] - max(c[i] for c in corners))
            for i in range(3)]
    return math.sqrt(math.fsum(g * g for g in gaps))


def _sphere_reach(scene: model.Scene, sphere) -> tuple[float, float]:
    d = math.dist(sphere.center, scene.camera.eye)
    return abs(d - sphere.radius), d + sphere.radius


def _disk_reach(scene: model.Scene, plane) -> tuple[float, float]:
    centre, radius = geometry.plane_disk(scene, plane)
    height = math.dist(centre, scene.camera.eye)       # the disk's centre is the eye's foot on it
    return height, math.hypot(height, radius)          # its rim


def _corner_reach(scene: model.Scene, shape) -> tuple[float, float]:
    """Between the eye's distance to the axis-aligned box around its world corners and its
    farthest corner."""
    eye = scene.camera.eye
    corners = shape.corners()
    return _box_distance(eye, corners), max(math.dist(c, eye) for c in corners)


def _shape_reach(scene: model.Scene) -> tuple[list[float], list[float]]:
    """(nearest, farthest): for every shape of a kind whose reach is known before Mitsuba
    loads it (all but the meshes), how near to the eye its surface may come and how far
    from it it reaches (``clip_planes``)."""
    nearest, farthest = [], []
    for kind in SHAPE_KINDS:
        reach = MITSUBA_SHAPES[kind.keyword].reach
        for shape in getattr(scene, kind.plural):
            near, far = reach(scene, shape)
            nearest.append(near)
            farthest.append(far)
    return nearest, farthest


def clip_planes(scene: model.Scene) -> tuple[float, float]:
    """(near_clip, far_clip) that keep every shape in view.

    Mitsuba's defaults (0.01, 10 000) drop geometry the scene language allows.
    A sphere of centre c and radius r lies between ||c − e| − r| and |c − e| + r
    of the eye e (inside it too); a plane, rendered as a disk of radius R around the
    eye's foot on it (``geometry.plane_disk``), between the eye's height h above it and
    √(h² + R²), its rim; a box between the eye's distance to its world bounding box (0
    inside) and its farthest corner. So: far just past the farthest of these, near half
    the nearest — never below the reference tracer's smallest hit distance, so an eye on
    a surface still sees what the reference sees. A mesh's vertices are in its file, not
    known before Mitsuba loads it: a scene with meshes gets that floor as its near and
    the cap below as its far (which costs nothing, see next).

    How ``perspective`` uses them (src/sensors/perspective.cpp): a ray starts on
    the near plane, o = e + d·near/d_z, with maxt = (far − near)/d_z, and its
    direction comes from the inverse projection, which Mitsuba writes down in
    closed form (``Transform::perspective``): a film point maps to
    (x·tan·near, y·tan·near, near), then normalised, so the ratio far/near costs
    no precision however large it is. What float32 does not tolerate is an
    infinite far (> 3.4e38): the inverse's term (near − far)/(far·near) becomes
    inf/inf = NaN and so does every ray. So far is capped at 2¹²⁵ (4.3e37); only
    a shape beyond Embree's ±1.8e18 (warned about below) gets near it. Near is
    at least 1e-6, far at least 2·near, both normal float32 numbers.
    """
    eye = scene.camera.eye
    if not scene.shapes():
        return 0.01, 1e4   # Mitsuba's defaults: nothing to see either way
    floor = _NEAREST_HIT_REL * (1.0 + max(map(abs, eye)))
    if any(MITSUBA_SHAPES[kind.keyword].reach is None and getattr(scene, kind.plural)
           for kind in SHAPE_KINDS):         # a mesh's reach: unknown before Mitsuba loads it
        return floor, _FAR_CLIP_MAX
    nearest, farthest = _shape_reach(scene)
    near = max(0.5 * min(nearest), floor)
    far = min(max(max(farthest) * (1.0 + 1e-3), 2.0 * near), _FAR_CLIP_MAX)
    return near, far


#: The largest far_clip (see clip_planes): finite in float32 with room to spare.
_FAR_CLIP_MAX = 2.0 ** 125


class Float32RangeWarning(UserWarning):
    """A shape, eye or light beyond what Mitsuba's float32 (and Embree's) arithmetic reaches."""


# float32's unit roundoff·2: the scale of Mitsuba's intersection error on a sphere is
# 2⁻²³·(max|c_k| + r). Measured (docs/rendering-model.md, "Large spheres"): a ground sphere
# agrees with the reference while that error is up to 1.6× the eye's distance to the
# surface, and fails from 3.2× on; the warning comes from 1×.
_FLOAT32_ERROR_SCALE = FLOAT32_EPSILON

# Embree, Mitsuba's ray tracer in the scalar and LLVM variants, takes coordinates only in
# ±1.844e18 (its FLT_LARGE): a sphere whose bounding box reaches past it is dropped, and a
# ray from beyond it meets nothing (measured: radius 1.8e18 at the origin is hit, 1.85e18
# is not). Warned from 1.8e18.
_EMBREE_LIMIT = 1.8e18

# A point light's weight I/d² is a float32 below 2⁻¹²⁶ (flushed to zero) once d ≥ 2⁶³
# ≈ 9.2e18: the light then lights nothing (measured: 6.1e18 right, 9.8e18 dark). Warned
# from 2⁶² (a light's distance to the farthest point of any sphere).
_LIGHT_DISTANCE_LIMIT = 2.0 ** 62


# A triangle's normal is normalize(e₁ × e₂) in float32: its squared length overflows once
# |e₁ × e₂| (twice the triangle's area) reaches √FLT_MAX ≈ 1.8e19, and the normal is 0.
_FACE_LIMIT = 2.0 ** 64


def _where(scene: model.Scene, node) -> str:
    return f"{scene.source or '<scene>'}:{node.pos or '?'}"


def _reach_problem(where: str, what: str, extent: float, placed: float, error: float,
                   distance: float | None) -> str | None:
    """The message of one shape (``what``) reaching ``extent`` from the origin (its
    coordinates' largest magnitude ``placed``), whose float32 placement error ``error``
    may reach the eye's distance to it (None: not checked): Embree's range first."""
    if extent > _EMBREE_LIMIT:
        return (f"{where}: {what} reaches {extent:g} from the origin, beyond ±{_EMBREE_LIMIT:g}, "
                f"the coordinates Mitsuba's CPU ray tracer (Embree) accepts: Mitsuba drops it "
                f"(docs/rendering-model.md)")
    if distance is not None and error > distance:
        return (f"{where}: {what} at {placed:g} from the origin is beyond float32's reach from "
                f"this eye: Mitsuba's intersection error (~{error:.3g}) exceeds the eye's distance "
                f"to its surface ({distance:.3g}), so the Mitsuba image may be wrong there (the "
                f"reference tracer is float64; docs/rendering-model.md)")
    return None


def _largest(v) -> float:
    return max(map(abs, v))


def _sphere_problems(scene: model.Scene, sphere) -> tuple[list, list]:
    extent = _largest(sphere.center) + sphere.radius
    problem = _reach_problem(
        _where(scene, sphere), f"sphere of radius {sphere.radius:g}", extent,
        _largest(sphere.center), _FLOAT32_ERROR_SCALE * extent,
        abs(math.dist(sphere.center, scene.camera.eye) - sphere.radius))
    return [problem], [(sphere.center, sphere.radius)]


def _disk_problems(scene: model.Scene, plane) -> tuple[list, list]:
    centre, radius = geometry.plane_disk(scene, plane)
    problem = _reach_problem(
        _where(scene, plane), f"plane (rendered as a disk of radius {radius:.3g})",
        _largest(centre) + radius, _largest(centre), _FLOAT32_ERROR_SCALE * _largest(centre),
        math.dist(centre, scene.camera.eye))
    return [problem], [(centre, 0.0)]


def _corner_problems(scene: model.Scene, shape) -> tuple[list, list]:
    """A bounded shape by its eight world corners (a mesh file unread: its transform's
    origin), named by its keyword."""
    corners = shape.corners()
    if corners is None:                 # a mesh file unread: its transform's origin
        corners = [shape.bounds()[0]]
    extent = max(map(_largest, corners))
    distance = _box_distance(scene.camera.eye, corners) if len(corners) == 8 else 0.0
    problem = _reach_problem(_where(scene, shape), kind_of(shape).keyword, extent,
                             extent, _FLOAT32_ERROR_SCALE * extent,
                             distance if distance > 0 else None)
    return [problem], [(corner, 0.0) for corner in corners]


def _box_problems(scene: model.Scene, box) -> tuple[list, list]:
    """Its corners', then a face so large that Mitsuba's float32 normal of it overflows."""
    problems, lit = _corner_problems(scene, box)
    corners = [corner for corner, _ in lit]
    edges = [[a - b for a, b in zip(corners[k], corners[0])] for k in (4, 2, 1)]  # x, y, z
    face = max(math.sqrt(sum(c * c for c in cross(edges[k], edges[k - 1])))
               for k in range(3))
    if face >= _FACE_LIMIT:
        problems.append(
            f"{_where(scene, box)}: box with a face of {face:.3g} square units: Mitsuba's "
            f"float32 face normal (the cross product of two edges, normalised through its "
            f"square) overflows from {_FACE_LIMIT:.3g}, so that face is shaded black "
            f"(docs/rendering-model.md)")
    return problems, lit


def float32_range_problems(scene: model.Scene) -> list[str]:
    """One message per shape, eye or light that Mitsuba cannot place precisely enough.

    A shape which reaches past Embree's coordinate range — a sphere, a plane's disk
    (``geometry.plane_disk``), a box's corners, a mesh's (the world corners of its file's
    bounds, ``geometry.mesh_corners``) — or whose float32 intersection error reaches the
    eye's distance to it: a sphere's, 2⁻²³·(max|c_k| + r); a plane's, 2⁻²³·max|c_k| of its
    disk's centre c (where Mitsuba's float32 numbers put the plane), against the eye's
    height above it; a box's or a mesh's, 2⁻²³ times its largest corner coordinate,
    against the eye's distance to the axis-aligned box around those corners (a lower
    bound of its distance to the surface; not checked from inside it), or a box whose
    faces are so large that Mitsuba's float32 normal of them overflows; an eye past that
    range; a light so far from the shapes that its float32 1/d² underflows.
    """
    problems = []
    problems = []
    eye = scene.camera.eye
    if _largest(eye) > _EMBREE_LIMIT:
        problems.append(
            f"{_where(scene, scene.camera)}: the eye at {_largest(eye):g} from the origin is "
            f"beyond ±{_EMBREE_LIMIT:g}, the coordinates Mitsuba's CPU ray tracer (Embree) "
            f"accepts: its rays meet nothing there (docs/rendering-model.md)")
    lit = []        # (point, radius) around which each shape lies, for the lights' check
    for kind in SHAPE_KINDS:            # kind by kind, each in the file's order
        check = MITSUBA_SHAPES[kind.keyword].range_problems
        for shape in getattr(scene, kind.plural):
            found, around = check(scene, shape)
            problems += found
            lit += around
    problems = [problem for problem in problems if problem]
    for light in scene.lights:
        farthest = max((math.dist(light.position, c) + r for c, r in lit), default=0.0)
        if farthest >= _LIGHT_DISTANCE_LIMIT:
            problems.append(
                f"{_where(scene, light)}: light {farthest:.3g} from the farthest shape point it "
                f"may light: from {2 * _LIGHT_DISTANCE_LIMIT:.3g} on, Mitsuba's float32 point "
                f"light (intensity/distance²) underflows to zero, so it may light nothing there "
                f"(docs/rendering-model.md)")
    return problems


in_object_space = model.in_object_space


def _product(a, b):
    """The 4×4 product a·b, in double precision (rows)."""
    return (np.asarray(a, dtype=np.float64) @ np.asarray(b, dtype=np.float64)).tolist()


def _transform(matrix):
    """A double-precision 4×4 (rows) as Mitsuba's transform: its entries rounded once to
    float32, and their inverse computed in double precision and rounded once — as Mitsuba's
    XML parser makes a ``<matrix>`` (src/core/parser.cpp), so an exported scene renders
    bit for bit as this dict (mimarble/tools/export.py), and a disk R wide, whose float32
    determinant R² would be far off, keeps an exact inverse."""
    import mitsuba as mi   # imported here: the module itself stays importable without it
    single = mi.ScalarMatrix4f([list(map(float, row)) for row in matrix])
    inverse = mi.ScalarTransform4d(mi.ScalarMatrix4d(single)).inverse_transpose
    return mi.ScalarTransform4f(single, mi.ScalarMatrix4f(inverse))


def disk_to_world(scene: model.Scene, plane: model.Plane):
    """The ``to_world`` (4×4 rows, double precision) of the Mitsuba ``disk`` that renders
    ``plane``: the unit disk (z = 0, normal +z) scaled by the radius R in its plane and
    centred as ``geometry.plane_disk`` says, its x, y, z axes the plane frame's
    bitangent, tangent and normal (``geometry.plane_frame``; right-handed, as bitangent ×
    tangent = normal). The normal is not scaled: Mitsuba inverts the matrix in float32,
    through its determinant, R² here (R³ would overflow from R ≈ 7·10¹², a scene's extent
    of 7·10⁸), and local z is then the height above the plane in world units."""
    centre, radius = geometry.plane_disk(scene, plane)
    tangent, normal, bitangent = geometry.plane_frame(plane.normal)
    return [[radius * bitangent[i], radius * tangent[i], normal[i], centre[i]]
            for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def cube_to_world(box: model.Box):
    """The ``to_world`` (4×4 rows, double precision) of the Mitsuba ``cube`` ([−1, 1]³)
    that renders ``box``: its transform · translate(centre) · scale(half extents)."""
    centre = [(lo + hi) / 2 for lo, hi in zip(box.min, box.max)]
    half = [(hi - lo) / 2 for lo, hi in zip(box.min, box.max)]
    placed = [[half[i] if j == i else 0.0 for j in range(3)] + [centre[i]] for i in range(3)]
    return _product(geometry.object_to_world(box), placed + [[0.0, 0.0, 0.0, 1.0]])


def shape_dict(scene: model.Scene, shape) -> dict:
    """The Mitsuba shape (without its BSDF) of one shape of ``scene``.

    * sphere → ``sphere`` (centre, radius);
    * plane → ``disk``, an analytic shape (its hit is the ray's, at the t where it meets
      the plane, accurate at any radius; ``rectangle`` is a two-triangle mesh whose hit is
      re-interpolated from its corners, ulp(R) off at radius R), placed by
      :func:`disk_to_world`;
    * box → ``cube``, a mesh of 12 triangles, placed by :func:`cube_to_world`;
    * mesh → ``ply`` or ``obj`` (by the file's ending), placed by its transform, with
      ``face_normals`` (flat shading, as the reference) and ``flip_tex_coords`` said out
      loud at Mitsuba's defaults (OBJ: v → 1 − v, so that an OBJ's v = 0 is an image's
      bottom row; PLY: as written). Mitsuba's loaders change nothing else: positions are
      the file's through ``to_world`` (rounded to float32), faces as given.
    """
    return MITSUBA_SHAPES[kind_of(shape).keyword].shape_dict(scene, shape)


def _sphere_dict(scene: model.Scene, sphere) -> dict:
    return {"type": "sphere", "center": list(sphere.center), "radius": sphere.radius}


def _disk_dict(scene: model.Scene, plane) -> dict:
    return {"type": "disk", "to_world": _transform(disk_to_world(scene, plane))}


def _cube_dict(scene: model.Scene, box) -> dict:
    return {"type": "cube", "to_world": _transform(cube_to_world(box))}


def _file_mesh_dict(scene: model.Scene, shape) -> dict:
    kind = os.path.splitext(shape.file)[1].lower()[1:]
    return {"type": kind, "filename": shape.location,
            "to_world": _transform(geometry.object_to_world(shape)), "face_normals": True,
            "flip_tex_coords": kind == "obj"}


def _facing_out(shape_out: dict, shape) -> None:
    """A translucent box's or mesh's normals facing out of it under a transform that
    mirrors (det < 0). Mitsuba enters a shape's ``interior`` when a ray crosses against its
    geometric normal, the cross product of a triangle's edges — which a mirror turns
    inwards: the medium would be outside. A mesh (flat, ``face_normals``) then gets
    ``flip_normals``; a box, whose ``cube`` carries vertex normals that the inverse
    transpose keeps outward, gets its cube mirrored back, to_world·diag(−1, 1, 1), the
    same points ([−1, 1]³ is symmetric) with det > 0. A sphere's and a plane's disk's
    normals face out (and up) whatever their placement."""
    mirrored = MITSUBA_SHAPES[kind_of(shape).keyword].mirrored
    if mirrored is not None \
            and np.linalg.det(np.asarray(geometry.object_to_world(shape), dtype=np.float64)) < 0:
        mirrored(shape_out, shape)


def _mirror_cube(shape_out: dict, box) -> None:
    mirror = [[-1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0],
              [0.0, 0.0, 0.0, 1.0]]
    shape_out["to_world"] = _transform(_product(cube_to_world(box), mirror))


def _flip_normals(shape_out: dict, mesh) -> None:
    shape_out["flip_normals"] = True


@dataclass(frozen=True)
class MitsubaShape:
    """A kind of shape in Mitsuba's scene: ``shape_dict`` (scene, shape) -> its dict
    without its BSDF; ``two_sided``: path mode wraps its BSDF in ``twosided`` (Mitsuba's
    BSDFs reflect on the side their normal points to; whitted flips n to the viewer;
    a sphere is seen from outside); ``reach`` (scene, shape) -> (nearest, farthest) from
    the eye (:func:`clip_planes`), None where unknown before Mitsuba loads it (a mesh's
    file); ``range_problems`` (scene, shape) -> (messages or None, (point, radius) around
    which it lies) (:func:`float32_range_problems`); ``mirrored`` (shape dict, shape):
    what turns a translucent shape's normals back out under a mirroring transform
    (:func:`_facing_out`), None where they face out whatever the placement."""

    shape_dict: Callable
    two_sided: bool = True
    reach: Callable | None = _corner_reach
    range_problems: Callable = _corner_problems
    mirrored: Callable | None = None


#: Each kind of shape, by keyword (shape_kinds.SHAPE_KINDS; tests/test_shape_kinds.py checks
#: that every kind has its entry).
MITSUBA_SHAPES: dict[str, MitsubaShape] = {
    "sphere": MitsubaShape(_sphere_dict, two_sided=False, reach=_sphere_reach,
                           range_problems=_sphere_problems),
    "plane": MitsubaShape(_disk_dict, reach=_disk_reach, range_problems=_disk_problems),
    "box": MitsubaShape(_cube_dict, range_problems=_box_problems, mirrored=_mirror_cube),
    "mesh": MitsubaShape(_file_mesh_dict, reach=None, mirrored=_flip_normals),
}


def is_two_sided(shape) -> bool:
    """Whether path mode wraps the shape's BSDF in ``twosided`` (:class:`MitsubaShape`)."""
    return MITSUBA_SHAPES[kind_of(shape).keyword].two_sided


