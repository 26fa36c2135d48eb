"""The ``marble`` texture: the paper's ChannelMarble as a Mitsuba 3 texture.

.. math::

    v = \\text{scale}\\cdot p, \\qquad F(v) = \\sum_{i<K} N(2^i v)/2^i

    t = \\begin{cases}
        |\\sin(\\pi(\\text{period}\\, v_a + \\text{distortion}\\, F(v)))| & \\texttt{abs\\_sine} \\\\
        \\tfrac12(\\sin(\\text{period}\\, v_a + \\text{distortion}\\, F(v)) + 1) & \\texttt{sine} \\\\
        \\tfrac12(\\cos(v_a + \\text{distortion}\\, F(v)) + 1) & \\texttt{cosine}
        \\end{cases}

    \\text{colour} = \\text{ramp}(\\operatorname{clamp}(t, 0, 1))

``p`` is the world-space point, or its image under the inverse of ``to_world``;
``v_a`` is the coordinate of ``v`` that ``axis`` names. The ramp holds K colours at
evenly spaced keys k/(K−1), interpolated linearly.

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Description
   * - ``scale``
     - float (1.0)
     - Texture-space scale applied to the point before anything else, > 0 (as in the
       scene language). Differentiable.
   * - ``period``
     - float (1.0)
     - Stripe frequency along ``axis`` (unused by ``cosine``, whose paper formula has none).
       Differentiable.
   * - ``distortion``
     - float (1.0)
     - Weight of the fractal noise in the phase. Differentiable.
   * - ``octaves``
     - integer (8)
     - Number of noise octaves K, 0..64. Structural: changing it compiles a new kernel.
       Octaves from 25 on are below float32 resolution and are not evaluated.
   * - ``function``
     - string (``abs_sine``)
     - ``abs_sine`` (paper §3.2), ``sine`` (Fig. 1), ``cosine`` (Fig. 2).
   * - ``axis``
     - string (``x``)
     - The coordinate the stripes run along: ``x``, ``y`` or ``z``.
   * - ``turbulence``
     - boolean (false)
     - Sum |N| instead of N (Perlin's turbulence).
   * - ``ramp``
     - string (the paper's Fig. 5 ramp)
     - Colours ``"r g b, r g b, …"`` (one or more; ``#rrggbb`` also accepted). In XML also
       ``<rgb name="ramp" …/>`` (one colour: a constant) or ``<rgb name="ramp_0" …/>``,
       ``<rgb name="ramp_1" …/>``, … (XML cannot repeat a name).
       Differentiable (key ``ramp``, a Color3f of K entries).
   * - ``tolerance``
     - float (1.52e-4)
     - Colour error allowed for leaving out fine octaves, ≥ 0: only the leading octaves
       whose omission could move some colour component by more than this are evaluated
       (a proven bound over every point; mimarble/error_budget.py). 0 evaluates every
       octave. The default moves an 8-bit sRGB image by at most half a code value where
       the texture reaches it unscaled. Recomputed when ``distortion`` or ``ramp``
       change; a new count of octaves compiles a new kernel.
   * - ``filter``
     - string (``none``)
     - How a pixel's footprint (from the ray differentials the integrator provides;
       ``whitted`` does) filters the marble. ``none``: the colour at the point.
       ``bandlimit``: octaves finer than the footprint are left out, the last one
       faded in (pbrt-v4's FBm clamp): fewer noise evaluations, less aliasing.
       ``prefilter``: the colour averaged over the pixel's interval of phase, exactly
       (mimarble/prefilter.py), the octaves finer than the footprint left out and
       their spread of phase added to the interval. Exact where the phase is linear
       across the pixel; octaves one to four pixels long are not (docs/benchmarks.md
       has the error against time). Without differentials every filter is ``none``.
   * - ``to_world``
     - transform (identity)
     - Places the texture in the world; the point is mapped by its inverse. Must be
       invertible (a singular one is refused). In ``mi.traverse`` as ``to_world``
       (not differentiable).

Parameters a sweep changes (``scale``, ``period``, ``distortion``, ``ramp``) are
opaque Dr.Jit values: changing them reuses the compiled kernel.

What the texture does not need it does not compute: no noise at all when
``distortion`` is 0 (and not being differentiated), no ``to_world`` transform
when none was given, and a constant when the ramp has one colour.
"""

from __future__ import annotations

import math
import re

import numpy as np

from . import environment, error_budget
from .noise import MAX_OCTAVES, fractal3, fractal3_band_limited, fractal3_weighted
from .noise_gradient import fractal3_band_limited_gradient, fractal3_gradient
from .plugins import plugin, transform_matrix
from .prefilter import PhaseAverage
from .scene.model import AXES, FIG5_RAMP, MARBLE_FILTERS, MARBLE_FUNCTIONS

dr, mi = environment.import_drjit_and_mitsuba()

# A luminance for mean(): Rec. 709 weights, as Mitsuba's luminance().
_LUMINANCE = np.array([0.212671, 0.715160, 0.072169])


class MarbleParameterError(ValueError):
    """An invalid ``marble`` parameter; the message names it and its value."""


# ---------------------------------------------------------------------------
# Parameter parsing and validation (plain Python)

def parse_ramp(value) -> tuple[tuple[float, float, float], ...]:
    """Colours from ``"r g b, r g b, …"``, ``"#rrggbb, …"`` or a sequence of triples."""
    if isinstance(value, str):
        colours = []
        for item in value.split(","):
            item = item.strip()
            if item.startswith("#") and len(item) == 7:
                try:
                    colours.append(tuple(int(item[i:i + 2], 16) / 255.0 for i in (1, 3, 5)))
                    continue
                except ValueError:
                    pass
            try:
                numbers = tuple(float(x) for x in item.split())
            except ValueError:
                numbers = ()
            if len(numbers) != 3:
                raise MarbleParameterError(
                    f"marble: ramp colour {item!r} in ramp={value!r} is not three numbers "
                    f"'r g b' (colours are separated by commas)")
            colours.append(numbers)
    elif _is_colour(value):             # <rgb name="ramp" …/>: one colour, a constant
        colours = [tuple(float(value[i]) for i in range(3))]
    else:
        try:
            colours = [tuple(float(x) for x in c) for c in value]
        except (TypeError, ValueError):
            raise MarbleParameterError(f"marble: ramp={value!r} is not a list of colours") from None
        if any(len(c) != 3 for c in colours):
            raise MarbleParameterError(f"marble: ramp={value!r} has a colour without 3 components")
    if not colours:
        raise MarbleParameterError(f"marble: ramp={value!r} is empty; give at least one colour")
    if not all(math.isfinite(x) for c in colours for x in c):
        raise MarbleParameterError(f"marble: ramp={value!r} has a non-finite component")
    return tuple(colours)


def _is_colour(value) -> bool:
    """An RGB triple of numbers (a Mitsuba colour property), not a list of colours."""
    try:
        return len(value) == 3 and all(isinstance(float(value[i]), float) for i in range(3)) \
            and not isinstance(value[0], (tuple, list))
    except (TypeError, ValueError, IndexError):
        return False


_NUMBERED_RAMP = re.compile(r"ramp_(\d+)$")


def ramp_property(props):
    """The ramp as given: ``ramp`` (a string, a list, or one ``rgb``), or ``ramp_0``,
    ``ramp_1``, … (one ``<rgb>`` each, as Mitsuba XML cannot repeat a name)."""
    numbered = sorted((int(m.group(1)), key) for key in props.keys()
                      if (m := _NUMBERED_RAMP.match(key)))
    if not numbered:
        return props.get("ramp", FIG5_RAMP)   # default: the paper's Fig. 5 ramp
    if "ramp" in props:
        raise MarbleParameterError("marble: give either ramp or ramp_0, ramp_1, …, not both")
    if [k for k, _ in numbered] != list(range(len(numbered))):
        raise MarbleParameterError(f"marble: numbered ramp colours must be ramp_0 … "
                                   f"ramp_{len(numbered) - 1} without gaps, got "
                                   f"{', '.join(key for _, key in numbered)}")
    return [props[key] for _, key in numbered]


def check_positive(name: str, x) -> float:
    x = check_number(name, x)
    if not x > 0:
        raise MarbleParameterError(f"marble: {name}={x!r} must be > 0")
    return x


def check_number(name: str, x) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
        raise MarbleParameterError(f"marble: {name}={x!r} must be a finite number")
    return float(x)


def check_nonnegative(name: str, x) -> float:
    x = check_number(name, x)
    if not x >= 0:
        raise MarbleParameterError(f"marble: {name}={x!r} must be ≥ 0")
    return x


def check_octaves(octaves) -> int:
    if isinstance(octaves, bool) or not isinstance(octaves, int) or not 0 <= octaves <= MAX_OCTAVES:
        raise MarbleParameterError(f"marble: octaves={octaves!r} must be an integer in 0..{MAX_OCTAVES}")
    return octaves


def check_boolean(name: str, value) -> bool:
    if not isinstance(value, bool):
        raise MarbleParameterError(f"marble: {name}={value!r} must be a boolean (true or false)")
    return value


def check_choice(name: str, value, choices) -> str:
    if value not in choices:
        raise MarbleParameterError(f"marble: {name}={value!r} must be one of {', '.join(choices)}")
    return value


def ramp_mean(ramp, function: str) -> np.ndarray:
    """Mean colour of the texture, assuming the phase is uniform over a period.

    All three functions map a uniform phase θ to t with the arcsine density on
    [0, 1] (t = |sin θ| or ½(sin θ + 1)), so the mean is the ramp averaged over
    θ; midpoint quadrature with 4096 nodes is exact to ~1e-7 for a piecewise
    linear ramp.
    """
    ramp = np.asarray(ramp, dtype=np.float64).reshape(-1, 3)
    theta = (np.arange(4096) + 0.5) * (2 * np.pi / 4096)
    t = np.abs(np.sin(theta)) if function == "abs_sine" else 0.5 * (np.sin(theta) + 1)
    x = t * (len(ramp) - 1)
    i = np.minimum(np.floor(x).astype(int), max(len(ramp) - 2, 0))
    f = (x - i)[:, None]
    j = np.minimum(i + 1, len(ramp) - 1)
    return ((1 - f) * ramp[i] + f * ramp[j]).mean(axis=0)


# ---------------------------------------------------------------------------
# The texture, written once for every RGB variant (see mimarble.plugins).

@plugin("texture", "marble")
class Marble:
    """Marble solid texture (Park & Park 2004). See the module docstring for parameters."""

    def __init__(self, props):
        mi.Texture.__init__(self, props)
        if not mi.variant().endswith("_rgb"):
            raise MarbleParameterError(f"marble: variant {mi.variant()} is not supported; "
                                       f"use an RGB variant (llvm_ad_rgb, cuda_ad_rgb, scalar_rgb)")
        scale = check_positive("scale", props.get("scale", 1.0))
        period = check_number("period", props.get("period", 1.0))
        distortion = check_number("distortion", props.get("distortion", 1.0))
        self.octaves = check_octaves(props.get("octaves", 8))
        self.function = check_choice("function", props.get("function", "abs_sine"),
                                     MARBLE_FUNCTIONS)
        self.axis = check_choice("axis", props.get("axis", "x"), AXES)
        self.turbulence = check_boolean("turbulence", props.get("turbulence", False))
        if "bandlimit" in props:
            raise MarbleParameterError('marble: bandlimit was replaced by filter; write '
                                       'filter="bandlimit" (or "prefilter", "none")')
        self.filter = check_choice("filter", props.get("filter", "none"), MARBLE_FILTERS)
        self.tolerance = check_nonnegative("tolerance",
                                           props.get("tolerance", error_budget.DEFAULT_TOLERANCE))
        colours = parse_ramp(ramp_property(props))

        self.scale = mi.Float(scale)
        self.period = mi.Float(period)
        self.distortion = mi.Float(distortion)
        self.ramp = mi.Color3f(*zip(*colours)) if dr.is_jit_v(mi.Float) else \
            [mi.Color3f(c) for c in colours]
        self.octaves_param = mi.UInt32(self.octaves)
        if "to_world" in props:
            # Properties hold transforms in double precision; the kernel uses float.
            matrix = np.array(props["to_world"].matrix, dtype=np.float64).reshape(4, 4)
            _check_invertible(matrix)
            self.to_world = mi.Transform4f(mi.Matrix4f(matrix.tolist()))
        else:
            self.to_world = None
        self.parameters_changed([])

    # -- Mitsuba object protocol -------------------------------------------

    def traverse(self, cb):
        flags = mi.ParamFlags.Differentiable
        cb.put("scale", self.scale, flags)
        cb.put("period", self.period, flags)
        cb.put("distortion", self.distortion, flags)
        cb.put("ramp", self.ramp, flags)
        cb.put("octaves", self.octaves_param, mi.ParamFlags.NonDifferentiable)
        if self.to_world is not None:
            cb.put("to_world", self.to_world, mi.ParamFlags.NonDifferentiable)

    _EDITABLE = ("scale", "period", "distortion", "ramp", "octaves_param", "to_world")

    def parameters_changed(self, keys=[]):
        """Re-validate after ``mi.traverse`` edits; keep the values opaque.

        An invalid edit raises and puts the last valid values back, so the
        texture never renders with them.
        """
        try:
            check_positive("scale", _first(self.scale))
            for name in ("period", "distortion"):
                check_number(name, _first(getattr(self, name)))
            if self.to_world is not None:
                _check_invertible(transform_matrix(self.to_world))
            octaves = check_octaves(int(_first(self.octaves_param)))
            colours = self._ramp_numpy()
            if colours.size == 0 or not np.isfinite(colours).all():
                raise MarbleParameterError("marble: ramp must hold one or more finite colours")
        except MarbleParameterError:
            # In place: mi.traverse keeps references to these very objects.
            for name, value in getattr(self, "_last_valid", {}).items():
                if dr.is_jit_v(mi.Float):
                    mi.set_property(getattr(self, name), value)
                else:
                    setattr(self, name, value)
            raise
        # Copies: mi.traverse writes new values into these very objects.
        self._last_valid = {name: type(getattr(self, name))(getattr(self, name))
                            for name in self._EDITABLE if getattr(self, name) is not None}
        # p = to_world⁻¹·p_world, from the matrix as it is now (None: the identity).
        self.to_texture = None if self.to_world is None else self.to_world.inverse()
        for name in ("scale", "period", "distortion", "ramp"):
            dr.make_opaque(getattr(self, name))
        self.octaves = octaves   # structural: a new count traces a new kernel at the next eval
        # The octaves the error budget keeps (structural too): mimarble/error_budget.py.
        self.octaves_evaluated = error_budget.octaves_needed(
            self.tolerance, octaves, _first(self.distortion), colours, self.function)
        self.ramp_size = len(colours)
        self.phase_average = self._phase_average()
        self._mean = float(ramp_mean(colours, self.function) @ _LUMINANCE)
        self._max = float(colours.max())
        # Static decisions: what this texture can skip (see the module docstring).
        self.needs_noise = self.octaves_evaluated > 0 and (_first(self.distortion) != 0.0
                                                           or dr.grad_enabled(self.distortion))

    def to_string(self):
        return (f"Marble[function={self.function}, axis={self.axis}, scale={_first(self.scale)}, "
                f"period={_first(self.period)}, distortion={_first(self.distortion)}, "
                f"octaves={self.octaves} ({self.octaves_evaluated} within tolerance="
                f"{self.tolerance:g}), turbulence={self.turbulence}, filter={self.filter}, "
                f"ramp={self.ramp_size} colours]")

    def is_spatially_varying(self):
        return self.ramp_size > 1

    def mean(self):
        return mi.Float(self._mean)

    def max(self):
        return self._max

    def spectral_resolution(self):
        return 0.0

    # -- Evaluation ------------------------------------------------------------

    def eval(self, si, active=True):
        differentials = self.pixel_differentials(si)
        if differentials is None:
            return self.colour_at(si.p)
        if self.phase_average is not None:
            return self.prefiltered_colour(si.p, *differentials)
        return self.colour_at(si.p, _footprint(*differentials))

    def eval_3(self, si, active=True):
        return self.eval(si, active)

    def eval_1(self, si, active=True):
        return mi.luminance(self.eval(si, active))

    def eval_1_grad(self, si, active=True):
        """∂(luminance)/∂(u, v), exact, by the chain rule (what Mitsuba's ``bumpmap`` reads):

            ∇_p lum = lum(ramp′(t)) · t′(φ) · scale · (period·e_a + distortion·∇F(v)),

        ∇F from :func:`mimarble.noise_gradient.fractal3_gradient` (one pass with F),
        mapped to world space by ``to_world``'s inverse transpose, then dotted with
        ∂p/∂u and ∂p/∂v. The full sum of the evaluated octaves (band-limiting is a
        rendering filter of the colour, not of its derivative).
        """
        if self.ramp_size == 1:
            return dr.zeros(mi.Vector2f, dr.width(si.p))
        p = si.p if self.to_texture is None else self.to_texture @ si.p
        v = _product(p, self.scale)
        if self.needs_noise:
            phase, grad_phase = self.phase_and_gradient(
                v, *fractal3_gradient(v, self.octaves_evaluated, self.turbulence))
        else:
            phase, grad_phase = self.phase_and_gradient(v)
        slope = mi.luminance(self.ramp_slope(self.stripe_of_phase(phase)))
        gradient = (slope * self.stripe_slope(phase) * self.scale) * grad_phase
        if self.to_texture is not None:  # ∇ in world space: (M⁻¹)ᵀ ∇ with M⁻¹ = to_texture
            m = self.to_texture.matrix
            gradient = mi.Vector3f(*(sum(m[i][j] * gradient[i] for i in range(3))
                                     for j in range(3)))
        return mi.Vector2f(dr.dot(gradient, si.dp_du), dr.dot(gradient, si.dp_dv))

    def pixel_differentials(self, si):
        """(∂v/∂x, ∂v/∂y): the pixel's extent in texture space, or None (``filter none``).

        From the ray differentials the integrator stored in ``si.duv_dx``,
        ``si.duv_dy`` (``compute_uv_partials``): ∂p/∂x = ∂p/∂u·∂u/∂x + ∂p/∂v·∂v/∂x,
        through to_world's inverse and the scale. Without differentials they are 0,
        and every filter keeps every octave at the point.
        """
        if self.filter == "none" or not dr.is_jit_v(mi.Float):
            return None
        dp_dx = si.dp_du * si.duv_dx.x + si.dp_dv * si.duv_dx.y
        dp_dy = si.dp_du * si.duv_dy.x + si.dp_dv * si.duv_dy.y
        if self.to_texture is not None:
            dp_dx, dp_dy = self.to_texture @ dp_dx, self.to_texture @ dp_dy
        return dp_dx * self.scale, dp_dy * self.scale

    def prefiltered_colour(self, p_world, dv_dx, dv_dy):
        """The colour averaged over the pixel (``filter prefilter``).

        Across the pixel's box (x, y ∈ [−½, ½]) the phase is, to first order,
        φ + a·x + b·y with a = ∇φ·∂v/∂x, b = ∇φ·∂v/∂y, ∇φ = period·e_a + distortion·∇F.
        Along the longer of the two it is a box of phase of width max(|a|, |b|),
        averaged exactly (mimarble/prefilter.py); across the shorter, two-point
        Gauss–Legendre. The octaves finer than the footprint (past
        PREFILTER_MARGIN) are left out of F; their spread of phase, variance
        distortion²·σ², widens the box by PHASE_SPREAD_WIDENING·σ² in the square.
        Where the box is below float32's resolution of the phase, the colour at
        the point.
        """
        p = p_world if self.to_texture is None else self.to_texture @ p_world
        v = _product(p, self.scale)
        if self.needs_noise:
            F, grad_F, dropped = fractal3_band_limited_gradient(
                v, self.octaves_evaluated, _footprint(dv_dx, dv_dy), PREFILTER_MARGIN,
                self.turbulence, (dv_dx, dv_dy))
            phase, grad_phase = self.phase_and_gradient(v, F, grad_F)
            spread = dr.square(self.distortion) * dropped
        else:
            phase, grad_phase = self.phase_and_gradient(v)
            spread = 0.0
        a, b = dr.abs(dr.dot(grad_phase, dv_dx)), dr.abs(dr.dot(grad_phase, dv_dy))
        long, short = dr.maximum(a, b), dr.minimum(a, b)
        width = dr.sqrt(dr.square(long) + PHASE_SPREAD_WIDENING * spread)
        below, below_defined = self.phase_average(phase - _GAUSS_NODE * short, width)
        above, above_defined = self.phase_average(phase + _GAUSS_NODE * short, width)
        colour = dr.select(below_defined & above_defined, 0.5 * (below + above),
                           self.ramp_at(self.stripe_of_phase(phase)))
        finite = dr.isfinite(p_world.x) & dr.isfinite(p_world.y) & dr.isfinite(p_world.z)
        return dr.select(finite, colour, dr.nan)

    def phase_and_gradient(self, v, F=None, grad_F=None):
        """(φ, ∇_v φ) at texture-space points, given F and ∇F (None: no noise)."""
        axis = AXES.index(self.axis)
        e_axis = mi.Vector3f(*(1.0 if k == axis else 0.0 for k in range(3)))
        frequency = 1.0 if self.function == "cosine" else self.period
        if F is None:
            return self.phase(v, 0.0), e_axis * frequency
        return (self.phase(v, _product(self.distortion, F)),
                e_axis * frequency + grad_F * self.distortion)

    def colour_at(self, p_world, footprint=None):
        """The marble colour at world-space points (any Dr.Jit array of points).

        A point with a NaN or infinite coordinate gets a NaN colour, decided here
        once rather than left to how each backend's min/max and float→int
        conversions treat NaN (they differ: LLVM's vector min keeps a NaN,
        constant folding of a one-lane array drops it).
        """
        if self.ramp_size == 1:   # a constant: no noise, no ramp interpolation
            return self.ramp_at(p_world.x)
        p = p_world if self.to_texture is None else self.to_texture @ p_world
        colour = self.ramp_at(self.stripe(_product(p, self.scale), footprint))
        finite = dr.isfinite(p_world.x) & dr.isfinite(p_world.y) & dr.isfinite(p_world.z)
        return dr.select(finite, colour, dr.nan)

    def stripe(self, v, footprint=None):
        """t ∈ [0, 1] at texture-space points v (already scaled).

        A product or sum of finite terms that overflows float32 (a huge but finite
        scale, period or distortion) is taken as 0, like any angle past float32's
        resolution, so finite input always gives a finite colour; NaN and ±Inf
        input still give NaN.
        """
        if not self.needs_noise:
            phase_noise = 0.0
        elif footprint is None:
            phase_noise = _product(self.distortion,
                                   fractal3(v, self.octaves_evaluated, self.turbulence))
        elif dr.grad_enabled(v):   # reverse mode cannot go through the symbolic loop
            phase_noise = _product(self.distortion, fractal3_weighted(
                v, self.octaves_evaluated, footprint, self.turbulence))
        else:
            phase_noise = _product(self.distortion, fractal3_band_limited(
                v, self.octaves_evaluated, footprint, self.turbulence))
        return self.stripe_of_phase(self.phase(v, phase_noise))

    def phase(self, v, phase_noise):
        """φ = period·v_a + distortion·F (cosine: v_a + distortion·F), given distortion·F."""
        along = v[AXES.index(self.axis)]
        if self.function == "cosine":
            return _sum(along, phase_noise)
        return _sum(_product(self.period, along), phase_noise)

    def stripe_of_phase(self, phase):
        """t(φ): |sin πφ|, ½(sin φ + 1) or ½(cos φ + 1)."""
        if self.function == "abs_sine":
            # |sin(πφ)| has period 1 in φ, and φ − ⌊φ⌋ is exact: any φ works.
            return dr.abs(dr.sin(dr.pi * (phase - dr.floor(phase))))
        if self.function == "sine":
            return 0.5 * (dr.sin(_reduce_angle(phase)) + 1.0)
        return 0.5 * (dr.cos(_reduce_angle(phase)) + 1.0)

    def stripe_slope(self, phase):
        """dt/dφ of :meth:`stripe_of_phase`."""
        if self.function == "abs_sine":
            # On φ − ⌊φ⌋ ∈ [0, 1) sin π(·) ≥ 0, so |sin| is sin there: slope π cos.
            return dr.pi * dr.cos(dr.pi * (phase - dr.floor(phase)))
        if self.function == "sine":
            return 0.5 * dr.cos(_reduce_angle(phase))
        return -0.5 * dr.sin(_reduce_angle(phase))

    def ramp_at(self, t):
        """Piecewise-linear ramp at t (clamped to [0, 1]), colours at keys k/(K−1).

        The gather index is in 0..K−2 by construction, whatever t is: a NaN t
        (for which ⌊x⌋ is NaN and its uint32 conversion is 2^31 on x86, an
        out-of-bounds read that kills the process on AVX2 machines) reads key 0,
        and the NaN then reaches the colour through f. One colour is a constant
        (the index must not come from ⌊t·0⌋ − 1).
        """
        if self.ramp_size == 1:
            zero = dr.zeros(mi.UInt32, dr.width(t)) if dr.is_jit_v(mi.Float) else 0
            return self._ramp_colour(zero)
        index, f = self._ramp_piece(t)
        return dr.lerp(self._ramp_colour(index), self._ramp_colour(index + 1), f)

    def _ramp_piece(self, t):
        """(i, f): t on the ramp's piece i (0..K−2, NaN-proof, see :meth:`ramp_at`) at f."""
        last = self.ramp_size - 1
        x = dr.clip(t, 0.0, 1.0) * last
        i = dr.floor(x)
        i = dr.select((i >= 0.0) & (i <= last - 1), i, dr.select(i > 0.0, last - 1, 0.0))
        return dr.uint32_array_t(type(x))(i), x - i

    def ramp_slope(self, t):
        """d ramp/dt at t: (K−1)·(c_{i+1} − c_i) on the piece t falls in (0 outside [0, 1])."""
        index, _ = self._ramp_piece(t)
        step = self._ramp_colour(index + 1) - self._ramp_colour(index)
        return dr.select((t >= 0.0) & (t <= 1.0), step * float(self.ramp_size - 1), 0.0)

    # -- helpers ---------------------------------------------------------------

    def _phase_average(self):
        """The prefilter's tables (``filter prefilter`` with a ramp of 2+ colours), else None."""
        if self.filter != "prefilter" or self.ramp_size < 2 or not dr.is_jit_v(mi.Float):
            return None
        average = getattr(self, "phase_average", None)
        if average is None or average.last != self.ramp_size - 1:
            average = PhaseAverage(self.function, self.ramp_size, self._ramp_piece,
                                   self._ramp_colour)
        average.update(self.ramp)
        return average

    def _ramp_colour(self, index):
        if isinstance(self.ramp, list):
            return self.ramp[index]
        return dr.gather(mi.Color3f, self.ramp, index)

    def _ramp_numpy(self) -> np.ndarray:
        if isinstance(self.ramp, list):
            return np.array([[c[0], c[1], c[2]] for c in self.ramp], dtype=np.float64)
        return np.array(self.ramp, dtype=np.float64).T   # Color3f converts as (3, K)


#: Octaves the prefilter keeps past pbrt's Nyquist cut (noise.band_limit), and the
#: weight of the left-out octaves' phase variance in the squared box width (12: a box of
#: that variance). Chosen by measurement: docs/benchmarks.md, "Prefiltered marble".
PREFILTER_MARGIN = 2.0
PHASE_SPREAD_WIDENING = 12.0
#: Two-point Gauss–Legendre on [−½, ½] (nodes ±1/(2√3), weights ½), across the pixel's
#: short side: on fig11a with 2 octaves, unlit, 1 spp interior RMSE 0.0013 against 0.0019
#: for one box of the same variance (√(a² + b²)); equal with 8 octaves.
_GAUSS_NODE = 0.5 / math.sqrt(3.0)


def _footprint(dv_dx, dv_dy):
    """The pixel's width in noise units: the longer of its two sides."""
    return dr.maximum(dr.norm(dv_dx), dr.norm(dv_dy))


_TWO_PI = 2.0 * math.pi
_LARGEST_MEANINGFUL_ANGLE = float(2 ** 24)


def _overflowed(result, a, b):
    """``result`` of finite ``a`` and ``b`` that overflowed to ±inf → 0; else as it is."""
    return dr.select(dr.isinf(result) & dr.isfinite(a) & dr.isfinite(b), 0.0, result)


def _product(a, b):
    return _overflowed(a * b, a, b)


def _sum(a, b):
    return _overflowed(a + b, a, b)


def _reduce_angle(x):
    """x mod 2π, for sin/cos that misbehave on huge arguments (Dr.Jit's float32
    sin leaves [−1, 1] past ~1e9 and gives NaN past ~1.8e19).

    Below 2^24 the reduction is as accurate as x itself. Beyond, a float32 angle
    has no fractional digits at all — the stripe is meaningless there — and the
    angle is taken as 0, so the colour stays finite and deterministic. NaN stays NaN.
    """
    x = dr.select(dr.abs(x) < _LARGEST_MEANINGFUL_ANGLE, x, dr.select(dr.isnan(x), x, 0.0))
    return x - _TWO_PI * dr.floor(x * (1.0 / _TWO_PI))


def _check_invertible(matrix: np.ndarray) -> None:
    """A to_world whose linear part cannot be inverted (in float32) would put every point at
    one phase: the first ramp colour everywhere. Refused instead."""
    linear = matrix[:3, :3]
    if not np.isfinite(matrix).all():
        raise MarbleParameterError("marble: to_world has a non-finite entry")
    scale = np.abs(linear).max()
    det = np.linalg.det(linear)
    if scale == 0 or not abs(det) > (1e-6 * scale) ** 3:
        raise MarbleParameterError(f"marble: to_world is singular (determinant {det:.3g} of its "
                                   f"3×3 part): texture space would collapse")


def _first(value) -> float:
    """The (single) value held by a Dr.Jit scalar array or a Python number."""
    if isinstance(value, (int, float)):
        return float(value)
    return float(value[0]) if dr.width(value) > 0 else float("nan")
