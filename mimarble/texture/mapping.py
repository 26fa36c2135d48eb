"""Where the marble is evaluated: the texture point and the pixel's footprint.

    v = scale · to_world⁻¹ · p,        ∂v/∂x = scale · to_world⁻¹ · (∂p/∂u ∂u/∂x + ∂p/∂v ∂v/∂x)

p is the world-space point Mitsuba hands the texture; ``to_world`` places the texture
in the world (the identity when not given; always in ``mi.traverse``, as bitmap's
``to_uv`` is; no transform is traced while it is the identity). The footprint comes
from the ray differentials the integrator stored in ``si.duv_dx``, ``si.duv_dy`` by
``compute_uv_partials`` (``whitted`` does; Mitsuba 3.9's own integrators never do, and
then they are literal zeros, :func:`without_footprint`, and every filter is ``none``).
Mitsuba's perspective camera starts the differential rays at the near clip plane, not
at the eye; :func:`differentials_from_the_eye` moves them back, for the integrator to
apply before ``compute_uv_partials`` (docs/design-decisions.md, "Filtering the pixel"),
or before :func:`compute_uv_partials_scaled`, the same solve safe on a plane's disk.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mimarble.runtime import environment
from .finite_arithmetic import finite_product
from mimarble.parameters import ParameterError

dr, mi = environment.import_drjit_and_mitsuba()


class TexturePoint(NamedTuple):
    """A texture point v, its pixel's extent (∂v/∂x, ∂v/∂y; None when not asked for),
    and whether the world point was finite (a NaN or infinite one gets a NaN colour)."""

    v: object
    dv_dx: object
    dv_dy: object
    finite: object

    @property
    def footprint(self):
        """The pixel's width in noise units: the longer of its two sides."""
        return dr.maximum(dr.norm(self.dv_dx), dr.norm(self.dv_dy))


class TextureMapping:
    """p ↦ v = scale · to_world⁻¹ · p, for points, footprints and gradients.

    ``DRJIT_STRUCT``: what the kernel reads — to_world⁻¹ and the scale — is seen by Dr.Jit's
    traversal (``dr.freeze``) through the texture; to_world⁻¹ is opaque, so a recording
    takes it as an input rather than baking it into the kernel. ``to_world`` itself is
    read on the host only (checked, inverted, traversed by ``mi.traverse``), so it is not
    among them: a recorded pass walks its inputs at every replay, and a transform is 32
    variables (docs/design-decisions.md, "Adaptive samples: the pass's fixed cost")."""

    DRJIT_STRUCT = {"to_texture": object, "scale": object}

    def __init__(self, to_world):
        """``to_world``: an editable transform (checked and inverted in :meth:`check` and
        :meth:`changed`, which the texture calls whenever its parameters change)."""
        self.to_world = to_world
        self.scale, self.to_texture = None, None

    @classmethod
    def from_properties(cls, props):
        """``to_world`` from the plugin's properties (none: the identity); a singular
        one is refused."""
        # Properties hold transforms in double precision; the kernel uses float.
        matrix = np.array(props["to_world"].matrix, dtype=np.float64).reshape(4, 4) \
            if "to_world" in props else np.eye(4)
        return cls(mi.Transform4f(mi.Matrix4f(matrix.tolist())))

    def check(self, matrix: np.ndarray) -> None:
        """ParameterError unless ``to_world`` (``matrix``: its 4×4 as ``mi.traverse`` may
        have left it, read once by the texture) can be inverted."""
        check_invertible(matrix)

    def changed(self, scale, matrix: np.ndarray) -> None:
        """After the parameters changed: the scale (in JIT variants the texture's very
        opaque ``mi.Float``, which ``mi.traverse`` edits in place), and to_world⁻¹
        (None: the identity). ``matrix`` None: to_world is on the device only (an edit the
        host never read), inverted there, whatever it is."""
        self.scale = scale
        identity = matrix is not None and np.array_equal(matrix, np.eye(4))
        self.to_texture = None if identity else self.to_world.inverse()
        if dr.is_jit_v(mi.Float):   # an edit's new value reuses the kernel and its recording
            dr.make_opaque(self.to_world)
            if self.to_texture is not None:
                dr.make_opaque(self.to_texture)

    def point(self, p):
        """v at world points p."""
        return finite_product(p if self.to_texture is None else self.to_texture @ p, self.scale)

    def map(self, si, footprint: bool = False) -> TexturePoint:
        """The texture point of ``si``, with the pixel's footprint when asked for."""
        p = si.p
        finite = dr.isfinite(p.x) & dr.isfinite(p.y) & dr.isfinite(p.z)
        if not footprint:
            return TexturePoint(self.point(p), None, None, finite)
        dp_dx = si.dp_du * si.duv_dx.x + si.dp_dv * si.duv_dx.y
        dp_dy = si.dp_du * si.duv_dy.x + si.dp_dv * si.duv_dy.y
        if self.to_texture is not None:
            dp_dx, dp_dy = self.to_texture @ dp_dx, self.to_texture @ dp_dy
        return TexturePoint(self.point(p), dp_dx * self.scale, dp_dy * self.scale, finite)

    def gradient_to_world(self, gradient):
        """∇_p of a function whose gradient in to_world's frame is ``gradient``:
        (M⁻¹)ᵀ ∇ with M⁻¹ = to_texture (the scale is the caller's)."""
        if self.to_texture is None:
            return gradient
        m = self.to_texture.matrix
        return mi.Vector3f(*(sum(m[i][j] * gradient[i] for i in range(3)) for j in range(3)))


class NoFootprintWarning(UserWarning):
    """A filtered marble was evaluated without ray differentials: its filter did nothing."""


def no_footprint_message(texture_id: str, filter: str) -> str:
    """The warning of a marble (its id, or "") whose ``filter`` needs a pixel footprint
    and was given none."""
    name = f" {texture_id!r}" if texture_id else ""
    return (f"marble{name}: filter={filter!r} has no pixel footprint to filter "
            f"over: the integrator computed no ray differentials (si.duv_dx, si.duv_dy "
            f"are 0), so the marble is its colour at the point, as filter='none'. "
            f"mimarble's 'whitted' provides them; Mitsuba's own integrators ('path', "
            f"'prb', 'direct', ...) do not (docs/mitsuba-scene.md). Said once per "
            f"texture; a symbolic call traces every live instance, so this may be a "
            f"marble of another scene still loaded.")


class _Omitted:
    """Set while an integrator traces materials without footprints on purpose (whitted,
    when none of its scene's materials filters, still traces every live material in its
    symbolic call, other scenes' filtered marbles too): they are not warned about."""
    depth = 0

    def __enter__(self):
        _Omitted.depth += 1

    def __exit__(self, *exc):
        _Omitted.depth -= 1


def footprints_omitted_on_purpose() -> _Omitted:
    """``with footprints_omitted_on_purpose(): …``: :func:`footprints_omitted` is True."""
    return _Omitted()


def footprints_omitted() -> bool:
    """Whether an integrator is tracing materials without footprints on purpose now."""
    return _Omitted.depth > 0


def without_footprint(si) -> bool:
    """Whether ``si`` carries no pixel footprint at all: every component of ``si.duv_dx``
    and ``si.duv_dy`` is a literal 0, the value Mitsuba gives every surface interaction
    (``finalize_surface_interaction``) and only ``compute_uv_partials`` replaces.

    Decided at trace time, from what the variables *are* (a literal's value is held in
    the variable, read without a kernel, also inside a symbolic call or loop and while
    ``dr.freeze`` records), never from values in memory: computed partials are not
    literals, whatever their values. False in the scalar variant (it filters nothing)."""
    if not dr.is_jit_v(mi.Float):
        return False
    for value in (si.duv_dx.x, si.duv_dx.y, si.duv_dy.x, si.duv_dy.y):
        if value.state != dr.VarState.Literal or value[0] != 0.0:
            return False
    return True


#: The Mitsuba camera whose differential rays start at the main ray's near-plane point:
#: ``perspective.cpp`` moves ``ray.o`` to the near clip plane, then sets
#: ``ray.o_x = ray.o_y = ray.o``. (``thinlens`` and ``orthographic`` are right: the first
#: takes the base ``Sensor``'s neighbouring rays, the second offsets o_x, o_y itself.)
NEAR_PLANE_CAMERA = "PerspectiveCamera"


def differentials_from_the_eye(ray, scene):
    """``ray`` with its differential rays starting at the eye where Mitsuba's
    perspective camera started them at the main ray's near-plane point o.

    ``compute_uv_partials`` intersects the differential rays o_x + s·d_x with the tangent
    plane at the hit, and the step they make on it is linear in the distance of their
    common origin from the plane: from o every footprint comes out (t − near_t)/t of its
    size (t from the eye, near_t = near_clip/cos θ), exactly, not to first order. This is
    for an integrator to apply before ``compute_uv_partials`` (a texture sees neither the
    ray nor the camera: docs/design-decisions.md). Lanes whose o_x and o_y both
    equal o get the eye of the scene's perspective sensor whose near plane holds o (the
    one nearest to it, where there are several: ``mi.render(scene, sensor=i)`` does not
    say which it traces); every other lane keeps its own (an orthographic or thin-lens
    sensor, rays that start at the eye already, as ``render_in_passes``' do). A ray
    without differentials, or a scene without a perspective sensor, comes back as it
    is. A new ray: ``ray`` itself is left alone."""
    cameras = [s for s in scene.sensors() if s.class_name() == NEAR_PLANE_CAMERA]
    if not ray.has_differentials or not cameras:
        return ray
    eye = off = None
    for camera in cameras:
        to_world = camera.world_transform()
        here = mi.Point3f(to_world.translation())
        if len(cameras) == 1:
            eye = here
        else:   # o, in the frame of the camera that made the ray, is on z = near_clip
            distance = dr.abs((to_world.inverse() @ ray.o).z - camera.near_clip())
            if eye is None:
                eye, off = here, distance
            else:
                nearer = distance < off
                eye, off = dr.select(nearer, here, eye), dr.minimum(distance, off)
    near_plane = dr.all(ray.o_x == ray.o) & dr.all(ray.o_y == ray.o)
    fixed = type(ray)(ray)          # a copy of the ray; its differentials are set below
    fixed.o_x = dr.select(near_plane, eye, ray.o_x)
    fixed.o_y = dr.select(near_plane, eye, ray.o_y)
    fixed.d_x, fixed.d_y = ray.d_x, ray.d_y
    fixed.has_differentials = True
    return fixed


def compute_uv_partials_scaled(si, ray) -> None:
    """``si.compute_uv_partials(ray)`` with ``si.dp_du`` and ``si.dp_dv`` divided by their
    lengths L_u, L_v while it solves, and ``si.duv_dx``, ``si.duv_dy`` multiplied back by
    1/L_u, 1/L_v: the same footprint dp/dx = dp_du·du/dx + dp_dv·dv/dx, to rounding.

    Mitsuba's least squares forms det = |dp_du|²·|dp_dv|² − (dp_du·dp_dv)², of the
    size L_u²·L_v², in float32. On a plane's disk (``disk``: dp_du is a radius R long,
    dp_dv 2π·|p − c|, both of the scene's extent times 10⁴) it overflows from an extent of
    about 10⁷, and the partials come out 0 (Mitsuba's guard against an infinite 1/det:
    no footprint, every filter ``none``) or, larger still, NaN. With unit tangents det
    is at most 1 and stays a normal float32 unless they are nearly parallel; a tangent of
    length 0 (the disk's centre) keeps Mitsuba's answer, 0."""
    du, dv = dr.norm(si.dp_du), dr.norm(si.dp_dv)
    du, dv = dr.select(du > 0, du, 1.0), dr.select(dv > 0, dv, 1.0)
    dp_du, dp_dv = mi.Vector3f(si.dp_du), mi.Vector3f(si.dp_dv)   # copies, not views of si
    si.dp_du, si.dp_dv = dp_du / du, dp_dv / dv
    si.compute_uv_partials(ray)
    si.duv_dx = mi.Vector2f(si.duv_dx.x / du, si.duv_dx.y / dv)
    si.duv_dy = mi.Vector2f(si.duv_dy.x / du, si.duv_dy.y / dv)
    si.dp_du, si.dp_dv = dp_du, dp_dv


def check_invertible(matrix: np.ndarray) -> None:
    """A to_world whose linear part cannot be inverted (in float32) would put every point
    at one phase: the first ramp colour everywhere. Refused instead."""
    linear = matrix[:3, :3]
    if not np.isfinite(matrix).all():
        raise ParameterError("marble: to_world has a non-finite entry")
    scale = np.abs(linear).max()
    det = np.linalg.det(linear)
    if scale == 0 or not abs(det) > (1e-6 * scale) ** 3:
        raise ParameterError(f"marble: to_world is singular (determinant {det:.3g} of its "
                             f"3×3 part): texture space would collapse")
