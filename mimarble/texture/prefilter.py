"""The marble colour averaged over an interval of phase, exactly: the prefilter.

Over a pixel the phase φ of the marble (``mimarble/mitsuba/plugins/marble.py``) runs over an interval;
the pixel's colour is the mean of f(φ) = ramp(t(φ)) over it. f is periodic in φ, so
with its antiderivative G the mean over [φ − w/2, φ + w/2] is

    (G(φ + w/2) − G(φ − w/2)) / w,

two lookups, whatever w. G is exact here, in closed form. With y = φ/P + y₀ each
function's stripe becomes one shape of period 1 in y, symmetric about y = ½ but the
sawtooth's::

    abs_sine:  t = |sin πφ|        P = 1,   y₀ = 0     t = T(x) = sin πx
    sine:      t = ½(sin φ + 1)    P = 2π,  y₀ = ¼     t = T(x) = sin² πx
    cosine:    t = ½(cos φ + 1)    P = 2π,  y₀ = ½     t = T(x) = sin² πx
    triangle:  t = 1 − |1 − 2 frac φ|  P = 1, y₀ = 0   t = T(x) = 1 − |1 − 2x|
    sawtooth:  t = frac φ          P = 1,   y₀ = 0     t = T(x) = x (rising only)

with x = y − ⌊y⌋. The ramp is linear in t on each of its K − 1 pieces,
ramp = α_i + β_i t, β_i = (c_{i+1} − c_i)/(t_{i+1} − t_i), α_i = c_i − t_i β_i
(evenly spaced keys t_i = i/(K−1): β_i = (K−1)(c_{i+1} − c_i), α_i = c_i − i(c_{i+1} − c_i);
at positions, mimarble/texture/ramp.py, the end colours held to 0 and 1 as pieces of their own);
t crosses the keys at x_k = T⁻¹(t_k) rising and 1 − x_k falling, which cut the period
into 2(K−1) pieces j with boundaries B_j (the sawtooth: K − 1, rising). On a piece

    ∫_a^b f = α_i (b − a) + β_i ∫_a^b T,
    ∫_a^b sin πs ds   = (2/π) sin(π(a+b)/2) sin(π(b−a)/2)
    ∫_a^b sin² πs ds  = (b−a)/2 − cos(π(a+b)) sin(π(b−a)) / (2π)
    ∫_a^b T           = (b − a)·T((a+b)/2)     (triangle, sawtooth: T linear on a piece)

(products of sines: no cancellation as b → a, so a narrow interval inside one piece is
as accurate as a point). Whole pieces come from a table C_j = ∫_0^{B_j} f, linear in
the ramp colours (C = W·c, W built here in float64), so it follows ``mi.traverse``
edits and carries gradients to the ramp. An interval across pieces is the two end
partials plus C differences; across periods adds whole periods C_end.

Over a whole period the mean is C_end, the texture's mean colour (:func:`period_weights`).
The float64 twin (numerical quadrature, nothing shared) is
:mod:`mimarble.reference.prefilter`.
"""

from __future__ import annotations

import numpy as np

from mimarble.runtime import environment

dr, mi = environment.import_drjit_and_mitsuba()


#: Intervals of more periods than this are the period's mean (n_hi − n_lo stays exact).
_MANY_PERIODS = float(2 ** 20)


def piece_count(shape, size: int) -> int:
    """The pieces of a period: 2(K−1) for a symmetric shape (rising, then falling),
    K−1 for the sawtooth's ramp (rising only)."""
    return 2 * (size - 1) if shape.symmetric else size - 1


def piece_table(shape, size: int, keys=None) -> tuple[np.ndarray, np.ndarray]:
    """(B, W) for a stripe ``shape`` (mimarble/texture/stripes.py) and a ramp of ``size`` ≥ 2
    colours at ``keys`` (None: evenly spaced k/(K−1); else K non-decreasing keys from 0
    to 1, mimarble/texture/ramp.py): the n+1 piece boundaries B_j in [0, 1] (n =
    :func:`piece_count`) and the weights W (n+1, K) with C_j = ∫_0^{B_j} f = Σ_k W_jk c_k.
    An empty piece (two equal keys) has length 0 and weight 0."""
    last = size - 1
    evenly = keys is None
    keys = np.arange(size) / last if evenly else np.asarray(keys, dtype=np.float64)
    rising = shape.inverse(keys)
    if shape.symmetric:
        rising[-1] = 0.5
        boundaries = np.concatenate([rising, 1.0 - rising[-2::-1]])
    else:
        rising[-1] = 1.0
        boundaries = rising
    pieces = piece_count(shape, size)
    weights = np.zeros((pieces + 1, size))
    for j in range(pieces):
        i = j if j < last else 2 * last - 1 - j
        a, b = boundaries[j], boundaries[j + 1]
        length = b - a
        # ∫ c_i + (t − t_i)/(t_{i+1} − t_i)·(c_{i+1} − c_i) = c_i (L − m) + c_{i+1} m
        moment = shape.antiderivative(b) - shape.antiderivative(a) - keys[i] * length
        if evenly:
            m = last * moment
        else:
            width = keys[i + 1] - keys[i]
            m = moment / width if width > 0.0 else 0.0
        weights[j + 1] = weights[j]
        weights[j + 1, i] += length - m
        weights[j + 1, i + 1] += m
    return boundaries, weights


def period_weights(shape, size: int, keys=None) -> np.ndarray:
    """W_end (float64, exact): the mean colour over a period of phase, C_end, is
    Σ_k W_end,k c_k — what the texture averages to where its phase is spread uniformly."""
    return piece_table(shape, size, keys)[1][-1]


class PhaseAverage:
    """ramp∘t averaged over phase intervals, for one stripe function and ramp.

    The ramp (mimarble/texture/ramp.py) is read through its own ``piece`` and ``colour``, so
    exactly as the unfiltered texture reads it. ``DRJIT_STRUCT``: the tables, for Dr.Jit's
    traversal (``dr.freeze``) through the texture.
    """

    DRJIT_STRUCT = {"boundaries": object, "cumulative": object}

    def __init__(self, stripe, ramp):
        self.shape = stripe.shape
        self.last = ramp.count - 1
        self.pieces = piece_count(self.shape, ramp.count)
        self.ramp = ramp
        boundaries, self.weights = piece_table(self.shape, ramp.count)
        # Evenly spaced, the boundaries are the table's, made once. At positions they are
        # T⁻¹ of the ramp's own positions, in the kernel (:meth:`_boundary`): a table made
        # again at every edit was not an input a recorded pass (dr.freeze) followed —
        # measured: replayed passes read the first table's memory after it was freed.
        self.boundaries = None if ramp.positioned else mi.Float(boundaries)
        self.update()

    def update(self) -> None:
        """C = W·c from the ramp as it is now (a Color3f of K entries; gradients flow to
        the colours). With positions, W is made again from their values (float64, no
        derivative to the positions through the table)."""
        if self.ramp.positioned:
            self.weights = piece_table(self.shape, self.ramp.count, self.ramp.keys())[1]
        cumulative = dr.zeros(mi.Color3f, self.weights.shape[0])
        for k in range(self.weights.shape[1]):
            c_k = dr.gather(mi.Color3f, self.ramp.colours, mi.UInt32(k))
            cumulative += mi.Float(self.weights[:, k]) * c_k
        dr.eval(cumulative)
        self.cumulative = cumulative

    def __call__(self, phase, width):
        """The mean of ramp(t(φ)) over [phase − width/2, phase + width/2] (width ≥ 0),
        and a mask of the lanes where it is defined (an interval below float32's
        resolution of the phase, or a NaN: use the point)."""
        shape = self.shape
        y = shape.y(phase)
        half = width * (0.5 / shape.period)
        lo, hi = y - half, y + half
        n_lo, n_hi = dr.floor(lo), dr.floor(hi)
        x_lo, x_hi = lo - n_lo, hi - n_hi
        (alpha_lo, beta_lo), j_lo = self._piece_at(x_lo)
        (alpha_hi, beta_hi), j_hi = self._piece_at(x_hi)

        def partial(a, b, alpha, beta):
            return alpha * (b - a) + beta * shape.integral(a, b)

        # The mean is each integral over the length it integrates, both from the same
        # rounded numbers: lo − ⌊lo⌋ drops low bits of a negative lo, hi − lo would not.
        x_end = hi - n_lo
        inside, inside_length = partial(x_lo, x_end, alpha_lo, beta_lo), x_end - x_lo
        end_lo, start_hi = self._boundary(j_lo + 1), self._boundary(j_hi)
        periods = n_hi - n_lo
        whole = (dr.gather(mi.Color3f, self.cumulative, j_hi)
                 - dr.gather(mi.Color3f, self.cumulative, j_lo + 1)
                 + periods * self._period_integral())
        across = (partial(x_lo, end_lo, alpha_lo, beta_lo) + whole
                  + partial(start_hi, x_hi, alpha_hi, beta_hi))
        across_length = (end_lo - x_lo) + (periods + (start_hi - end_lo)) + (x_hi - start_hi)
        same = (periods == 0.0) & (j_lo == j_hi)
        length = dr.select(same, inside_length, across_length)
        mean = dr.select(same, inside, across) / length
        many = periods >= _MANY_PERIODS
        mean = dr.select(many, self._period_integral(), mean)
        return mean, many | (length > 0.0)

    def _boundary(self, j):
        """B_j: the table's, or at positions T⁻¹(P_k) rising (k = j) and 1 − T⁻¹(P_k)
        falling (k = 2(K−1) − j), the peak at ½ (the sawtooth: P_j, rising only)."""
        if not self.ramp.positioned:
            return dr.gather(mi.Float, self.boundaries, j)
        if not self.shape.symmetric:
            return self.ramp.position(j)
        falling = j > self.last
        k = dr.select(falling, 2 * self.last - j, j)
        x = dr.select(k == self.last, 0.5, self.shape.rising(self.ramp.position(k)))
        return dr.select(falling, 1.0 - x, x)

    def _period_integral(self):
        """∫ f over one period = its mean (the period is 1 in y)."""
        index = dr.full(mi.UInt32, self.pieces, 1)
        return dr.gather(mi.Color3f, self.cumulative, index)

    def _piece_at(self, x):
        """((α_i, β_i), j) of the piece holding x ∈ [0, 1)."""
        i, _ = self.ramp.piece(self.shape.stripe(x))
        j = dr.select(x < 0.5, i, 2 * self.last - 1 - i) if self.shape.symmetric else i
        return self.ramp.linear(i), j
