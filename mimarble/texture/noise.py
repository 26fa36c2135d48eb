"""Ken Perlin's improved noise (SIGGRAPH 2002), its exact gradient and its fractal sum, in Dr.Jit.

The same functions run on every Dr.Jit array type: the scalar variant's Python
floats, LLVM and CUDA arrays (with or without AD), in float32 or float64 — the
type of the input point decides. Inside a Mitsuba kernel they are traced once.

    noise3(p)            N(p), improved noise, |N| ≤ 1.0364 (not 1)
    noise3_gradient(p)   (N(p), ∇N(p)) in one pass, N bit for bit noise3's
    fractal3(p, K)       F = Σ_{i<K} N(2^i p) / 2^i     the paper's Fractal3 (Fig. 6)
    fractal3(p, K, True)     Σ_{i<K} |N(2^i p)| / 2^i   Perlin's turbulence
    fractal_sum(p, K, …)     the one octave sum behind fractal3: band-limited to a
                             pixel's footprint, with ∇F, with |N| folded in the pixel
    Spectrum(ω, λ)       another gain ω and lacunarity λ (POV-Ray's omega and lambda):
                         F = Σ_{i<K} ω^i N(λ^i p); the paper's are ω = ½, λ = 2

The gradient: N is a trilinear interpolation, with weights u = fade(x), v = fade(y),
w = fade(z), of the eight corner values d_c = G_c · (p − corner_c), G_c the corner's
gradient vector. So, with L(u, v, w; values) the nested lerps of :func:`trilinear`::

    ∂N/∂x = L(u, v, w; G_x) + fade′(x) · ∂L/∂u,    fade′(t) = 30 t² (t − 1)²
    ∂L/∂u = lerp(w, lerp(v, d₁ − d₀, d₃ − d₂), lerp(v, d₅ − d₄, d₇ − d₆))

and likewise for y and z (each corner value is linear in p, so its own gradient is
G_c, read off :func:`grad` by its linearity: G = (grad(h, 1, 0, 0), grad(h, 0, 1, 0),
grad(h, 0, 0, 1)), exactly). The float64 twin, written from the sum-of-ω form, is
:mod:`mimarble.reference.noise_gradient`.

``perlin(points)`` and ``fractal(points, K)`` are the NumPy entry points: (N, 3)
in, (N,) out, through the very same Dr.Jit code.

Numerical safety, for every finite input:

* The lattice cell is wrapped modulo 256 *in floating point* before any
  float→int conversion: ``c − 256·⌊c/256⌋`` is exact for every float (each step
  is exact scaling or an exactly representable difference), so even 1e20 gives
  an index in [0, 256) and never an out-of-range conversion (LLVM poison).
* Octave frequencies cannot overflow: a coordinate with |x| ≥ 2^24 is an even
  integer, so ``2^i·x`` and ``2^i·(x mod 256)`` fall on the same lattice cell
  with zero fraction; such coordinates are wrapped once before the octave loop,
  after which 2^i·x < 2^88 for every i < 64.
* Octaves that float32 cannot add are not evaluated: the tail Σ_{i≥K} holds at
  most 1.0364·2^(1−K), so octaves from ``MAX_OCTAVES_EVALUATED`` = 25 on change
  F by at most ``SKIPPED_OCTAVES_BOUND`` = 1.0364·2^−24 ≈ 6.2e-8, below the float32
  rounding error of the octaves that are summed. 32 or 64 octaves cost what 25 do.
  At gain ω the tail is 1.0364·ω^K/(1−ω): octaves from the first K where it is at most
  the same 1.0364·2^−24 are left out (:func:`max_octaves_evaluated`; 25 at ½, all 64
  from ω ≈ 0.755 on).
* At lacunarity λ ≤ 3 (the parameter's range) the finest octave's point λ^63·|q| stays
  below 2^124 for |q| < 2^24: no overflow. A coordinate of 2^24 or more is wrapped
  mod 256 once as at λ = 2 (where that is exact); at another λ the point is beyond
  float32's resolution there anyway, and the result finite and deterministic.

Non-finite input (NaN, ±Inf) gives NaN out, never an error or an abort: the
lattice index of such lanes is replaced by 0 before the integer conversion and
the NaN then propagates through the arithmetic.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from mimarble.contract import FLOAT32_INTEGER_LIMIT, MAX_OCTAVES_EVALUATED, NOISE_BOUND, SKIPPED_OCTAVES_BOUND
from mimarble.runtime import environment
from mimarble.parameters import BY_NAME, MAX_OCTAVES

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


def max_octaves_evaluated(gain: float = 0.5) -> int:
    """The octaves float32 can add at gain ω: the first k whose tail, at most
    NOISE_BOUND·ω^k/(1−ω), is at most SKIPPED_OCTAVES_BOUND = NOISE_BOUND·2^−24 (25 at
    the paper's ½, where the tail is 2^(1−k)), and at most MAX_OCTAVES."""
    gain = float(gain)
    for k in range(MAX_OCTAVES + 1):
        if gain ** k / (1.0 - gain) <= 2.0 ** -24:
            return k
    return MAX_OCTAVES


def octaves_evaluated(octaves: int, gain: float = 0.5) -> int:
    """How many octaves a K-octave sum actually evaluates (see SKIPPED_OCTAVES_BOUND)."""
    if not 0 <= octaves <= MAX_OCTAVES:
        raise ValueError(f"octaves must be an integer in 0..{MAX_OCTAVES}, got {octaves}")
    return min(octaves, MAX_OCTAVES_EVALUATED if gain == 0.5 else max_octaves_evaluated(gain))


class Spectrum:
    """The octaves' gain ω and lacunarity λ: octave i has amplitude ω^i and frequency λ^i.

    ``gain`` and ``lacunarity`` are what the kernel reads: Python floats (literals, as the
    paper's ½ and 2 by default) or opaque Dr.Jit values (the texture's, so that a new
    value reuses the compiled kernel and carries derivatives). ``gain_value`` is the
    number that decides how many octaves float32 can add (structural). The constants the
    filters derive from them (1/log₂λ, log₂ω, ω², 1/(1−ω), 1/(1−ω²), and ω^K', ω^2K' for
    the ``octaves`` K' a texture evaluates) are computed here in double precision and held
    like the two (``opaque``: as opaque Dr.Jit values); the filters' cut-offs and estimates
    carry no derivative to ω or λ, the sum does. ``DRJIT_STRUCT``: Dr.Jit's traversal
    (``dr.freeze``) sees them through the texture."""

    DRJIT_STRUCT = {"gain": object, "lacunarity": object, "inverse_log_lacunarity": object,
                    "log_gain": object, "gain_squared": object, "inverse_tail": object,
                    "inverse_tail_squared": object, "gain_power": object,
                    "gain_power_squared": object}

    def __init__(self, gain_value: float = 0.5, lacunarity_value: float = 2.0, gain=None,
                 lacunarity=None, opaque: bool = False, octaves: int | None = None):
        # The table's ranges (a ParameterError, a ValueError, outside them). A value None:
        # held on the device only (an edit the host never read, mimarble/mitsuba/plugins/marble.py); its
        # constants are then derived there, in single precision, from ``gain`` or
        # ``lacunarity`` (no read back), and every octave is evaluated.
        self.gain_value = None if gain_value is None else BY_NAME["gain"].check(float(gain_value))
        self.lacunarity_value = None if lacunarity_value is None else \
            BY_NAME["lacunarity"].check(float(lacunarity_value))
        self.gain = self.gain_value if gain is None else gain
        self.lacunarity = self.lacunarity_value if lacunarity is None else lacunarity
        self.octaves = octaves
        g = self.gain_value if self.gain_value is not None else dr.detach(self.gain)
        lacunarity_held = self.lacunarity_value if self.lacunarity_value is not None \
            else dr.detach(self.lacunarity)

        def log2(x):
            return math.log2(x) if isinstance(x, float) else dr.log2(x)
        derived = {"inverse_log_lacunarity": 1.0 / log2(lacunarity_held),
                   "log_gain": log2(g),
                   "gain_squared": g * g,
                   "inverse_tail": 1.0 / (1.0 - g),
                   "inverse_tail_squared": 1.0 / (1.0 - g * g),
                   "gain_power": g ** (octaves or 0),
                   "gain_power_squared": g ** (2 * (octaves or 0))}
        for name, value in derived.items():
            if opaque:
                value = mi.Float(value)
                dr.make_opaque(value)
            setattr(self, name, value)

    @property
    def paper(self) -> bool:
        """The paper's ω = ½ and λ = 2."""
        return self.gain_value == 0.5 and self.lacunarity_value == 2.0   # (None: not known)

    def differentiated(self) -> bool:
        return dr.grad_enabled(self.gain) or dr.grad_enabled(self.lacunarity)

    def most(self, octaves: int) -> int:
        """The octaves of a K-octave sum evaluated at this gain (a gain on the device:
        every one)."""
        if self.gain_value is None:
            return octaves
        return octaves_evaluated(octaves, self.gain_value)

    def power(self, k: int, squared: bool = False):
        """ω^k (ω^2k): the held value for the spectrum's own ``octaves``, else a literal."""
        if k == self.octaves:
            return self.gain_power_squared if squared else self.gain_power
        held = self.gain_value if self.gain_value is not None else dr.detach(self.gain)
        return held ** (2 * k if squared else k)


#: The paper's octaves: ω = ½, λ = 2, as literals.
PAPER_SPECTRUM = Spectrum()


def fractal3(p, octaves: int, turbulence: bool = False, spectrum: Spectrum = PAPER_SPECTRUM):
    """F(p) = Σ_{i<K} N(2^i p)/2^i (paper Fig. 6); with ``turbulence``, |N| in the sum;
    with a ``spectrum``, Σ ω^i N(λ^i p)."""
    return fractal_sum(p, octaves, turbulence, spectrum=spectrum).value


class FractalSum(NamedTuple):
    """What :func:`fractal_sum` returns: F, ∇F (None unless asked for), the
    variance σ² of F across the pixel that ∇F does not describe (0 unless folding), and
    with ``point``, F at the point with every octave (None unless asked for)."""

    value: object
    gradient: object
    spread: object
    point: object = None


def fractal_sum(p, octaves: int, turbulence: bool = False, *, band=None, gradient: bool = False,
                differentials=None, spectrum: Spectrum = PAPER_SPECTRUM,
                point: bool = False) -> FractalSum:
    """The one octave sum: F(p) = Σ_{i<K'} w_i · ω^i N(λ^i p), K' = min(K, 25) at the
    paper's ω = ½, λ = 2 (``spectrum``: another ω and λ; K' from ω, :func:`octaves_evaluated`).

    ``octaves`` is structural (a Python int). Options:

    * ``turbulence``: |N| in place of N (Perlin's turbulence).
    * ``band``: (whole, last) from :func:`band_limit`: octaves i < whole have weight 1,
      octave ``whole`` weight ``last``, the rest are left out; each lane stops after its
      own last octave (fewer noise evaluations where the footprint is large).
    * ``gradient``: also ∇F = Σ w_i (ωλ)^i ∇N(λ^i p) (at the paper's ω, λ the 2^i of the
      chain rule cancels the amplitude: (ωλ)^i = 1 exactly); turbulence's |N|
      contributes sign(N)·∇N (0 where N = 0).
    * ``differentials`` (∂p/∂x, ∂p/∂y), with ``turbulence``: |N| folds where N crosses 0
      inside the pixel. Where N runs linearly over [n − W/2, n + W/2] across it (W from
      ∇N and the differentials, |n| < W/2), the mean of |N| is n²/W + W/4, not |n|, and
      it spreads with variance n² + W²/12 − mean² about that mean, with no slope: such an
      octave adds its mean to F and its spread to σ², not its gradient.
    * ``point``, with ``band``: also F with every octave, unweighted and unfolded, bit
      for bit :func:`fractal3`'s (the same terms in the same order): the band's octaves
      share their noise with it, the rest are plain N (a second loop from each lane's
      last octave), so the point sample costs only the octaves past the band.

    In JIT variants the octaves are a symbolic loop (``dr.while_loop``): one noise
    evaluation's code, however many octaves. Unrolled, a kernel holds every octave's
    code, and LLVM compiles a long straight-line kernel in more than linear time (a
    product of many marbles; docs/benchmarks.md, "Compile time"), while the loop
    renders as fast. The loop is unrolled where it must be: in the scalar variant, and when ``p``,
    ω or λ carries derivatives (reverse mode cannot go through a symbolic loop). The
    frequencies and amplitudes λ^i and ω^i are products of i factors either way (2^i and
    2^−i: exact), so both forms give the same bits.
    """
    most = spectrum.most(octaves)
    float_type = type(p.x)
    jit = dr.is_jit_v(float_type)
    width = dr.width(p)
    with_gradient = gradient or differentials is not None
    folds = turbulence and differentials is not None
    state = {"total": dr.zeros(float_type, width) if jit else 0.0}
    if with_gradient:
        state["gradient"] = dr.zeros(type(p), width) if jit else type(p)(0.0)
    if folds:
        state["spread"] = dr.zeros(float_type, width)
    if point:
        state["point"] = dr.zeros(float_type, width) if jit else 0.0
    if most == 0:
        return _result(state)
    q = wrap_large_point(p)

    def octave(i, frequency, amplitude, state):
        """One octave's terms; its frequency λ^i and amplitude ω^i as the loop made them."""
        if with_gradient:
            n, g = noise3_gradient(q * frequency)
        else:
            n, g = noise3(q * frequency), None
        if turbulence:
            if g is not None:
                g = g * dr.sign(n) * dr.select(n == 0.0, 0.0, 1.0)
            n = dr.abs(n)
        state = dict(state)
        if point:
            state["point"] = state["point"] + n * amplitude
        weight = None
        if band is not None:
            whole, last = band
            i_float = float_type(i)
            weight = dr.select(i_float < whole, 1.0, dr.select(i_float == whole, last, 0.0))
        weighted = amplitude if weight is None else amplitude * weight
        if folds:
            # N across the pixel, in N's units: ∇N(2^i p)·2^i·(∂p/∂x, ∂p/∂y).
            across = frequency * dr.sqrt(dr.square(dr.dot(g, differentials[0]))
                                         + dr.square(dr.dot(g, differentials[1])))
            folded = n < 0.5 * across
            mean = dr.select(folded, dr.square(n) / across + 0.25 * across, n)
            variance = dr.select(folded, dr.square(n) + dr.square(across) / 12.0
                                 - dr.square(mean), 0.0)
            n, g = mean, dr.select(folded, 0.0, g)
            state["spread"] = state["spread"] + dr.maximum(variance, 0.0) * dr.square(weighted)
        state["total"] = state["total"] + n * weighted
        if g is not None:
            chain = amplitude * frequency     # (ωλ)^i: 1, exactly, at the paper's ω and λ
            state["gradient"] = state["gradient"] + (g * chain if weight is None
                                                     else g * (chain * weight))
        return state

    gain, lacunarity = spectrum.gain, spectrum.lacunarity
    if not jit or dr.grad_enabled(p) or spectrum.differentiated():
        frequency, amplitude = 1.0, 1.0
        for i in range(most):
            state = octave(i, frequency, amplitude, state)
            frequency, amplitude = frequency * lacunarity, amplitude * gain
        return _result(state)

    uint_type = dr.uint32_array_t(float_type)
    if band is None:
        count = dr.full(uint_type, most, width)
    else:
        whole, last = band
        count = uint_type(whole) + dr.select(last > 0.0, 1, 0)

    def body(i, frequency, amplitude, state):
        return (i + 1, frequency * lacunarity, amplitude * gain,
                octave(i, frequency, amplitude, state))

    loop = (dr.zeros(uint_type, width), dr.full(float_type, 1.0, width),
            dr.full(float_type, 1.0, width), state)
    # Nested in another symbolic operation (an integrator's symbolic `if`, loop or call)
    # the loop can only be symbolic, and is said to be so: left to choose by
    # JitFlag.SymbolicLoops, which Mitsuba turns off to differentiate a render
    # (Integrator::render_backward), Dr.Jit makes it symbolic anyway with a warning per
    # trace (`ad_loop("unnamed"): forcing conditional statement to symbolic mode`).
    # Nothing differentiable enters it (a differentiated p is unrolled above). Outside
    # one, the flag decides, as before.
    mode = "symbolic" if dr.flag(dr.JitFlag.SymbolicScope) else None
    i, frequency, amplitude, state = dr.while_loop(loop, lambda i, *rest: i < count, body,
                                                   mode=mode)
    if point:
        def rest(i, frequency, amplitude, total):
            n = noise3(q * frequency)
            if turbulence:
                n = dr.abs(n)
            return i + 1, frequency * lacunarity, amplitude * gain, total + n * amplitude

        state = dict(state)
        state["point"] = dr.while_loop((i, frequency, amplitude, state["point"]),
                                       lambda i, *rest: i < most, rest, mode=mode)[3]
    return _result(state)


def _result(state) -> FractalSum:
    return FractalSum(state["total"], state.get("gradient"), state.get("spread", 0.0),
                      state.get("point"))


def _smoothstep(a, b, x):
    t = dr.clip((x - a) / (b - a), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


# Octaves kept past pbrt's Nyquist cut. Measured on fig11a (250², against a 64-spp
# float64 reference): RMSE at 1 spp 0.030 with pbrt's cut, 0.020 with 1 more octave,
# 0.0175 with 2 (plain supersampling: 0.018), 0.018 with 3; the cost of 32 octaves
# stays that of 8 (docs/benchmarks.md). The marble's colour is a nonlinear function
# of the phase, so octaves near the pixel size still shift the pixel's mean.
# (Measured while footprints came out half their size, docs/design-decisions.md; with
# true footprints margin 2 gives fig11a 256² 1-spp RMSE 0.0178, plain sampling 0.0184.)
BAND_LIMIT_MARGIN = 2


def band_limit(footprint, octaves: int, margin: float = BAND_LIMIT_MARGIN,
               spectrum: Spectrum = PAPER_SPECTRUM):
    """(whole octaves, weight of the next one) for a footprint in noise-space units.

    pbrt-v4's FBm clamp, n = clamp(−1 − log2(footprint), 0, K), moved up by
    ``margin`` octaves (:data:`BAND_LIMIT_MARGIN` unless given); the octave ⌊n⌋ fades
    in with smoothstep(0.3, 0.7) of the fraction, so the count changes without seams.
    At lacunarity λ octave i's frequency is λ^i, below the footprint's Nyquist rate while
    λ^i·footprint < ½: n = margin + (−1 − log2 footprint)/log2 λ, written
    (margin − 1/log2 λ) − log2(footprint)/log2 λ so that λ = 2 gives the bits it did.
    A zero footprint (no ray differentials) keeps every octave, and so does a NaN one.
    """
    most = float(spectrum.most(octaves))
    if spectrum.paper and isinstance(spectrum.lacunarity, float):
        n = margin - 1.0 - dr.log2(footprint)
    else:
        scale = spectrum.inverse_log_lacunarity
        n = (margin - scale) - dr.log2(footprint) * scale
    # NaN (a lane without a valid footprint) and +inf both fail `n < most`: all octaves.
    # The loop count must never come from a NaN: its integer conversion is unbounded.
    n = dr.maximum(dr.select(n < most, n, most), 0.0)
    whole = dr.floor(n)
    return whole, _smoothstep(0.3, 0.7, n - whole)


#: Var N(p) of the improved noise over uniformly spread points, and Var |N(p)|
#: (turbulence): measured in float64 on the reference noise over 2·10⁶ points uniform in
#: [−100, 100]³ (N: 0.0731, mean 1e-4; |N|: 0.0245, mean 0.220); tests/test_prefilter.py
#: measures them again. Octaves are near independent, so leaving out octaves i ≥ n of
#: F moves it by a spread of variance V·Σ_{i≥n} 4^−i.
NOISE_VARIANCE = 0.0731
ABS_NOISE_VARIANCE = 0.0245
#: E|N(p)| (the mean of a turbulence octave; E N = 0), measured with the variances.
ABS_NOISE_MEAN = 0.2204


def left_out(band, octaves: int, turbulence: bool = False,
             spectrum: Spectrum = PAPER_SPECTRUM):
    """(mean, variance) that the octaves a ``band`` leaves out would add to F: (1 − last)
    of octave ``whole`` and all of whole+1 … K'−1. Their variance is V·Σ w²ω^2i; their
    mean is 0, or E|N|·Σ w ω^i for turbulence (|N| averages E|N| over a pixel). At the
    paper's ω = ½: V·Σ w²4^−i and E|N|·Σ w 2^−i, written as before (the same bits)."""
    whole, last = band
    most = spectrum.most(octaves)
    outside = whole < float(most)
    variance = ABS_NOISE_VARIANCE if turbulence else NOISE_VARIANCE
    if spectrum.paper and isinstance(spectrum.gain, float):
        power = dr.exp2(-2.0 * whole)                      # 4^−whole
        dropped = dr.square(1.0 - last) * power + (power * 0.25 - 4.0 ** -most) * (4.0 / 3.0)
    else:                                                  # ω^2·whole, Σ_{whole<i<K'} ω^2i
        g = spectrum
        power = dr.exp2((2.0 * g.log_gain) * whole)
        dropped = dr.square(1.0 - last) * power + (power * g.gain_squared - g.power(
            most, squared=True)) * g.inverse_tail_squared
    dropped = dr.select(outside, variance * dr.maximum(dropped, 0.0), 0.0)
    mean = 0.0
    if turbulence:
        if spectrum.paper and isinstance(spectrum.gain, float):
            half = dr.exp2(-whole)                         # 2^−whole
            weights = (1.0 - last) * half + dr.maximum(half - 2.0 ** (1 - most), 0.0)
        else:                                              # ω^whole, Σ_{whole<i<K'} ω^i
            g = spectrum
            half = dr.exp2(g.log_gain * whole)
            weights = (1.0 - last) * half + dr.maximum(
                half * g.gain - g.power(most), 0.0) * g.inverse_tail
        mean = dr.select(outside, ABS_NOISE_MEAN * weights, 0.0)
    return mean, dropped


# ---------------------------------------------------------------------------
# NumPy entry points, through the very same Dr.Jit code

def _array_types():
    """(Array3f, Float) of the backend the NumPy entry points run on.

    The current variant's JIT backend; for the scalar variant, Dr.Jit's LLVM
    backend when usable, else None (then the points go one by one).
    """
    variant = mi.variant() or ""
    if variant.startswith("cuda_"):
        return dr.cuda.Array3f, dr.cuda.Float
    if variant.startswith("llvm_") or environment.variant_problem("llvm_ad_rgb") is None:
        return dr.llvm.Array3f, dr.llvm.Float
    return None, None


def _evaluate(points, fn) -> np.ndarray:
    pts = np.ascontiguousarray(np.asarray(points, dtype=np.float32))
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {pts.shape}")
    array3f, float_type = _array_types()
    if array3f is None:
        return np.array([fn(dr.scalar.Array3f(*map(float, row))) for row in pts], np.float32)
    p = array3f(float_type(pts[:, 0]), float_type(pts[:, 1]), float_type(pts[:, 2]))
    return np.asarray(fn(p), dtype=np.float32).reshape(len(pts))


def perlin(points) -> np.ndarray:
    """Improved noise at NumPy points (N, 3) → float32 (N,)."""
    return _evaluate(points, noise3)


def fractal(points, octaves: int, turbulence: bool = False, gain: float = 0.5,
            lacunarity: float = 2.0) -> np.ndarray:
    """F at NumPy points (N, 3) → float32 (N,); ``turbulence`` sums |N| instead; ``gain``
    ω and ``lacunarity`` λ: Σ ω^i N(λ^i p)."""
    octaves_evaluated(octaves)   # validate before any work
    spectrum = Spectrum(gain, lacunarity)
    return _evaluate(points, lambda p: fractal3(p, octaves, turbulence, spectrum))
