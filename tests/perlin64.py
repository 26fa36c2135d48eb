"""An independent float64 Perlin noise for the tests: Shirley's sum-of-ω form.

Written from the paper's §2.2 (with its typo fixed: ω(t) = −6|t|⁵ + 15|t|⁴ −
10|t|³ + 1) and Perlin's 2002 gradient set, not from mimarble.texture.noise:

    n(x, y, z) = Σ_{corners (i,j,k) of the cell} ω(x−i) ω(y−j) ω(z−k) g_ijk·(x−i, y−j, z−k)

with g_ijk = G[P[(P[(P[i] + j) mod 256] + k) mod 256] mod 16]. Everything is
float64 NumPy; inputs are used exactly as given (floats convert exactly).
"""

import numpy as np

# Perlin's permutation, typed in again here so that a typo in the package's copy
# shows up as disagreement (it did once: a missing 222).
P = np.array([
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69, 142,
    8, 99, 37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219, 203,
    117, 35, 11, 32, 57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175, 74,
    165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122, 60, 211, 133, 230, 220,
    105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54, 65, 25, 63, 161, 1, 216, 80, 73, 209, 76, 132,
    187, 208, 89, 18, 169, 200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173, 186, 3,
    64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212, 207, 206, 59, 227,
    47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213, 119, 248, 152, 2, 44, 154, 163, 70, 221,
    153, 101, 155, 167, 43, 172, 9, 129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232, 178, 185,
    112, 104, 218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162, 241, 81, 51,
    145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157, 184, 84, 204, 176, 115, 121,
    50, 45, 127, 4, 150, 254, 138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141, 128, 195, 78,
    66, 215, 61, 156, 180], dtype=np.int64)

# Perlin 2002: the 12 cube-edge directions in hash order, padded to 16.
G = np.array([
    (1, 1, 0), (-1, 1, 0), (1, -1, 0), (-1, -1, 0),
    (1, 0, 1), (-1, 0, 1), (1, 0, -1), (-1, 0, -1),
    (0, 1, 1), (0, -1, 1), (0, 1, -1), (0, -1, -1),
    (1, 1, 0), (0, -1, 1), (-1, 1, 0), (0, -1, -1)], dtype=np.float64)


def omega(t):
    """The cubic-quintic weight of the paper's §2.2 (typo fixed), zero for |t| ≥ 1."""
    a = np.abs(t)
    return np.where(a < 1, -6 * a**5 + 15 * a**4 - 10 * a**3 + 1, 0.0)


def _mod256(c):
    """Exact c mod 256 of float64 integers of any size (fmod is exact in IEEE)."""
    r = np.fmod(c, 256.0)
    return np.where(r < 0, r + 256.0, r).astype(np.int64)


def noise(points):
    """Perlin improved noise at (N, 3) float64 points, by the sum-of-ω form."""
    pts = np.asarray(points, dtype=np.float64)
    cell = np.floor(pts)
    frac = pts - cell          # exact in float64 for inputs that came from float32
    base = _mod256(cell)
    total = np.zeros(len(pts))
    for i in (0, 1):
        for j in (0, 1):
            for k in (0, 1):
                corner = np.array([i, j, k])
                idx = (base + corner) % 256
                h = P[(P[(P[idx[:, 0]] + idx[:, 1]) % 256] + idx[:, 2]) % 256] % 16
                d = frac - corner
                weight = omega(d[:, 0]) * omega(d[:, 1]) * omega(d[:, 2])
                total += weight * np.einsum("nj,nj->n", G[h], d)
    return total


def fractal(points, octaves, turbulence=False):
    """Σ_{i<K} N(2^i p)/2^i in float64 (no octave is skipped)."""
    pts = np.asarray(points, dtype=np.float64)
    total = np.zeros(len(pts))
    for i in range(octaves):
        n = noise(pts * 2.0**i)
        total += (np.abs(n) if turbulence else n) / 2.0**i
    return total


def noise_float32_lerp_form(points):
    """Perlin's published reference code (lerp form), emulated in NumPy float32.

    Operation for operation the Java reference with float in place of double:
    the Dr.Jit implementation must agree with it bit for bit on a backend that
    does not fuse multiply-adds.
    """
    f = np.float32
    pts = np.asarray(points, dtype=np.float32)
    perm = np.concatenate([P, P])
    cell = np.floor(pts)
    X, Y, Z = (_mod256(cell[:, a].astype(np.float64)) for a in range(3))
    x, y, z = (pts[:, a] - cell[:, a] for a in range(3))

    def fade(t):
        return t * t * t * (t * (t * f(6) - f(15)) + f(10))

    def lerp(t, a, b):
        return a + t * (b - a)

    def grad(h, gx, gy, gz):
        h = h & 15
        u = np.where(h < 8, gx, gy)
        v = np.where(h < 4, gy, np.where((h == 12) | (h == 14), gx, gz))
        return np.where(h & 1 == 0, u, -u) + np.where(h & 2 == 0, v, -v)

    u, v, w = fade(x), fade(y), fade(z)
    x1, y1, z1 = x - f(1), y - f(1), z - f(1)
    A = perm[X] + Y
    AA, AB = perm[A] + Z, perm[A + 1] + Z
    B = perm[X + 1] + Y
    BA, BB = perm[B] + Z, perm[B + 1] + Z
    return lerp(w, lerp(v, lerp(u, grad(perm[AA], x, y, z), grad(perm[BA], x1, y, z)),
                        lerp(u, grad(perm[AB], x, y1, z), grad(perm[BB], x1, y1, z))),
                lerp(v, lerp(u, grad(perm[AA + 1], x, y, z1), grad(perm[BA + 1], x1, y, z1)),
                        lerp(u, grad(perm[AB + 1], x, y1, z1), grad(perm[BB + 1], x1, y1, z1))))
