"""The marble's stripe functions: phase φ, stripe t(φ), slope dt/dφ, and their facts.

With v the texture point, v_a its ``axis`` coordinate and F the fractal noise::

    abs_sine:  φ = period·v_a + distortion·F    t = |sin(π φ)|        |dt/dφ| ≤ π
    sine:      φ = period·v_a + distortion·F    t = ½(sin φ + 1)      |dt/dφ| ≤ ½
    cosine:    φ = v_a + distortion·F           t = ½(cos φ + 1)      |dt/dφ| ≤ ½
    triangle:  φ = period·v_a + distortion·F    t = 1 − |1 − 2 frac φ|   |dt/dφ| = 2
    sawtooth:  φ = period·v_a + distortion·F    t = frac φ            dt/dφ = 1, a jump at
                                                                      each integer φ

(the paper's §3.2, Fig. 1 and Fig. 2; cosine's formula has no period; triangle and
sawtooth are POV-Ray's ``triangle_wave``, its marble's default, and ``ramp_wave``).
Each is one record, :data:`STRIPES`, read by the texture (mimarble/mitsuba/plugins/marble.py), the
error budget (the slope bound S, and whether t jumps), the prefilter (the stripe's
shape over a period) and the stress suite (amplitude and angular frequency, for the
float32 error of t). The paper's t are A·f(ω·φ + c) with f = sin or cos: A the
amplitude, ω the angular frequency, so the slope bound is S = A·ω; the waves' A·ω is
their slope too (A = 1; ω = 2 for the triangle, 1 for the sawtooth).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mimarble.contract import FLOAT32_INTEGER_LIMIT
from mimarble.runtime import environment
from mimarble.texture.sine_pi import cos_pi, sin_pi
from .finite_arithmetic import finite_product, finite_sum

dr, mi = environment.import_drjit_and_mitsuba()

_TWO_PI = 2.0 * math.pi
_LARGEST_MEANINGFUL_ANGLE = FLOAT32_INTEGER_LIMIT


def reduce_angle(x):
    """x mod 2π, for sin/cos that misbehave on huge arguments (Dr.Jit's float32
    sin leaves [−1, 1] past ~1e9 and gives NaN past ~1.8e19).

    Below 2^24 the reduction is as accurate as x itself. Beyond, a float32 angle
    has no fractional digits at all — the stripe is meaningless there — and the
    angle is taken as 0, so the colour stays finite and deterministic. NaN stays NaN.
    """
    x = dr.select(dr.abs(x) < _LARGEST_MEANINGFUL_ANGLE, x, dr.select(dr.isnan(x), x, 0.0))
    return x - _TWO_PI * dr.floor(x * (1.0 / _TWO_PI))


@dataclass(frozen=True)
class StripeShape:
    """t as a function of y = φ/period + offset, one shape of period 1 in y, T(x) with
    x = y − ⌊y⌋: ``sin`` sin πx, ``sin2`` sin² πx, ``triangle`` 1 − |1 − 2x| (each
    rising on [0, ½] and symmetric about ½), or ``ramp`` x (rising on all of [0, 1), back
    to 0 at 1: not symmetric). The prefilter (mimarble/texture/prefilter.py) integrates the ramp
    over it in closed form."""

    period: float
    offset: float
    form: str = "sin"

    @property
    def symmetric(self) -> bool:
        """Rising on [0, ½], the mirror image falling on [½, 1]; else rising on [0, 1)."""
        return self.form != "ramp"

    def y(self, phase):
        if self.period == 1.0 and self.offset == 0.0:
            return phase
        return phase * (1.0 / self.period) + self.offset

    # float64 NumPy, for the prefilter's table

    def inverse(self, t: np.ndarray) -> np.ndarray:
        """The rising x where T(x) = t: in [0, ½] (symmetric shapes) or [0, 1]."""
        if self.form == "triangle":
            return 0.5 * t
        if self.form == "ramp":
            return np.asarray(t, dtype=np.float64).copy()
        return np.arcsin(np.sqrt(t) if self.form == "sin2" else t) / math.pi

    def antiderivative(self, x: np.ndarray) -> np.ndarray:
        """∫_0^x T, for x in [0, 1]."""
        if self.form == "sin2":
            return x / 2 - np.sin(2 * math.pi * x) / (4 * math.pi)
        if self.form == "triangle":
            return np.where(x <= 0.5, x * x, 0.5 - (1 - x) ** 2)
        if self.form == "ramp":
            return 0.5 * x * x
        return (1 - np.cos(math.pi * x)) / math.pi

    # Dr.Jit, in the kernel

    def rising(self, t):
        """:meth:`inverse` in the kernel: the rising x where T(x) = t."""
        if self.form == "triangle":
            return 0.5 * t
        if self.form == "ramp":
            return t
        return dr.asin(dr.sqrt(t) if self.form == "sin2" else t) * (1.0 / dr.pi)

    def stripe(self, x):
        if self.form == "triangle":
            return 1.0 - dr.abs(1.0 - 2.0 * x)
        if self.form == "ramp":
            return x
        s = sin_pi(x)
        return s * s if self.form == "sin2" else s

    def integral(self, a, b):
        """∫_a^b T for a, b on one piece of the ramp (one side of ½ for the triangle),
        without cancellation as b → a (products of sines; a linear T is its value at the
        midpoint times the length)."""
        if self.form == "sin2":
            return 0.5 * (b - a) - cos_pi(a + b) * sin_pi(b - a) * (0.5 / dr.pi)
        if self.form == "triangle":
            return (b - a) * (1.0 - dr.abs(1.0 - (a + b)))
        if self.form == "ramp":
            return (b - a) * (0.5 * (a + b))
        return (2.0 / dr.pi) * sin_pi(0.5 * (a + b)) * sin_pi(0.5 * (b - a))


class StripeFunction:
    """One stripe function: its phase, t(φ), dt/dφ, and the facts the bounds use."""

    name: str
    uses_period: bool = True
    amplitude: float = 0.5           # A
    angular_frequency: float = 1.0   # ω
    jumps: bool = False              # t(φ) jumps (from 1 to 0) once a period
    shape: StripeShape

    @property
    def slope_bound(self) -> float:
        """S = sup |dt/dφ| = A·ω."""
        return self.amplitude * self.angular_frequency

    def phase(self, v, axis: int, period, noise):
        """φ at the texture point ``v`` from its ``axis`` coordinate v_a, the period and
        ``noise`` = distortion·F (0.0 for none). A function whose phase is not planar
        (not of v_a alone) overrides this and :meth:`phase_gradient`."""
        along = v[axis]
        if not self.uses_period:
            return finite_sum(along, noise)
        return finite_sum(finite_product(period, along), noise)

    def phase_gradient(self, v, axis: int, period, noise_gradient=None):
        """∇_v φ at ``v`` = frequency·e_axis + ``noise_gradient`` (distortion·∇F; None:
        none)."""
        e_axis = mi.Vector3f(*(1.0 if k == axis else 0.0 for k in range(3)))
        along = e_axis * (period if self.uses_period else 1.0)
        return along if noise_gradient is None else along + noise_gradient

    def t(self, phase):
        raise NotImplementedError

    def slope(self, phase):
        raise NotImplementedError


class AbsSine(StripeFunction):
    name = "abs_sine"
    amplitude, angular_frequency = 1.0, math.pi
    shape = StripeShape(1.0, 0.0, "sin")

    def t(self, phase):
        # |sin(πφ)| has period 1 in φ, and φ − ⌊φ⌋ is exact: any φ works.
        return dr.abs(dr.sin(dr.pi * (phase - dr.floor(phase))))

    def slope(self, phase):
        # On φ − ⌊φ⌋ ∈ [0, 1) sin π(·) ≥ 0, so |sin| is sin there: slope π cos.
        return dr.pi * dr.cos(dr.pi * (phase - dr.floor(phase)))


class Sine(StripeFunction):
    name = "sine"
    shape = StripeShape(2 * math.pi, 0.25, "sin2")   # ½(sin φ + 1) = sin² π(φ/2π + ¼)

    def t(self, phase):
        return 0.5 * (dr.sin(reduce_angle(phase)) + 1.0)

    def slope(self, phase):
        return 0.5 * dr.cos(reduce_angle(phase))


class Cosine(StripeFunction):
    name = "cosine"
    uses_period = False
    shape = StripeShape(2 * math.pi, 0.5, "sin2")    # ½(cos φ + 1) = sin² π(φ/2π + ½)

    def t(self, phase):
        return 0.5 * (dr.cos(reduce_angle(phase)) + 1.0)

    def slope(self, phase):
        return -0.5 * dr.sin(reduce_angle(phase))


class Triangle(StripeFunction):
    """POV-Ray's ``triangle_wave``, its marble's default: 2·frac φ on the first half of
    each period, 2(1 − frac φ) on the second (pattern.cpp's Triangle_Wave), the phase of
    ``abs_sine``: the same zeros and peaks, straight flanks of slope ±2 instead of π cos."""

    name = "triangle"
    amplitude, angular_frequency = 1.0, 2.0
    shape = StripeShape(1.0, 0.0, "triangle")

    def t(self, phase):
        # φ − ⌊φ⌋ is exact, as abs_sine's: any φ works.
        return 1.0 - dr.abs(1.0 - 2.0 * (phase - dr.floor(phase)))

    def slope(self, phase):
        return dr.select(phase - dr.floor(phase) < 0.5, 2.0, -2.0)


class Sawtooth(StripeFunction):
    """POV-Ray's ``ramp_wave``: t = frac φ, rising from 0 to 1 over each period and back
    to 0 at once: the ramp's last colour meets its first there (a hard edge unless they
    are equal; the error budget keeps every octave then, mimarble/texture/error_budget.py)."""

    name = "sawtooth"
    amplitude, angular_frequency = 1.0, 1.0
    jumps = True
    shape = StripeShape(1.0, 0.0, "ramp")

    def t(self, phase):
        return phase - dr.floor(phase)

    def slope(self, phase):
        return dr.full(type(phase), 1.0, dr.width(phase)) if dr.is_jit_v(phase) else 1.0


#: The stripe functions by name (mimarble/parameters.py: FUNCTIONS).
STRIPES: dict[str, StripeFunction] = {f.name: f for f in (AbsSine(), Sine(), Cosine(),
                                                            Triangle(), Sawtooth())}
