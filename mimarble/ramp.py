"""The marble's colour ramp: K colours at keys k/(K−1), piecewise linear in t ∈ [0, 1].

    ramp(t) = lerp(c_i, c_{i+1}, f),   x = clamp(t, 0, 1)·(K−1),  i = ⌊x⌋ ∈ 0..K−2,  f = x − i
    ramp′(t) = (K−1)·(c_{i+1} − c_i)   (0 outside [0, 1])

The colours live in one container that ``mi.traverse`` edits in place: a ``Color3f`` of
K entries in JIT variants (gathered in the kernel, opaque, differentiable), a (K, 3)
``TensorXf`` in the scalar variant, whose lookups read a list of colours made from it
whenever it changes (Mitsuba cannot write into a Python list).
"""

from __future__ import annotations

import numpy as np

from . import environment
from .prefilter import period_weights

dr, mi = environment.import_drjit_and_mitsuba()


def ramp_storage(colours):
    """The container of a ramp's colours for ``mi.traverse`` (see the module docstring)."""
    if dr.is_jit_v(mi.Float):
        return mi.Color3f(*zip(*colours))
    return dr.scalar.TensorXf(np.asarray(colours, dtype=np.float32).reshape(-1, 3))


class Ramp:
    """The colours, their lookups in the kernel, and their facts (size, mean).

    ``DRJIT_STRUCT``: Dr.Jit's traversal (``dr.freeze``) sees the colours through the
    texture that holds the ramp, so a recording takes them as inputs."""

    DRJIT_STRUCT = {"storage": object, "colours": object}

    def __init__(self, storage):
        self.storage = storage
        self.changed()

    def changed(self) -> None:
        """Read the colours again (after ``mi.traverse`` wrote new ones) and keep them
        opaque: a new value reuses the compiled kernel."""
        if dr.is_jit_v(mi.Float):
            self.colours = self.storage
            self.size = dr.width(self.storage)
            dr.make_opaque(self.storage)
        else:
            self.colours = [mi.Color3f(*map(float, c)) for c in self.numpy()]
            self.size = len(self.colours)

    def numpy(self) -> np.ndarray:
        """The colours as float64 (K, 3)."""
        if dr.is_jit_v(mi.Float):   # component by component: no kernel packs them first
            return np.stack([np.asarray(dr.detach(self.storage[k]).numpy(), dtype=np.float64)
                             for k in range(3)], axis=1)
        return np.array(self.storage, dtype=np.float64).reshape(-1, 3)

    def mean(self, stripe):
        """The mean colour where the phase of ``stripe`` is spread uniformly: Σ_k w_k c_k
        with the weights of one period of the prefilter's table (exact), as a Dr.Jit
        colour, so that it carries derivatives to the ramp."""
        if self.size == 1:
            return self.constant(1) if dr.is_jit_v(mi.Float) else self.colour(0)
        weights = period_weights(stripe.shape, self.size)
        index = (lambda k: mi.UInt32(k)) if dr.is_jit_v(mi.Float) else int
        total = self.colour(index(0)) * float(weights[0])
        for k in range(1, self.size):
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
        """(i, f): t on the ramp's piece i (0..K−2, NaN-proof, see :meth:`__call__`) at f."""
        last = self.size - 1
        x = dr.clip(t, 0.0, 1.0) * last
        i = dr.floor(x)
        i = dr.select((i >= 0.0) & (i <= last - 1), i, dr.select(i > 0.0, last - 1, 0.0))
        return dr.uint32_array_t(type(x))(i), x - i

    def slope(self, t):
        """ramp′(t): (K−1)·(c_{i+1} − c_i) on the piece t falls in, 0 outside [0, 1]."""
        index, _ = self.piece(t)
        step = self.colour(index + 1) - self.colour(index)
        return dr.select((t >= 0.0) & (t <= 1.0), step * float(self.size - 1), 0.0)

    def colour(self, index):
        """c_index."""
        if isinstance(self.colours, list):
            return self.colours[index]
        return dr.gather(mi.Color3f, self.colours, index)
