"""Scene shapes → Mitsuba shapes: each kind's shape dict and placement, the clip planes
that keep every shape in view, and a translucent shape's normals facing out.

:data:`MITSUBA_SHAPES` holds one :class:`MitsubaShape` per kind of
:data:`~mimarble.scene.shapes.SHAPE_KINDS`, by keyword; a bounded kind's reach
defaults to its eight world corners' (``shape.corners()``), so a new kind needs its dict
alone. Shapes (:func:`shape_dict`): a sphere → ``sphere``, a plane → ``disk`` (the disk it is
rendered as, ``geometry.plane_disk``), a box → ``cube``, a mesh → ``ply``/``obj``, each under
the id ``Scene.shapes()`` gives it. A material whose channels hold a ``space object`` marble
becomes one BSDF per shape, its object-space textures placed by the shape's object space
(``to_world`` = S·M, v = scale·(S·M)⁻¹·p); in path mode planes, boxes and meshes get their
BSDF wrapped in ``twosided`` (docs/rendering-model.md, "Planes, boxes and meshes";
docs/mitsuba-scene.md).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mimarble.contract import T_MIN_REL
from mimarble.scene import geometry, model
from mimarble.scene.shapes import SHAPE_KINDS, kind_of


in_object_space = model.in_object_space


def matrix_product(a, b):
    """The 4×4 product a·b, in double precision (rows)."""
    return (np.asarray(a, dtype=np.float64) @ np.asarray(b, dtype=np.float64)).tolist()


def mitsuba_transform(matrix):
    """A double-precision 4×4 (rows) as Mitsuba's transform: its entries rounded once to
    float32, and their inverse computed in double precision and rounded once — as Mitsuba's
    XML parser makes a ``<matrix>`` (src/core/parser.cpp), so an exported scene renders
    bit for bit as this dict (mimarble/tools/export.py), and a disk R wide, whose float32
    determinant R² would be far off, keeps an exact inverse."""
    import mitsuba as mi   # imported here: the module itself stays importable without it
    single = mi.ScalarMatrix4f([list(map(float, row)) for row in matrix])
    inverse = mi.ScalarTransform4d(mi.ScalarMatrix4d(single)).inverse_transpose
    return mi.ScalarTransform4f(single, mi.ScalarMatrix4f(inverse))


# The reference tracer accepts hits from t = T_MIN_REL·(1 + max|eye_k|) on.
_NEAREST_HIT_REL = T_MIN_REL


def box_distance(point, corners) -> float:
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
    return box_distance(eye, corners), max(math.dist(c, eye) for c in corners)


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
    return matrix_product(geometry.object_to_world(box), placed + [[0.0, 0.0, 0.0, 1.0]])


def shape_dict(scene: model.Scene, shape) -> dict:
    """The Mitsuba shape (without its BSDF) of one shape of ``scene``.

    * sphere → ``sphere`` (centre, radius);
    * plane → ``disk``, an analytic shape (its hit is the ray's, at the t where it meets
      the plane, accurate at any radius; ``rectangle`` is a two-triangle mesh whose hit is
      re-interpolated from its corners, ulp(R) off at radius R), placed by
      :func:`disk_to_world`;
    * box → ``cube``, a mesh of 12 triangles, placed by :func:`cube_to_world`;
    * mesh → ``ply`` or ``obj`` (by the file's ending), placed by its transform, with
      ``face_normals`` true (flat shading) unless it is smooth (:func:`is_smooth`: then
      false, so that Mitsuba reads the file's vertex normals or, without them, computes
      its own, and interpolates them across each triangle as the reference does) and
      ``flip_tex_coords`` said out loud at Mitsuba's defaults (OBJ: v → 1 − v, so that an OBJ's v = 0 is an image's
      bottom row; PLY: as written). Mitsuba's loaders change nothing else: positions are
      the file's through ``to_world`` (rounded to float32), faces as given.
    """
    return MITSUBA_SHAPES[kind_of(shape).keyword].shape_dict(scene, shape)


def _sphere_dict(scene: model.Scene, sphere) -> dict:
    return {"type": "sphere", "center": list(sphere.center), "radius": sphere.radius}


def _disk_dict(scene: model.Scene, plane) -> dict:
    return {"type": "disk", "to_world": mitsuba_transform(disk_to_world(scene, plane))}


def _cube_dict(scene: model.Scene, box) -> dict:
    return {"type": "cube", "to_world": mitsuba_transform(cube_to_world(box))}


def _file_mesh_dict(scene: model.Scene, shape) -> dict:
    kind = os.path.splitext(shape.file)[1].lower()[1:]
    return {"type": kind, "filename": shape.location,
            "to_world": mitsuba_transform(geometry.object_to_world(shape)),
            "face_normals": not is_smooth(shape), "flip_tex_coords": kind == "obj"}


def is_smooth(shape) -> bool:
    """Whether a shape is a mesh shaded with vertex normals: ``Mesh.is_smooth`` of its
    file's facts (``smooth`` as written, else whether the file has normals)."""
    if not isinstance(shape, model.Mesh):
        return False
    from mimarble.meshes.facts import mesh_facts       # kept per version of the file
    return shape.is_smooth(mesh_facts(shape.location).has_normals)


def facing_out(shape_out: dict, shape) -> None:
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
    shape_out["to_world"] = mitsuba_transform(matrix_product(cube_to_world(box), mirror))


def _flip_normals(shape_out: dict, mesh) -> None:
    shape_out["flip_normals"] = True


@dataclass(frozen=True)
class MitsubaShape:
    """A kind of shape in Mitsuba's scene: ``shape_dict`` (scene, shape) -> its dict
    without its BSDF; ``two_sided``: path mode wraps its BSDF in ``twosided`` (Mitsuba's
    BSDFs reflect on the side their normal points to; whitted flips n to the viewer;
    a sphere is seen from outside); ``reach`` (scene, shape) -> (nearest, farthest) from
    the eye (:func:`clip_planes`), None where unknown before Mitsuba loads it (a mesh's
    file; by default a bounded kind's eight world corners); ``mirrored`` (shape dict, shape):
    what turns a translucent shape's normals back out under a mirroring transform
    (:func:`facing_out`), None where they face out whatever the placement."""

    shape_dict: Callable
    two_sided: bool = True
    reach: Callable | None = _corner_reach
    mirrored: Callable | None = None


#: Each kind of shape, by keyword (shapes.SHAPE_KINDS; tests/test_shape_kinds.py checks
#: that every kind has its entry).
MITSUBA_SHAPES: dict[str, MitsubaShape] = {
    "sphere": MitsubaShape(_sphere_dict, two_sided=False, reach=_sphere_reach),
    "plane": MitsubaShape(_disk_dict, reach=_disk_reach),
    "box": MitsubaShape(_cube_dict, mirrored=_mirror_cube),
    "mesh": MitsubaShape(_file_mesh_dict, reach=None, mirrored=_flip_normals),
}


def is_two_sided(shape) -> bool:
    """Whether path mode wraps the shape's BSDF in ``twosided`` (:class:`MitsubaShape`)."""
    return MITSUBA_SHAPES[kind_of(shape).keyword].two_sided


