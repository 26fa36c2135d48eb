"""The marble formula of docs/design.md in float64 NumPy, on the tests' own noise (perlin64)."""

import numpy as np

import perlin64

PAPER_RAMP = np.array([(1.0, k / 8.0, 0.0) for k in range(8)])
AXES = {"x": 0, "y": 1, "z": 2}


def stripe(points, scale=1.0, period=1.0, distortion=1.0, octaves=8, function="abs_sine",
           axis="x", turbulence=False):
    v = np.asarray(points, dtype=np.float64) * scale
    phase = distortion * perlin64.fractal(v, octaves, turbulence) if distortion else 0.0
    a = v[:, AXES[axis]]
    if function == "abs_sine":
        return np.abs(np.sin(np.pi * (period * a + phase)))
    if function == "sine":
        return 0.5 * (np.sin(period * a + phase) + 1)
    return 0.5 * (np.cos(a + phase) + 1)


def ramp(t, colours=PAPER_RAMP):
    colours = np.asarray(colours, dtype=np.float64)
    if len(colours) == 1:
        return np.repeat(colours, len(t), axis=0)
    keys = np.linspace(0, 1, len(colours))
    t = np.clip(t, 0, 1)
    return np.stack([np.interp(t, keys, colours[:, c]) for c in range(3)], axis=1)


def colour(points, ramp_colours=PAPER_RAMP, **params):
    return ramp(stripe(points, **params), ramp_colours)
