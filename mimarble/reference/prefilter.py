"""The marble colour averaged over an interval of phase, by quadrature, in float64.

The twin of :mod:`mimarble.texture.prefilter`, sharing nothing with it: the mean of
ramp(t(φ)) over [φ − w/2, φ + w/2] by composite Gauss–Legendre quadrature (4 nodes
on each of ``pieces`` equal sub-intervals) of the reference marble's own stripe and
ramp. f = ramp∘t is smooth between the ramp's keys and continuous across them, so the
error is that of the kinks, O(h²) with h = w/pieces: below 1e-7 of the colour range
with the default for any interval the tests use. The sawtooth jumps at every integer
phase: its interval is cut there first, and where t crosses a ramp key (t is φ − ⌊φ⌋
there, so at integer + key), each part integrated the same way: a jump inside a
sub-interval would make the error O(h), and between the cuts f is linear.

Imports NumPy and :mod:`mimarble.reference.marble` only.
"""

from __future__ import annotations

import numpy as np

from .marble import ramp, stripe_of_phase

__all__ = ["phase_average"]

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(4)


def phase_average(phase, width, function: str, colours, pieces: int = 4096,
                  positions=None) -> np.ndarray:
    """Mean colour over [phase − width/2, phase + width/2] for each (phase, width) → (N, 3),
    the ramp's colours at ``positions`` when given (evenly spaced without).

    A width of 0 gives the colour at the phase."""
    phase = np.atleast_1d(np.asarray(phase, dtype=np.float64))
    width = np.broadcast_to(np.asarray(width, dtype=np.float64), phase.shape)
    out = np.empty(phase.shape + (3,))
    for n, (centre, w) in enumerate(zip(phase, width)):
        if w == 0.0:
            out[n] = ramp(stripe_of_phase(centre, function), colours, positions)
            continue
        lo, hi = centre - 0.5 * w, centre + 0.5 * w
        cuts = [lo, hi]
        if function == "sawtooth":
            c = np.asarray(colours, dtype=np.float64).reshape(-1, 3)
            keys = np.linspace(0.0, 1.0, len(c)) if positions is None else \
                np.asarray(positions, dtype=np.float64)
            whole = np.arange(np.floor(lo), np.floor(hi) + 1.0)
            keys = np.concatenate([[0.0], keys])     # the jump, and where t meets a key
            inner = (whole[:, None] + keys[None, :]).ravel()
            cuts = [lo] + sorted(set(inner[(inner > lo) & (inner < hi)].tolist())) + [hi]
        total = np.zeros(3)
        for a, b in zip(cuts[:-1], cuts[1:]):
            count = max(1 if function == "sawtooth" else 8, int(round(pieces * (b - a) / w)))
            step = (b - a) / count
            mid = a + step * (np.arange(count) + 0.5)
            nodes = (mid[:, None] + 0.5 * step * _NODES[None, :]).ravel()
            values = ramp(stripe_of_phase(nodes, function), colours,
                          positions).reshape(count, len(_NODES), 3)
            total += (values * _WEIGHTS[None, :, None]).sum(axis=(0, 1)) * 0.5 * step
        out[n] = total / w
    return out
