"""The marble's colour ramp: K colours at keys in [0, 1], piecewise linear in t ∈ [0, 1].

Evenly spaced (the paper's ramp, keys k/(K−1))::

    ramp(t) = lerp(c_i, c_{i+1}, f),   x = clamp(t, 0, 1)·(K−1),  i = ⌊x⌋ ∈ 0..K−2,  f = x − i
    ramp′(t) = (K−1)·(c_{i+1} − c_i)   (0 outside [0, 1])

At positions p_0 ≤ … ≤ p_{K−1} in [0, 1] (``ramp_positions``: POV-Ray's ``color_map``,
Blender's ColorRamp) the ramp is held as K + 2 entries, the end colours repeated at 0
and 1 (so that below p_0 and above p_{K−1} the end colours hold, with pieces the
prefilter can integrate like any other), P = (0, p_0, …, p_{K−1}, 1)::

    i = the largest in 0..K with P_i ≤ x,   x = clamp(t, 0, 1)
    ramp(t) = lerp(C_i, C_{i+1}, f),   f = (x − P_i)/(P_{i+1} − P_i)   (1 where P_{i+1} = P_i)
    ramp′(t) = (C_{i+1} − C_i)/(P_{i+1} − P_i)   (0 on an empty piece and outside [0, 1])

so two equal positions are a step, its upper colour from the position on. i is found
by a binary search of ⌈log₂(K+1)⌉ gathers, unrolled (K is structural).

The colours live in one container that ``mi.traverse`` edits in place: a ``Color3f`` of
K entries in JIT variants (gathered in the kernel, opaque, differentiable), a (K, 3)
``TensorXf`` in the scalar variant, whose lookups read a list of colours made from it
whenever it changes (Mitsuba cannot write into a Python list); the positions likewise,
a ``Float`` of K entries (scalar variant: an ``ArrayXf``). The K + 2 entries are
gathered from them whenever they change, so derivatives reach both.
"""

from __future__ import annotations

import numpy as np

from mimarble.runtime import environment
from .prefilter import period_weights

dr, mi = environment.import_drjit_and_mitsuba()


def ramp_storage(colours):
    """The container of a ramp's colours for ``mi.traverse`` (see the module docstring)."""
    if dr.is_jit_v(mi.Float):
        return mi.Color3f(*zip(*colours))
    return dr.scalar.TensorXf(np.asarray(colours, dtype=np.float32).reshape(-1, 3))


def positions_storage(positions):
    """The container of a ramp's positions for ``mi.traverse``."""
    if dr.is_jit_v(mi.Float):
        return mi.Float([float(p) for p in positions])
    return dr.scalar.ArrayXf([float(p) for p in positions])


class Ramp:
    """The colours, their lookups in the kernel, and their facts (size, mean).

    ``DRJIT_STRUCT``: Dr.Jit's traversal (``dr.freeze``) sees the colours through the
    texture that holds the ramp, so a recording takes them as inputs."""

    DRJIT_STRUCT = {"storage": object, "colours": object, "positions_storage": object,
                    "positions": object}

    def __init__(self, storage, positions_storage=None):
        self.storage = storage
        self.positions_storage = positions_storage
        self.positions = None
        self.changed()

    @property
    def positioned(self) -> bool:
        """Whether the colours sit at given positions (structural), not evenly spaced."""
        return self.positions_storage is not None

    def changed(self) -> None:
        """Read the colours again (after ``mi.traverse`` wrote new ones) and keep them
        opaque: a new value reuses the compiled kernel."""
        if dr.is_jit_v(mi.Float):
            self.size = dr.width(self.storage)
            dr.make_opaque(self.storage)
            if not self.positioned:
                self.colours = self.storage
            else:
                dr.make_opaque(self.positions_storage)
                ends = [0] + list(range(self.size)) + [self.size - 1]
                self.colours = dr.gather(mi.Color3f, self.storage, mi.UInt32(ends))
                inner = dr.gather(mi.Float, self.positions_storage, mi.UInt32(ends))
                k = dr.arange(mi.UInt32, self.size + 2)
                self.positions = dr.select(k == 0, 0.0, dr.select(k == self.size + 1, 1.0,
                                                                   inner))
                dr.eval(self.colours, self.positions)
        else:
            colours = self.numpy()
            self.size = len(colours)
            if self.positioned:
                colours = np.concatenate([colours[:1], colours, colours[-1:]])
                self.positions = [0.0] + [float(p) for p in self.positions_numpy()] + [1.0]
            self.colours = [mi.Color3f(*map(float, c)) for c in colours]
        #: Entries of the kernel's colour list: K, or K + 2 with positions.
        self.count = self.size + 2 if self.positioned else self.size

    def numpy(self) -> np.ndarray:
        """The colours as float64 (K, 3)."""
        if dr.is_jit_v(mi.Float):   # component by component: no kernel packs them first
            return np.stack([np.asarray(dr.detach(self.storage[k]).numpy(), dtype=np.float64)
                             for k in range(3)], axis=1)
        return np.array(self.storage, dtype=np.float64).reshape(-1, 3)

    def positions_numpy(self) -> np.ndarray:
        """The positions as float64 (K,) (positioned ramps only)."""
        storage = dr.detach(self.positions_storage) if dr.is_jit_v(mi.Float) \
            else self.positions_storage
        return np.asarray(np.array(storage), dtype=np.float64).ravel()

    def keys(self) -> np.ndarray:
        """The keys of the kernel's :attr:`count` entries, float64: k/(K−1), or
        (0, p_0, …, p_{K−1}, 1)."""
        if not self.positioned:
            return np.arange(self.size) / (self.size - 1)
        return np.concatenate([[0.0], self.positions_numpy(), [1.0]])

    def mean(self, stripe):
        """The mean colour where the phase of ``stripe`` is spread uniformly: Σ_k w_k c_k
        with the weights of one period of the prefilter's table (exact), as a Dr.Jit
        colour, so that it carries derivatives to the colours."""
        if self.size == 1:
            return self.constant(1) if dr.is_jit_v(mi.Float) else self.colour(0)
        weights = period_weights(stripe.shape, self.count,
                                 self.keys() if self.positioned else None)
        index = (lambda k: mi.UInt32(k)) if dr.is_jit_v(mi.Float) else int
        total = self.colour(index(0)) * float(weights[0])
        for k in range(1, self.count):
            total = total + self.colour(index(k)) * float(weights[k])
        return total

    # In the kernel

    def __call__(self, t):
        """ramp(t). The gather index is in 0..K−2 by construction, whatever t is: a NaN t
        (whose ⌊x⌋ converts to 2^31 on x86, an out-of-bounds read that kills the process
        on AVX2 machines) reads key 0, and the NaN reaches the colour through f. One
        colour is a constant (its index must not come from ⌊t·0⌋ − 1)."""
        if self.size == 1:
            return self.constant(dr.width(t))
        index, f = self.piece(t)
        return dr.lerp(self.colour(index), self.colour(index + 1), f)

    def constant(self, width: int):
        """The first colour, ``width`` lanes of it (a one-colour ramp everywhere)."""
        return self.colour(dr.zeros(mi.UInt32, width) if dr.is_jit_v(mi.Float) else 0)

    def piece(self, t):
        """(i, f): t on the ramp's piece i (0..count−2, NaN-proof, see :meth:`__call__`)
        at f."""
        if self.positioned:
            return self._positioned_piece(t)
        last = self.size - 1
        x = dr.clip(t, 0.0, 1.0) * last
        i = dr.floor(x)
        i = dr.select((i >= 0.0) & (i <= last - 1), i, dr.select(i > 0.0, last - 1, 0.0))
        return dr.uint32_array_t(type(x))(i), x - i

    def _positioned_piece(self, t):
        """The largest i ≤ count − 2 with P_i ≤ x, by binary lifting over the sorted keys:
        each candidate index is clamped into the array, so every gather is in bounds, and
        a NaN x passes no comparison (i = 0, f NaN)."""
        x = dr.clip(t, 0.0, 1.0)
        top = self.count - 2
        jit = dr.is_jit_v(mi.Float)
        i = dr.zeros(dr.uint32_array_t(type(x)), dr.width(x)) if jit else 0
        step = 1 << max(top.bit_length() - 1, 0)
        while step:
            candidate = i + step
            below = self.position(dr.minimum(candidate, top) if jit else min(candidate, top))
            i = dr.select((candidate <= top) & (below <= x), candidate, i)
            step >>= 1
        start, end = self.position(i), self.position(i + 1)
        width = end - start
        # P_i ≤ x ≤ P_{i+1} (x < P_{i+1} below the last piece), so f ∈ [0, 1] as rounded.
        return i, dr.select(width > 0.0, (x - start) / dr.select(width > 0.0, width, 1.0), 1.0)

    def linear(self, i):
        """(α_i, β_i) with ramp(t) = α_i + β_i·t on piece i (the prefilter's pieces)."""
        below, above = self.colour(i), self.colour(i + 1)
        step = above - below
        if not self.positioned:
            return below - mi.Float(i) * step, step * float(self.size - 1)
        start, end = self.position(i), self.position(i + 1)
        width = end - start
        beta = step / dr.select(width > 0.0, width, 1.0)
        beta = dr.select(width > 0.0, beta, 0.0)
        return dr.select(width > 0.0, below - start * beta, above), beta

    def slope(self, t):
        """ramp′(t) on the piece t falls in, 0 outside [0, 1] (and on an empty piece)."""
        index, _ = self.piece(t)
        step = self.colour(index + 1) - self.colour(index)
        inside = (t >= 0.0) & (t <= 1.0)
        if not self.positioned:
            return dr.select(inside, step * float(self.size - 1), 0.0)
        width = self.position(index + 1) - self.position(index)
        slope = step / dr.select(width > 0.0, width, 1.0)
        return dr.select(inside & (width > 0.0), slope, 0.0)

    def colour(self, index):
        """c_index (of the kernel's :attr:`count` entries)."""
        if isinstance(self.colours, list):
            return self.colours[index]
        return dr.gather(mi.Color3f, self.colours, index)

    def position(self, index):
        """P_index (positioned ramps)."""
        if isinstance(self.positions, list):
            return self.positions[index]
        return dr.gather(mi.Float, self.positions, index)
