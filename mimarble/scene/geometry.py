"""Where the shapes are: each shape's object space, a plane's frame and reach, bounds.

These are definitions of the scene, not algorithms: both renderers read them (the Mitsuba
translator places its shapes by them, the reference tracer intersects in them), as they
read a sphere's centre. Everything is double precision; standard library only.

* A shape's **object space** (``object_to_world``) is where its own numbers live and
  where a ``space object`` marble is evaluated:

  - sphere: the unit sphere at the origin, placed by translate(center)·scale(radius), so
    that a larger sphere carries a proportionally larger pattern;
  - plane: the plane y = 0 with normal +y, placed by the rotation that takes +y to its
    normal (:func:`plane_frame`), then translate(point);
  - box: the box between its corners ``min`` and ``max``, placed by its ``transform``;
  - mesh: the file's coordinates, placed by its ``transform``.

* A **plane** is infinite in the language; rendered, it is the disk of radius
  :func:`plane_disk` around the point of the plane nearest the eye: PLANE_REACH times the
  scene's extent, so that its edge lies within 10⁻⁴ rad of the true horizon (a tenth of
  a pixel at 30° over 500 pixels). Both renderers clip it there, so they agree at the
  horizon too.
"""

from __future__ import annotations

import math

from mimarble.scene import transforms

__all__ = ["PLANE_REACH", "plane_frame", "object_to_world", "plane_disk", "sphere_bounds",
           "box_corners", "mesh_corners", "apply", "apply_linear", "frame_matrix",
           "bounding_sphere"]

#: A plane's rendered radius in units of the scene's extent around it (:func:`plane_disk`).
PLANE_REACH = 1e4

Matrix = tuple[tuple[float, float, float, float], ...]


def _unit(v):
    length = math.sqrt(sum(c * c for c in v))
    return tuple(c / length for c in v)


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def plane_frame(normal):
    """(tangent, normal, bitangent): the images of +x, +y, +z under a rotation that takes +y
    to the unit ``normal``: for a normal in the upper half-space (n_y ≥ 0) the smallest such
    rotation; below it, the half turn about x (+y to −y) followed by the smallest rotation
    from −y to the normal, so that neither divides by a small 1 ± n_y. Unit, orthogonal to
    double precision and right-handed: tangent × normal = bitangent, as x × y = z."""
    n = _unit(normal)
    up = 1.0 if n[1] >= 0.0 else -1.0              # the pole the rotation starts from
    # Rodrigues' rotation from s·y to n (s = up): R = I + [k]× + [k]×²/(1 + s·n_y),
    # k = s·y × n; after the half turn for s = −1, x stays x and z becomes −z.
    k = (up * n[2], 0.0, -up * n[0])
    c = 1.0 / (1.0 + up * n[1])

    def rotate(v):
        kv = _cross(k, v)
        kkv = _cross(k, kv)
        return tuple(v[i] + kv[i] + c * kkv[i] for i in range(3))

    x = rotate((1.0, 0.0, 0.0))
    along = math.fsum(x[i] * n[i] for i in range(3))
    tangent = _unit(tuple(x[i] - along * n[i] for i in range(3)))
    bitangent = _unit(_cross(tangent, n))
    return tangent, n, bitangent


def frame_matrix(columns, origin) -> Matrix:
    """The 4×4 matrix (rows) whose first three columns are ``columns`` and whose
    translation is ``origin``."""
    return tuple(tuple(columns[j][i] for j in range(3)) + (float(origin[i]),)
                 for i in range(3)) + ((0.0, 0.0, 0.0, 1.0),)


def object_to_world(shape) -> Matrix:
    """The shape's object space to world (module docstring), as 4×4 rows: its own
    (shapes.py, the shape protocol)."""
    method = getattr(shape, "object_to_world", None)
    if method is None:
        raise TypeError(f"object_to_world: {shape!r:.60} is not a shape")
    return method()


def apply(matrix: Matrix, point):
    """matrix · (point, 1)."""
    return tuple(math.fsum(matrix[i][j] * point[j] for j in range(3)) + matrix[i][3]
                 for i in range(3))


def apply_linear(matrix: Matrix, vector):
    """matrix · (vector, 0)."""
    return tuple(math.fsum(matrix[i][j] * vector[j] for j in range(3)) for i in range(3))


def box_corners(box):
    """The eight corners of a box, in world space."""
    m = transforms.compose(box.transform)
    return [apply(m, (x, y, z)) for x in (box.min[0], box.max[0])
            for y in (box.min[1], box.max[1]) for z in (box.min[2], box.max[2])]


def mesh_corners(mesh):
    """The eight corners, in world space, of the box of a mesh file's vertex positions
    (meshes.facts.mesh_bounds, in file coordinates) placed by the mesh's transform: the
    mesh lies within their convex hull. None where the file cannot be read (the parser
    says why at the mesh)."""
    from mimarble.meshes.facts import mesh_bounds   # here: a malformed scene's answer needs none
    bounds = mesh_bounds(mesh.location)
    if bounds is None:
        return None
    (x0, y0, z0), (x1, y1, z1) = bounds
    m = transforms.compose(mesh.transform)
    return [apply(m, (x, y, z)) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]


def bounding_sphere(corners):
    """(centre, radius): the sphere about the corners' mean through the farthest one."""
    centre = tuple(sum(c[i] for c in corners) / len(corners) for i in range(3))
    return centre, max(math.dist(centre, c) for c in corners)


def sphere_bounds(shape):
    """(centre, radius) of a sphere enclosing the shape in world space, or None for an
    unbounded kind (a plane): its own ``bounds()`` (shapes.py) — a sphere's own; a
    box's or a mesh's (:func:`mesh_corners`) around its eight world corners."""
    return shape.bounds()


def plane_disk(scene, plane):
    """(centre, radius) of the disk a plane is rendered as: centred on the point of the
    plane nearest the eye, of radius PLANE_REACH·E, E = 1 + the largest distance from that
    point to the eye, the look-at point, a light or any bounded shape's bounding sphere
    (:func:`sphere_bounds`: a mesh's from its file's bounds)."""
    n = _unit(plane.normal)
    eye = scene.camera.eye
    height = math.fsum(n[i] * (eye[i] - plane.point[i]) for i in range(3))
    centre = tuple(eye[i] - height * n[i] for i in range(3))
    reach = [math.dist(centre, eye), math.dist(centre, scene.camera.lookat)]
    reach += [math.dist(centre, light.position) for light in scene.lights]
    for shape in scene.bounded_shapes():
        c, r = sphere_bounds(shape)
        reach.append(math.dist(centre, c) + r)
    return centre, PLANE_REACH * (1.0 + max(reach))
