"""The marble colour averaged over a Gaussian distribution of phase: an experiment.

Heitz, Nowrouzezahrai, Poulin & Neyret, "Filtering Non-Linear Transfer Functions on
Surfaces" (IEEE TVCG 2014), model what a pixel sees of a scalar field as a
distribution — mean and variance — and filter the transfer function (here the colour
map f = ramp∘t) against it. This module does that for the marble's phase, beside the
box of mimarble/texture/prefilter.py, for issue 24 (scripts/experiments/phase_distribution_trial.py
measures it; docs/bench/phase-distribution.json holds the numbers).

The series. In the stripe's normalised phase y = φ/P + y₀ (mimarble/texture/stripes.py) the
colour is f(y) = ramp(T(y − ⌊y⌋)), periodic with period 1, so

    f(y) = a₀ + 2 Σ_{k≥1} (a_k cos 2πky + b_k sin 2πky),
    a_k = ∫₀¹ f(x) cos 2πkx dx,   b_k = ∫₀¹ f(x) sin 2πkx dx

(b_k = 0 for the shapes symmetric about ½: all but the sawtooth). For Y of
characteristic function χ(ω) = E e^{iωY}, real and even (any symmetric distribution),

    E f(μ + Y) = a₀ + 2 Σ_k χ(2πk) (a_k cos 2πkμ + b_k sin 2πkμ),

exactly. The distributions used here are products of independent parts:

    Gaussian of variance s²:          χ(2πk) = exp(−2π²k²s²)
    uniform over a box of width w:    χ(2πk) = sin(πkw)/(πkw)

A Gaussian alone is Heitz et al.'s model; a Gaussian times the two boxes of the pixel's
linear phase φ + a·x + b·y (x, y uniform on [−½, ½]) is the exact first-order
parallelogram of mimarble/texture/filters.py convolved with the left-out octaves'
Gaussian (``widths`` of :meth:`PhaseGaussian.series`).

The coefficients a_k, b_k are linear in the ramp colours: a_k = Σ_j V_kj c_j, V built
in float64 from the prefilter's piece table (:func:`harmonic_weights`, Gauss–Legendre
on each piece, where f is α + β·T(x) and smooth), so ``mi.traverse`` edits reach them
(:meth:`PhaseGaussian.update`) and gradients flow to the colours, as in PhaseAverage.

Truncation. The series stops at the ``harmonics``-th term H; the first term left out is
bounded by its χ. Where χ(2π(H+1)) > :data:`TRUNCATION`^¼ — narrow distributions, which
would need many harmonics — the series is not used: :meth:`PhaseGaussian.__call__`
takes the box average of the same variance there (width √12·s, exact for a narrow
linear phase), and so does :class:`GaussianPrefilter` (or, ``narrow="prefilter"``, the
prefilter's box and two Gauss points); blended between (:meth:`PhaseGaussian._series_share`). With H = 8 a Gaussian alone is the series from
s = 0.066 periods on, the box below s = 0.033.
"""

from __future__ import annotations

import math

import numpy as np

from mimarble.runtime import environment
from mimarble.texture.filters import (GAUSS_NODE, PHASE_SPREAD_WIDENING, PREFILTER_MARGIN,
    Prefilter)
from mimarble.texture.prefilter import PhaseAverage, piece_table

dr, mi = environment.import_drjit_and_mitsuba()

#: Harmonics of the series: 8 render fig11a and fig09d as 16 and 32 do (interior RMSE
#: within 1e-5), for less work (scripts/experiments/phase_distribution_trial.py).
HARMONICS = 8
#: The series is used where the first harmonic it leaves out is damped below this: that
#: term is 2|a_K|·χ ≤ 2·(colour range)/(πK)·ε (a jump: the sawtooth's), ~1e-6 for a
#: continuous ramp∘t, whose a_K fall as 1/K².
TRUNCATION = 2.0 ** -10
#: Gauss–Legendre nodes per piece for V (float64): f is smooth on a piece, so the rule is
#: exact to rounding for the harmonics used here.
_NODES_PER_PIECE = 48


def harmonic_weights(shape, size: int, harmonics: int, keys=None) -> tuple[np.ndarray, np.ndarray]:
    """(A, B), each (harmonics + 1, size), float64: a_k = Σ_j A_kj c_j and
    b_k = Σ_j B_kj c_j for a ramp of ``size`` colours at ``keys`` (None: evenly spaced)
    over a stripe ``shape``. On piece j (boundaries from :func:`prefilter.piece_table`) the
    ramp is c_i (1 − u) + c_{i+1} u with u = (T(x) − t_i)/(t_{i+1} − t_i)."""
    last = size - 1
    keys_f = np.arange(size) / last if keys is None else np.asarray(keys, dtype=np.float64)
    boundaries, _ = piece_table(shape, size, keys)
    nodes, weights = np.polynomial.legendre.leggauss(_NODES_PER_PIECE)
    k = np.arange(harmonics + 1)[:, None]
    A = np.zeros((harmonics + 1, size))
    B = np.zeros((harmonics + 1, size))
    for j in range(len(boundaries) - 1):
        i = j if j < last else 2 * last - 1 - j     # the ramp piece: rising, then falling
        a, b = boundaries[j], boundaries[j + 1]
        if b <= a:                                  # an empty piece (two equal keys)
            continue
        width = keys_f[i + 1] - keys_f[i]
        x = 0.5 * (a + b) + 0.5 * (b - a) * nodes
        w = 0.5 * (b - a) * weights
        t = _stripe64(shape, x)
        u = (t - keys_f[i]) / width if width > 0.0 else np.ones_like(t)
        cos, sin = np.cos(2 * math.pi * k * x), np.sin(2 * math.pi * k * x)
        A[:, i] += cos @ (w * (1.0 - u))
        A[:, i + 1] += cos @ (w * u)
        B[:, i] += sin @ (w * (1.0 - u))
        B[:, i + 1] += sin @ (w * u)
    return A, B


def _stripe64(shape, x: np.ndarray) -> np.ndarray:
    """T(x) in float64 (mimarble/texture/stripes.py's StripeShape.stripe, for the table)."""
    if shape.form == "triangle":
        return 1.0 - np.abs(1.0 - 2.0 * x)
    if shape.form == "ramp":
        return x
    s = np.sin(math.pi * x)
    return s * s if shape.form == "sin2" else s


class PhaseGaussian:
    """ramp∘t averaged over distributions of phase by its Fourier series (module
    docstring), for one stripe function and ramp; the box (PhaseAverage) where the
    distribution is too narrow for the series.

    ``DRJIT_STRUCT``: the coefficients (one width-1 Color3f per harmonic, broadcast in
    the kernel) and the box's tables, for Dr.Jit's traversal (``dr.freeze``)."""

    DRJIT_STRUCT = {"cosines": object, "sines": object, "box": PhaseAverage}

    def __init__(self, stripe, ramp, harmonics: int = HARMONICS, box: PhaseAverage | None = None):
        self.shape = stripe.shape
        self.ramp = ramp
        self.harmonics = harmonics
        self.box = box if box is not None else PhaseAverage(stripe, ramp)
        self._weights = None
        self.update(box=box is None)

    def update(self, box: bool = True) -> None:
        """a_k, b_k from the ramp as it is now (gradients flow to the colours); with
        positions, V made again from their values; ``box``: the box's tables too."""
        if box:
            self.box.update()
        if self._weights is None or self.ramp.positioned:
            keys = self.ramp.keys() if self.ramp.positioned else None
            self._weights = harmonic_weights(self.shape, self.ramp.count, self.harmonics, keys)
        A, B = self._weights
        colours = [dr.gather(mi.Color3f, self.ramp.colours, mi.UInt32(j))
                   for j in range(A.shape[1])]

        def combine(row):
            total = dr.zeros(mi.Color3f, 1)
            for j, c in enumerate(colours):
                total += float(row[j]) * c
            return total

        self.cosines = [combine(A[k]) for k in range(self.harmonics + 1)]
        self.sines = [] if self.shape.symmetric else [combine(B[k])
                                                      for k in range(self.harmonics + 1)]
        dr.eval(self.cosines, self.sines)

    def series(self, phase, variance, widths=()):
        """(E f(φ + Y), share): Y a Gaussian of ``variance`` (in phase², ≥ 0) plus
        uniform boxes of the given ``widths`` (phase units, ≥ 0), all independent, by the
        truncated Fourier series; ``share`` (:meth:`_series_share`) 1 where that is
        accurate, 0 where the distribution is too narrow for the harmonics."""
        shape = self.shape
        if not dr.is_array_v(variance):      # no noise: σ² is the Python float 0
            variance = dr.full(mi.Float, variance, dr.width(phase))
        y = shape.y(phase)
        x = y - dr.floor(y)                  # exact: the series needs only y mod 1
        scale = 1.0 / shape.period
        # exp(−2π²k²s²) = q^{k²}: q^{(k+1)²} = q^{k²}·q^{2k+1}, the ratio times q² each step.
        q = dr.exp(-2.0 * dr.pi ** 2 * (scale * scale) * variance)
        q_squared = q * q
        damping, ratio = q, q * q_squared
        # sin(πkw)/(πkw) from the rotation (cos πw, sin πw) applied k times.
        boxes = []
        for w in widths:
            w = w * scale
            c, s = dr.cos(dr.pi * w), dr.sin(dr.pi * w)
            inverse = dr.select(w > 0.0, 1.0 / (dr.pi * dr.select(w > 0.0, w, 1.0)), 0.0)
            boxes.append((w, c, s, inverse))
        box_state = [(c, s) for _, c, s, _ in boxes]
        c1, s1 = dr.cos(2.0 * dr.pi * x), dr.sin(2.0 * dr.pi * x)
        ck, sk = c1, s1
        total = mi.Color3f(self.cosines[0])
        for k in range(1, self.harmonics + 1):
            factor = damping
            for (w, _, _, inverse), (bc, bs) in zip(boxes, box_state):
                factor *= dr.select(w > 0.0, bs * (inverse / k), 1.0)
            term = self.cosines[k] * ck
            if self.sines:
                term += self.sines[k] * sk
            total += (2.0 * factor) * term
            if k < self.harmonics:
                ck, sk = ck * c1 - sk * s1, sk * c1 + ck * s1
                damping, ratio = damping * ratio, ratio * q_squared
                box_state = [(bc * c - bs * s, bs * c + bc * s)
                             for (_, c, s, _), (bc, bs) in zip(boxes, box_state)]
        return total, self._series_share(variance * (scale * scale),
                                         [w * scale for w in widths])

    def _series_share(self, variance_y, widths_y):
        """How much of the series to take, from the damping χ of the first harmonic it
        leaves out, K = H + 1: 1 where χ ≤ ε (:data:`TRUNCATION`: that term is below
        ε·2|a_K|), 0 where χ ≥ ε^¼ (narrow distributions: too few harmonics),
        smoothstep in log χ between, so that where the model changes it changes without
        a seam (the blend's series error is at most ε^¼·2|a_K|, weighted by the share).
        Gaussian: log χ = −2π²K²s²; a box of width w: |sin(πKw)/(πKw)| ≤ min(1, 1/(πKw)).
        """
        K = float(self.harmonics + 1)
        log_bound = (-2.0 * dr.pi ** 2 * K * K) * variance_y
        for w in widths_y:
            log_bound -= dr.log(dr.maximum(1.0, (dr.pi * K) * w))
        start = 0.25 * math.log(TRUNCATION)      # share 0 at log χ = ¼ log ε, 1 at log ε
        share = dr.clip((log_bound - start) * (1.0 / (3.0 * start)), 0.0, 1.0)
        return share * share * (3.0 - 2.0 * share)

    def __call__(self, phase, std):
        """The mean of ramp(t(φ)) for φ normal with mean ``phase`` and deviation ``std``
        (≥ 0), and a mask of the lanes where it is defined: the series where the
        distribution is wide enough for it, the box of the same variance (width √12·std)
        where it is narrow, blended between (:meth:`_series_share`); undefined where the
        box is below float32's resolution of the phase, and at a NaN (use the point)."""
        wide_mean, share = self.series(phase, dr.square(std))
        narrow_mean, narrow_defined = self.box(phase, math.sqrt(12.0) * std)
        wide = (share >= 1.0) & ~dr.isnan(phase)
        return _blend(narrow_mean, wide_mean, share), wide | narrow_defined


def _blend(narrow, wide, share):
    """narrow where share is 0, wide where it is 1 (exactly: a NaN or infinite value of
    the other is not carried in), lerp between."""
    mixed = dr.select((share > 0.0) & (share < 1.0), dr.lerp(narrow, wide, share), narrow)
    return dr.select(share >= 1.0, wide, mixed)


class GaussianPrefilter(Prefilter):
    """Experimental (not a ``filter`` choice; scripts/experiments/phase_distribution_trial.py
    installs it): the prefilter with the Gaussian series where the pixel's distribution
    of phase is wide.

    The phase is as :class:`~mimarble.texture.filters.Prefilter` computes it (octaves past
    ``margin`` left out, their variance σ² = distortion²·(V·Σ + F.spread)); across the
    pixel it is φ + a·x + b·y to first order, x, y uniform on [−½, ½], a = |∇φ·∂v/∂x|,
    b = |∇φ·∂v/∂y|. ``model``:

    * ``"gaussian"``: Heitz et al.'s, one Gaussian of variance s² =
      ``linear_variance_scale``·(a² + b²)/12 + σ² ((a² + b²)/12: the variance of the
      linear phase over the unit pixel);
    * ``"parallelogram"``: the linear phase exactly (boxes of widths a and b),
      convolved with a Gaussian of variance σ².

    Where the series would need more than ``harmonics`` terms (narrow distributions),
    ``narrow``: ``"box"``, one box of the same variance (width √12·s, as
    :meth:`PhaseGaussian.__call__`); ``"prefilter"``, the prefilter's box and two Gauss
    points, as ``filter prefilter`` renders (twice the box's work, and no better:
    scripts/experiments/phase_distribution_trial.py); blended between
    (:meth:`PhaseGaussian._series_share`).
    """

    DRJIT_STRUCT = {"average": PhaseAverage, "gaussian": PhaseGaussian}

    def __init__(self, stripe, ramp, model: str = "gaussian", margin: float = PREFILTER_MARGIN,
                 harmonics: int = HARMONICS, linear_variance_scale: float = 1.0,
                 narrow: str = "box"):
        if model not in ("gaussian", "parallelogram"):
            raise ValueError(f"model={model!r}: gaussian or parallelogram")
        if narrow not in ("prefilter", "box"):
            raise ValueError(f"narrow={narrow!r}: prefilter or box")
        super().__init__(stripe, ramp)
        self.model, self.margin, self.narrow = model, margin, narrow
        self.linear_variance_scale = linear_variance_scale
        self.gaussian = PhaseGaussian(stripe, ramp, harmonics, box=self.average)

    def changed(self) -> None:
        self.average.update()
        self.gaussian.update(box=False)

    def colour(self, phase, point):
        """The Gaussian-filtered colour; the phase as the prefilter's
        (mimarble/texture/filters.py), with this filter's margin (:attr:`margin`)."""
        grad_phase, spread = phase.gradient, phase.spread
        phase = phase.value
        a, b = dr.abs(dr.dot(grad_phase, point.dv_dx)), dr.abs(dr.dot(grad_phase, point.dv_dy))
        linear_variance = (dr.square(a) + dr.square(b)) * (1.0 / 12.0)
        if self.model == "gaussian":
            variance = self.linear_variance_scale * linear_variance + spread
            wide, share = self.gaussian.series(phase, variance)
        else:
            variance = linear_variance + spread
            wide, share = self.gaussian.series(phase, spread, (a, b))
        colour_at_mean_phase = self.ramp(self.stripe.t(phase))
        if self.narrow == "box":
            box, defined = self.average(phase, dr.sqrt(12.0 * variance))
            narrow = dr.select(defined, box, colour_at_mean_phase)
        else:
            long, short = dr.maximum(a, b), dr.minimum(a, b)
            width = dr.sqrt(dr.square(long) + PHASE_SPREAD_WIDENING * spread)
            below, below_defined = self.average(phase - GAUSS_NODE * short, width)
            above, above_defined = self.average(phase + GAUSS_NODE * short, width)
            narrow = dr.select(below_defined & above_defined, 0.5 * (below + above),
                               colour_at_mean_phase)
        return _blend(narrow, wide, share)
