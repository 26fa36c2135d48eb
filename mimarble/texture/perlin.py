"""Ken Perlin's improved noise (SIGGRAPH 2002) and its exact gradient, in Dr.Jit.

The same functions run on every Dr.Jit array type: the scalar variant's Python
floats, LLVM and CUDA arrays (with or without AD), in float32 or float64 — the
type of the input point decides. Inside a Mitsuba kernel they are traced once.

    noise3(p)            N(p), improved noise, |N| ≤ 1.0364 (not 1)
    noise3_gradient(p)   (N(p), ∇N(p)) in one pass, N bit for bit noise3's

The octave sums over it are in :mod:`mimarble.texture.fbm`.

The gradient: N is a trilinear interpolation, with weights u = fade(x), v = fade(y),
w = fade(z), of the eight corner values d_c = G_c · (p − corner_c), G_c the corner's
gradient vector. So, with L(u, v, w; values) the nested lerps of :func:`trilinear`::

    ∂N/∂x = L(u, v, w; G_x) + fade′(x) · ∂L/∂u,    fade′(t) = 30 t² (t − 1)²
    ∂L/∂u = lerp(w, lerp(v, d₁ − d₀, d₃ − d₂), lerp(v, d₅ − d₄, d₇ − d₆))

and likewise for y and z (each corner value is linear in p, so its own gradient is
G_c, read off :func:`grad` by its linearity: G = (grad(h, 1, 0, 0), grad(h, 0, 1, 0),
grad(h, 0, 0, 1)), exactly). The float64 twin, written from the sum-of-ω form, is
:mod:`mimarble.reference.noise_gradient`.

Numerical safety, for every finite input:

* The lattice cell is wrapped modulo 256 *in floating point* before any
  float→int conversion: ``c − 256·⌊c/256⌋`` is exact for every float (each step
  is exact scaling or an exactly representable difference), so even 1e20 gives
  an index in [0, 256) and never an out-of-range conversion (LLVM poison).
* Octave frequencies cannot overflow: a coordinate with |x| ≥ 2^24 is an even
  integer, so ``2^i·x`` and ``2^i·(x mod 256)`` fall on the same lattice cell
  with zero fraction; such coordinates are wrapped once before the octave loop,
  after which 2^i·x < 2^88 for every i < 64.

Non-finite input (NaN, ±Inf) gives NaN out, never an error or an abort: the
lattice index of such lanes is replaced by 0 before the integer conversion and
the NaN then propagates through the arithmetic.
"""

from __future__ import annotations

import functools

import numpy as np

from mimarble.contract import FLOAT32_INTEGER_LIMIT, NOISE_BOUND
from mimarble.runtime import environment

dr, mi = environment.import_drjit_and_mitsuba()

# Perlin's reference permutation (improved noise, 2002).
PERMUTATION = (
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69,
    142, 8, 99, 37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219,
    203, 117, 35, 11, 32, 57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175,
    74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122, 60, 211, 133, 230,
    220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54, 65, 25, 63, 161, 1, 216, 80, 73, 209, 76,
    132, 187, 208, 89, 18, 169, 200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173,
    186, 3, 64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212, 207, 206,
    59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213, 119, 248, 152, 2, 44, 154, 163,
    70, 221, 153, 101, 155, 167, 43, 172, 9, 129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232,
    178, 185, 112, 104, 218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162,
    241, 81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157, 184, 84, 204,
    176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141,
    128, 195, 78, 66, 215, 61, 156, 180,
)


_TWO_24 = FLOAT32_INTEGER_LIMIT


def fade(t):
    """Perlin's quintic 6t⁵ − 15t⁴ + 10t³: C² at the lattice, so no visible creases."""
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def lerp(t, a, b):
    return a + t * (b - a)


def grad(h, x, y, z):
    """Dot product of (x, y, z) with the gradient that hash ``h`` selects.

    The 12 cube-edge directions, padded to 16 (Perlin 2002): no table lookup,
    the low four bits pick the components and their signs.
    """
    h = h & 15
    u = dr.select(h < 8, x, y)
    v = dr.select(h < 4, y, dr.select((h == 12) | (h == 14), x, z))
    return dr.select((h & 1) == 0, u, -u) + dr.select((h & 2) == 0, v, -v)


@functools.lru_cache(maxsize=None)
def _pair_table(uint_type):
    """P[k] | P[k+1] << 8 for k in 0..511 (P doubled, and doubled again at the end).

    Perlin's code always reads P[k] together with P[k+1] (the two corners
    along one axis), so one gather of a packed pair replaces two (the last four
    of the 5 gathers per noise; :func:`_corner_table` does the first two levels),
    bit for bit the same hashes. A tuple in scalar mode.
    """
    p = PERMUTATION * 3
    pairs = tuple(p[k] | (p[k + 1] << 8) for k in range(512))
    return uint_type(pairs) if dr.is_jit_v(uint_type) else pairs


@functools.lru_cache(maxsize=None)
def _corner_table(uint_type):
    """The first two hash levels of Perlin's code merged, for every cell column (X, Y).

    Entry 256·X + Y packs the four bytes P[A], P[A+1], P[B], P[B+1] with
    A = P[X] + Y and B = P[X+1] + Y, so one gather replaces three (7 → 5 per
    noise); 256 KiB, bit for bit the same hashes. A tuple in scalar mode.
    """
    p = np.array(PERMUTATION * 3, dtype=np.uint32)
    x, y = np.arange(256)[:, None], np.arange(256)[None, :]   # NumPy: 1 ms, a loop 60 ms
    a, b = p[x] + y, p[x + 1] + y
    entries = (p[a] | (p[a + 1] << 8) | (p[b] << 16) | (p[b + 1] << 24)).ravel()
    return uint_type(entries) if dr.is_jit_v(uint_type) else tuple(entries.tolist())


def lattice_tables(uint_type) -> tuple:
    """The two permutation tables every noise evaluation gathers from (made once per
    type). A texture holds them as its own members, as Mitsuba's C++ plugins hold their
    data, so that Dr.Jit's traversal finds them: a recording of its kernels
    (``dr.freeze``) refuses a variable made before it that no input reaches."""
    return _corner_table(uint_type), _pair_table(uint_type)


def _gather_corners(table, index):
    """(P[A], P[A+1], P[B], P[B+1]) from one gather of :func:`_corner_table`."""
    packed = table[index] if isinstance(table, tuple) else dr.gather(type(table), table, index)
    return packed & 255, (packed >> 8) & 255, (packed >> 16) & 255, packed >> 24


def _gather_pair(table, index):
    """(P[index], P[index + 1]) from one gather of the packed table."""
    packed = table[index] if isinstance(table, tuple) else dr.gather(type(table), table, index)
    return packed & 255, packed >> 8


def _lattice(x, uint_type):
    """Split x into its cell index ⌊x⌋ mod 256 and the fraction x − ⌊x⌋ ∈ [0, 1]."""
    cell = dr.floor(x)
    frac = x - cell
    wrapped = cell - 256.0 * dr.floor(cell * (1.0 / 256.0))   # exact: see module docstring
    wrapped = dr.select(dr.isfinite(wrapped), wrapped, 0.0)   # NaN/Inf lanes: index 0, NaN out
    return uint_type(wrapped), frac


def corner_hashes(p):
    """The cell fractions (x, y, z) of ``p`` and the hashes of its 8 cube corners,
    (hAA, hBA, hAB, hBB, hAA1, hBA1, hAB1, hBB1): corner (i, j, k) of the cell is
    ``A``/``B`` for i = 0/1, the first/second letter's ``A``/``B`` for j, ``1`` for k = 1."""
    float_type = type(p.x)
    uint_type = dr.uint32_array_t(float_type)
    pairs = _pair_table(uint_type)

    X, x = _lattice(p.x, uint_type)
    Y, y = _lattice(p.y, uint_type)
    Z, z = _lattice(p.z, uint_type)

    # Hash the 8 cube corners exactly as Perlin's reference code does
    # (A = P[X]+Y, AA = P[A]+Z, AB = P[A+1]+Z, B = P[X+1]+Y, …): the first two
    # levels from one gather of the (X, Y) table, then each P[k], P[k+1] couple
    # with one gather. Indices: 256·X + Y < 65536, and PA + Z ≤ 510 < 512.
    PA, PA1, PB, PB1 = _gather_corners(_corner_table(uint_type), X * 256 + Y)
    AA, AB, BA, BB = PA + Z, PA1 + Z, PB + Z, PB1 + Z
    hAA, hAA1 = _gather_pair(pairs, AA)
    hBA, hBA1 = _gather_pair(pairs, BA)
    hAB, hAB1 = _gather_pair(pairs, AB)
    hBB, hBB1 = _gather_pair(pairs, BB)
    return (x, y, z), (hAA, hBA, hAB, hBB, hAA1, hBA1, hAB1, hBB1)


def corner_dots(fractions, hashes):
    """Each corner's gradient dotted with the offset from that corner, in the order of
    :func:`corner_hashes`."""
    x, y, z = fractions
    x1, y1, z1 = x - 1.0, y - 1.0, z - 1.0
    hAA, hBA, hAB, hBB, hAA1, hBA1, hAB1, hBB1 = hashes
    return (grad(hAA, x, y, z), grad(hBA, x1, y, z), grad(hAB, x, y1, z), grad(hBB, x1, y1, z),
            grad(hAA1, x, y, z1), grad(hBA1, x1, y, z1), grad(hAB1, x, y1, z1),
            grad(hBB1, x1, y1, z1))


def trilinear(u, v, w, c):
    """Perlin's nested lerps of 8 corner values ``c`` (order of :func:`corner_hashes`)."""
    return lerp(w, lerp(v, lerp(u, c[0], c[1]), lerp(u, c[2], c[3])),
                   lerp(v, lerp(u, c[4], c[5]), lerp(u, c[6], c[7])))


def noise3(p):
    """Improved noise N(p) at a Dr.Jit 3-vector ``p`` (any backend, float32 or float64)."""
    fractions, hashes = corner_hashes(p)
    x, y, z = fractions
    return trilinear(fade(x), fade(y), fade(z), corner_dots(fractions, hashes))


def fade_derivative(t):
    """d/dt of 6t⁵ − 15t⁴ + 10t³ = 30 t² (t − 1)²."""
    s = t * (t - 1.0)
    return 30.0 * s * s


def noise3_gradient(p):
    """(N(p), ∇N(p)) at a Dr.Jit 3-vector ``p``; ∇N has the type of ``p``."""
    fractions, hashes = corner_hashes(p)
    x, y, z = fractions
    u, v, w = fade(x), fade(y), fade(z)
    d = corner_dots(fractions, hashes)
    one, zero = 1.0, 0.0
    gx = [grad(h, one, zero, zero) for h in hashes]
    gy = [grad(h, zero, one, zero) for h in hashes]
    gz = [grad(h, zero, zero, one) for h in hashes]

    d_du = lerp(w, lerp(v, d[1] - d[0], d[3] - d[2]), lerp(v, d[5] - d[4], d[7] - d[6]))
    d_dv = lerp(w, lerp(u, d[2] - d[0], d[3] - d[1]), lerp(u, d[6] - d[4], d[7] - d[5]))
    d_dw = (lerp(v, lerp(u, d[4], d[5]), lerp(u, d[6], d[7]))
            - lerp(v, lerp(u, d[0], d[1]), lerp(u, d[2], d[3])))
    gradient = type(p)(trilinear(u, v, w, gx) + fade_derivative(x) * d_du,
                       trilinear(u, v, w, gy) + fade_derivative(y) * d_dv,
                       trilinear(u, v, w, gz) + fade_derivative(z) * d_dw)
    return trilinear(u, v, w, d), gradient


def _wrap_large(x):
    """x mod 256 where |x| ≥ 2^24 (an even integer there, so the wrap is exact)."""
    return dr.select(dr.abs(x) >= _TWO_24, x - 256.0 * dr.floor(x * (1.0 / 256.0)), x)


def wrap_large_point(p):
    return type(p)(_wrap_large(p.x), _wrap_large(p.y), _wrap_large(p.z))

