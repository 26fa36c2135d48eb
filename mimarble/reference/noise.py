"""Perlin's improved noise (2002) in float64 NumPy, in Shirley's sum-of-ω form.

This is the reference tracer's own noise. It is written from the paper's §2.2
(Park & Park 2004, after Shirley) with the paper's typo fixed — the weight is a
quintic, not a sextic::

    ω(t) = −6|t|⁵ + 15|t|⁴ − 10|t|³ + 1   for |t| < 1,   0 otherwise

    n(x, y, z) = Σ_{corners (i, j, k) of the cell of (x, y, z)}
                 ω(x−i) ω(y−j) ω(z−k) · g_ijk · (x−i, y−j, z−k)

    g_ijk = G[ P[(P[(P[i mod 256] + j mod 256) mod 256] + k mod 256) mod 256] & 15 ]

with ``P`` Perlin's permutation and ``G`` the 16 gradients of his 2002 code in
hash order (the 12 cube-edge directions, then 4 of them again as padding). It
is the same function as Perlin's lerp form (``ImprovedNoise.noise``): ω(t) is
1 − fade(|t|), and ``lerp`` of the 8 corner dot products with fade weights
expands to this sum.

It imports NumPy only — nothing of ``mimarble.texture.noise`` (the Dr.Jit path it is
meant to check). Every step is exact or correctly rounded in float64:
``floor`` and ``x − floor(x)`` are exact, and the lattice coordinate is reduced
modulo 256 with ``np.fmod`` on the float64 integer (exact in IEEE arithmetic),
so even coordinates like 1e20 hash correctly (they are lattice points: the
noise there is exactly 0).

The fractal sum is the paper's ``Fractal3`` (Fig. 6)::

    F(v, K) = Σ_{i<K} N(2^i v) / 2^i           (|N| with turbulence)

evaluated for every octave (no octave is skipped, up to 64); ``2^i v`` is an
exact scaling in float64. With another gain ω and lacunarity λ (POV-Ray's omega and
lambda; the paper's are ½ and 2) it is Σ_{i<K} ω^i N(λ^i v), ω^i and λ^i as float64
powers (``ω ** i``: exact at the paper's values, so its sum is the same).
"""

from __future__ import annotations

import numpy as np

from mimarble.contract import MAX_OCTAVES, NOISE_BOUND

__all__ = ["P", "G", "omega", "noise", "noise3", "fractal", "fractal3", "MAX_OCTAVES", "NOISE_BOUND",
           "mod256"]

# Ken Perlin's permutation of 0..255 (ImprovedNoise.java, 2002).
P = np.array([
    151, 160, 137, 91, 90, 15,
    131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69, 142, 8, 99, 37, 240, 21, 10, 23,
    190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219, 203, 117, 35, 11, 32, 57, 177, 33,
    88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175, 74, 165, 71, 134, 139, 48, 27, 166,
    77, 146, 158, 231, 83, 111, 229, 122, 60, 211, 133, 230, 220, 105, 92, 41, 55, 46, 245, 40, 244,
    102, 143, 54, 65, 25, 63, 161, 1, 216, 80, 73, 209, 76, 132, 187, 208, 89, 18, 169, 200, 196,
    135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173, 186, 3, 64, 52, 217, 226, 250, 124, 123,
    5, 202, 38, 147, 118, 126, 255, 82, 85, 212, 207, 206, 59, 227, 47, 16, 58, 17, 182, 189, 28, 42,
    223, 183, 170, 213, 119, 248, 152, 2, 44, 154, 163, 70, 221, 153, 101, 155, 167, 43, 172, 9,
    129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232, 178, 185, 112, 104, 218, 246, 97, 228,
    251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162, 241, 81, 51, 145, 235, 249, 14, 239, 107,
    49, 192, 214, 31, 181, 199, 106, 157, 184, 84, 204, 176, 115, 121, 50, 45, 127, 4, 150, 254,
    138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141, 128, 195, 78, 66, 215, 61, 156, 180,
], dtype=np.int64)
P.setflags(write=False)

# Perlin 2002's gradients, indexed by hash & 15 (his grad(): u = h<8 ? x : y,
# v = h<4 ? y : h==12||h==14 ? x : z, signs from bits 0 and 1).
G = np.array([
    (1, 1, 0), (-1, 1, 0), (1, -1, 0), (-1, -1, 0),
    (1, 0, 1), (-1, 0, 1), (1, 0, -1), (-1, 0, -1),
    (0, 1, 1), (0, -1, 1), (0, 1, -1), (0, -1, -1),
    (1, 1, 0), (0, -1, 1), (-1, 1, 0), (0, -1, -1),
], dtype=np.float64)
G.setflags(write=False)
_GX, _GY, _GZ = (np.ascontiguousarray(G[:, c]) for c in range(3))


def omega(t):
    """The weight ω(t) = −6|t|⁵ + 15|t|⁴ − 10|t|³ + 1 for |t| < 1, else 0."""
    a = np.abs(np.asarray(t, dtype=np.float64))
    return np.where(a < 1.0, ((-6.0 * a + 15.0) * a - 10.0) * a * a * a + 1.0, 0.0)


def mod256(c):
    """``c mod 256`` in 0..255 (int64) of float64 integers of any magnitude; exact."""
    r = np.fmod(c, 256.0)
    r = np.where(r < 0.0, r + 256.0, r)
    return r.astype(np.int64)


def noise(x, y, z):
    """Perlin improved noise at (x, y, z) (broadcast arrays or scalars), float64.

    A scalar input gives a 0-d array; use ``float()`` for a Python number.
    """
    x, y, z = np.broadcast_arrays(*(np.asarray(c, dtype=np.float64) for c in (x, y, z)))
    shape = x.shape
    x, y, z = (c.ravel() for c in (x, y, z))

    xi, yi, zi = np.floor(x), np.floor(y), np.floor(z)
    fx, fy, fz = x - xi, y - yi, z - zi          # exact, in [0, 1)
    X0, Y0, Z0 = mod256(xi), mod256(yi), mod256(zi)
    X1, Y1, Z1 = (X0 + 1) & 255, (Y0 + 1) & 255, (Z0 + 1) & 255

    # Per-axis offsets to the two corners and their weights.
    dx = (fx, fx - 1.0)
    dy = (fy, fy - 1.0)
    dz = (fz, fz - 1.0)
    wx = (omega(dx[0]), omega(dx[1]))
    wy = (omega(dy[0]), omega(dy[1]))
    wz = (omega(dz[0]), omega(dz[1]))

    total = np.zeros_like(x)
    for a, Xa in enumerate((X0, X1)):
        pa = P[Xa]
        for b, Yb in enumerate((Y0, Y1)):
            pab = P[(pa + Yb) & 255]
            wab = wx[a] * wy[b]
            for c, Zc in enumerate((Z0, Z1)):
                h = P[(pab + Zc) & 255] & 15
                dot = _GX[h] * dx[a] + _GY[h] * dy[b] + _GZ[h] * dz[c]
                total += wab * wz[c] * dot
    return total.reshape(shape)


def noise3(points):
    """Noise at an (N, 3) array of points -> (N,)."""
    p = np.asarray(points, dtype=np.float64)
    return noise(p[..., 0], p[..., 1], p[..., 2])


def fractal(x, y, z, octaves, turbulence=False, gain=0.5, lacunarity=2.0):
    """``F = Σ_{i<octaves} ω^i N(λ^i v)`` at v = (x, y, z), ω = ``gain``, λ =
    ``lacunarity`` (the paper's: N(2^i v)/2^i); ``|N|`` with turbulence."""
    octaves = int(octaves)
    if not 0 <= octaves <= MAX_OCTAVES:
        raise ValueError(f"octaves must be in 0..{MAX_OCTAVES}, got {octaves}")
    gain, lacunarity = float(gain), float(lacunarity)
    x, y, z = np.broadcast_arrays(*(np.asarray(c, dtype=np.float64) for c in (x, y, z)))
    total = np.zeros(x.shape)
    for i in range(octaves):
        o = lacunarity ** i                      # 2^i: an exact power of two
        n = noise(x * o, y * o, z * o)
        if turbulence:
            n = np.abs(n)
        total += n * gain ** i                   # 2^−i: n / 2^i exactly
    return total


def fractal3(points, octaves, turbulence=False, gain=0.5, lacunarity=2.0):
    """The paper's ``Fractal3(v, octaves)`` at an (N, 3) array of points -> (N,)."""
    p = np.asarray(points, dtype=np.float64)
    return fractal(p[..., 0], p[..., 1], p[..., 2], octaves, turbulence, gain, lacunarity)
