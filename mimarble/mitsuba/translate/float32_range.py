"""What Mitsuba's float32 arithmetic (and Embree's range) cannot place precisely enough:
a shape, the eye or a light, one warning sentence each."""

from __future__ import annotations

import math

from mimarble.contract import FLOAT32_EPSILON
from mimarble.scene import geometry, model
from mimarble.scene.rules import cross

from mimarble.scene.shapes import SHAPE_KINDS, kind_of

from .shapes import box_distance


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
    distance = box_distance(scene.camera.eye, corners) if len(corners) == 8 else 0.0
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


#: Each kind's checks, by keyword (:func:`float32_range_problems`); any other kind, a
#: mesh's among them, is checked by its eight world corners.
_RANGE_PROBLEMS = {"sphere": _sphere_problems, "plane": _disk_problems, "box": _box_problems}


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
    eye = scene.camera.eye
    if _largest(eye) > _EMBREE_LIMIT:
        problems.append(
            f"{_where(scene, scene.camera)}: the eye at {_largest(eye):g} from the origin is "
            f"beyond ±{_EMBREE_LIMIT:g}, the coordinates Mitsuba's CPU ray tracer (Embree) "
            f"accepts: its rays meet nothing there (docs/rendering-model.md)")
    lit = []        # (point, radius) around which each shape lies, for the lights' check
    for kind in SHAPE_KINDS:            # kind by kind, each in the file's order
        check = _RANGE_PROBLEMS.get(kind.keyword, _corner_problems)
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
