"""The marble's stripe functions: phase φ, stripe t(φ), slope dt/dφ, and their facts.

With v the texture point, v_a its ``axis`` coordinate and F the fractal noise::

    abs_sine:  φ = period·v_a + distortion·F    t = |sin(π φ)|        |dt/dφ| ≤ π
    sine:      φ = period·v_a + distortion·F    t = ½(sin φ + 1)      |dt/dφ| ≤ ½
    cosine:    φ = v_a + distortion·F           t = ½(cos φ + 1)      |dt/dφ| ≤ ½

(the paper's §3.2, Fig. 1 and Fig. 2; cosine's formula has no period). Each is one
record, :data:`STRIPES`, read by the texture (mimarble/marble.py), the error budget
(the slope bound S), the prefilter (the stripe's shape over a period) and the stress
suite (amplitude and angular frequency, for the float32 error of t). Every t is
A·f(ω·φ + c) with f = sin or cos: A the amplitude, ω the angular frequency, so the
slope bound is S = A·ω.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import environment
from .finite_arithmetic import finite_product, finite_sum

dr, mi = environment.import_drjit_and_mitsuba()

_TWO_PI = 2.0 * math.pi
_LARGEST_MEANINGFUL_ANGLE = float(2 ** 24)


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
    """t as a function of y = φ/period + offset, one shape of period 1 in y, symmetric
    about y = ½: T(x) = sin πx, or sin² πx (``squared``), x = y − ⌊y⌋. The prefilter
    (mimarble/prefilter.py) integrates the ramp over it in closed form."""

    period: float
    offset: float
    squared: bool

    def y(self, phase):
        if self.period == 1.0 and self.offset == 0.0:
            return phase
        return phase * (1.0 / self.period) + self.offset

    # float64 NumPy, for the prefilter's table

    def inverse(self, t: np.ndarray) -> np.ndarray:
        """The rising x ∈ [0, ½] where T(x) = t."""
        return np.arcsin(np.sqrt(t) if self.squared else t) / math.pi

    def antiderivative(self, x: np.ndarray) -> np.ndarray:
        """∫_0^x T."""
        if self.squared:
            return x / 2 - np.sin(2 * math.pi * x) / (4 * math.pi)
        return (1 - np.cos(math.pi * x)) / math.pi

    # Dr.Jit, in the kernel

    def stripe(self, x):
        s = dr.sin(dr.pi * x)
        return s * s if self.squared else s

    def integral(self, a, b):
        """∫_a^b T, without cancellation as b → a (products of sines)."""
        if self.squared:
            return 0.5 * (b - a) - dr.cos(dr.pi * (a + b)) * dr.sin(dr.pi * (b - a)) * (0.5 / dr.pi)
        return (2.0 / dr.pi) * dr.sin((0.5 * dr.pi) * (a + b)) * dr.sin((0.5 * dr.pi) * (b - a))


class StripeFunction:
    """One stripe function: its phase, t(φ), dt/dφ, and the facts the bounds use."""

    name: str
    uses_period: bool = True
    amplitude: float = 0.5           # A
    angular_frequency: float = 1.0   # ω
    shape: StripeShape

    @property
    def slope_bound(self) -> float:
        """S = sup |dt/dφ| = A·ω."""
        return self.amplitude * self.angular_frequency

    def phase(self, along, period, noise):
        """φ from v_a, the period and ``noise`` = distortion·F (0.0 for none)."""
        if not self.uses_period:
            return finite_sum(along, noise)
        return finite_sum(finite_product(period, along), noise)

    def phase_gradient(self, axis: int, period, noise_gradient=None):
        """∇_v φ = frequency·e_axis + ``noise_gradient`` (distortion·∇F; None: none)."""
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
    shape = StripeShape(1.0, 0.0, False)

    def t(self, phase):
        # |sin(πφ)| has period 1 in φ, and φ − ⌊φ⌋ is exact: any φ works.
        return dr.abs(dr.sin(dr.pi * (phase - dr.floor(phase))))

    def slope(self, phase):
        # On φ − ⌊φ⌋ ∈ [0, 1) sin π(·) ≥ 0, so |sin| is sin there: slope π cos.
        return dr.pi * dr.cos(dr.pi * (phase - dr.floor(phase)))


class Sine(StripeFunction):
    name = "sine"
    shape = StripeShape(2 * math.pi, 0.25, True)     # ½(sin φ + 1) = sin² π(φ/2π + ¼)

    def t(self, phase):
        return 0.5 * (dr.sin(reduce_angle(phase)) + 1.0)

    def slope(self, phase):
        return 0.5 * dr.cos(reduce_angle(phase))


class Cosine(StripeFunction):
    name = "cosine"
    uses_period = False
    shape = StripeShape(2 * math.pi, 0.5, True)      # ½(cos φ + 1) = sin² π(φ/2π + ½)

    def t(self, phase):
        return 0.5 * (dr.cos(reduce_angle(phase)) + 1.0)

    def slope(self, phase):
        return -0.5 * dr.sin(reduce_angle(phase))


#: The stripe functions by name (mimarble/marble_parameters.py: FUNCTIONS).
STRIPES: dict[str, StripeFunction] = {f.name: f for f in (AbsSine(), Sine(), Cosine())}
