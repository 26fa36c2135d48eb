"""Gradients of the reference noise and fractal sum, in float64 NumPy.

The twin of :func:`mimarble.texture.noise.noise3_gradient`, written from the other form of the
noise (:func:`mimarble.reference.noise.noise`): a sum over the 8 corners of
ω(dx)·ω(dy)·ω(dz)·(G · d), d the offset from the corner and
ω(t) = 1 − 10|t|³ + 15|t|⁴ − 6|t|⁵. By the product rule

    ∂N/∂x = Σ_c [ω′(dx) ω(dy) ω(dz) (G·d) + ω(dx) ω(dy) ω(dz) G_x],
    ω′(t) = −30 t² (|t| − 1)² · sign(t),

and ∇F = Σ_i ∇N(2^i v) (|N|: sign(N)·∇N); at gain ω and lacunarity λ,
∇F = Σ_i (ωλ)^i ∇N(λ^i v). Imports NumPy and the reference noise only.
"""

from __future__ import annotations

import numpy as np

from .noise import G, MAX_OCTAVES, P, mod256, omega, noise

__all__ = ["omega_derivative", "noise_gradient", "fractal_gradient"]


def omega_derivative(t):
    """ω′(t) for |t| < 1, else 0."""
    t = np.asarray(t, dtype=np.float64)
    a = np.abs(t)
    return np.where(a < 1.0, -30.0 * t * t * (a - 1.0) ** 2 * np.sign(t), 0.0)


def noise_gradient(x, y, z):
    """∇N at (x, y, z) (broadcast arrays) -> array of shape (..., 3), float64."""
    x, y, z = np.broadcast_arrays(*(np.asarray(c, dtype=np.float64) for c in (x, y, z)))
    shape = x.shape
    x, y, z = (c.ravel() for c in (x, y, z))
    xi, yi, zi = np.floor(x), np.floor(y), np.floor(z)
    X = (mod256(xi), (mod256(xi) + 1) & 255)
    Y = (mod256(yi), (mod256(yi) + 1) & 255)
    Z = (mod256(zi), (mod256(zi) + 1) & 255)
    d = [(x - xi, x - xi - 1.0), (y - yi, y - yi - 1.0), (z - zi, z - zi - 1.0)]
    w = [(omega(a), omega(b)) for a, b in d]
    dw = [(omega_derivative(a), omega_derivative(b)) for a, b in d]

    out = np.zeros(x.shape + (3,))
    for a in (0, 1):
        for b in (0, 1):
            for c in (0, 1):
                h = P[(P[(P[X[a]] + Y[b]) & 255] + Z[c]) & 255] & 15
                g = G[h]                                     # (n, 3)
                dot = g[:, 0] * d[0][a] + g[:, 1] * d[1][b] + g[:, 2] * d[2][c]
                weight = w[0][a] * w[1][b] * w[2][c]
                out[:, 0] += dw[0][a] * w[1][b] * w[2][c] * dot + weight * g[:, 0]
                out[:, 1] += w[0][a] * dw[1][b] * w[2][c] * dot + weight * g[:, 1]
                out[:, 2] += w[0][a] * w[1][b] * dw[2][c] * dot + weight * g[:, 2]
    return out.reshape(shape + (3,))


def fractal_gradient(points, octaves, turbulence=False, gain=0.5, lacunarity=2.0):
    """∇F at an (N, 3) array of points, F = Σ_{i<octaves} ω^i N(λ^i v) -> (N, 3)."""
    octaves = int(octaves)
    if not 0 <= octaves <= MAX_OCTAVES:
        raise ValueError(f"octaves must be in 0..{MAX_OCTAVES}, got {octaves}")
    v = np.asarray(points, dtype=np.float64)
    out = np.zeros(v.shape)
    for i in range(octaves):
        o = float(lacunarity) ** i
        g = noise_gradient(v[..., 0] * o, v[..., 1] * o, v[..., 2] * o)
        if turbulence:
            g = g * np.sign(noise(v[..., 0] * o, v[..., 1] * o, v[..., 2] * o))[..., None]
        out += g * (float(gain) * float(lacunarity)) ** i
    return out
