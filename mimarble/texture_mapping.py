"""Where the marble is evaluated: the texture point and the pixel's footprint.

    v = scale · to_world⁻¹ · p,        ∂v/∂x = scale · to_world⁻¹ · (∂p/∂u ∂u/∂x + ∂p/∂v ∂v/∂x)

p is the world-space point Mitsuba hands the texture; ``to_world`` places the texture
in the world (the identity when not given; always in ``mi.traverse``, as bitmap's
``to_uv`` is; no transform is traced while it is the identity). The footprint comes
from the ray differentials the integrator stored in ``si.duv_dx``, ``si.duv_dy``
(``whitted`` does; without them they are 0, and every filter keeps every octave).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from . import environment
from .finite_arithmetic import finite_product
from .marble_parameters import ParameterError

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

    ``DRJIT_STRUCT``: its transforms and scale are seen by Dr.Jit's traversal
    (``dr.freeze``) through the texture; to_world⁻¹ is opaque, so a recording takes it
    as an input rather than baking it into the kernel."""

    DRJIT_STRUCT = {"to_world": object, "to_texture": object, "scale": object}

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
        (None: the identity)."""
        self.scale = scale
        identity = np.array_equal(matrix, np.eye(4))
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
