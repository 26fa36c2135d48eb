"""The numbers both renderers and the checks must agree on, declared once.

The Mitsuba path (float32, Dr.Jit) and the float64 reference tracer are written
independently — the reference imports no Mitsuba or Dr.Jit — but they compute the same
image only if they trace with the same epsilons, bound the noise alike, stop a path at
the same depth and refuse the same numbers. Those shared constants live here, each with
its reason, and every former copy reads them.

Standard library only and nothing from the package, so that any module (the scene
language, which may not import NumPy; the CLI, which must start fast; both renderers)
can import it. Each value's expression is kept exactly as it was where it came from:
some reach kernels as literals and must round to the same float32.
"""

from __future__ import annotations

__all__ = ["T_MIN_REL", "EPS_REL", "FLT_MAX", "FLT_MIN_NORMAL", "FLOAT32_EPSILON", "FLOAT32_UNIT_ROUNDOFF",
           "FLOAT32_INTEGER_LIMIT",
           "NOISE_BOUND", "MAX_OCTAVES", "MAX_OCTAVES_EVALUATED", "SKIPPED_OCTAVES_BOUND",
           "PATH_MAX_DEPTH", "PREVIEW_MAX_DEPTH", "VOLPATH_MAX_DEPTH", "VOLPATH_RR_DEPTH", "ROULETTE_DEPTH", "ROULETTE_MAX",
           "SPHERICAL_ALBEDO_FIT_B", "SPHERICAL_ALBEDO_FIT_C", "DEFAULT_MAX_SPP", "RENDER_MODES",
           "MAX_GRID_NODES"]

# ---------------------------------------------------------------------------
# Tracing (docs/rendering-model.md)

#: Primary rays accept hits at t > T_MIN_REL·(1 + max_k |origin_k|): the reference's
#: nearest hit, which the translator keeps the Mitsuba camera's near clip below.
T_MIN_REL = 1e-6
#: Shadow rays start at p + ε·n with ε = EPS_REL·(1 + max_k |p_k|), in both renderers
#: (not Mitsuba's RayEpsilon: the 10 % difference moved shadow edges by a pixel).
EPS_REL = 1e-4

# ---------------------------------------------------------------------------
# float32, the Mitsuba path's precision

#: The largest float32: every number of a scene must be at most this in magnitude.
FLT_MAX = 3.4028234663852886e38
#: The smallest normal float32, 2⁻¹²⁶: a smaller nonzero number is 0 to the renderer (its
#: JIT flushes subnormals to zero), so a size or an angle that must not be zero must be
#: at least this.
FLT_MIN_NORMAL = 2.0 ** -126
#: The gap between 1 and the next float32 (2⁻²³): float32 rounding errors scale with it.
FLOAT32_EPSILON = 2.0 ** -23
#: float32's unit roundoff (round to nearest): |fl(x) − x| ≤ 2⁻²⁴·|x|.
FLOAT32_UNIT_ROUNDOFF = 2.0 ** -24
#: 2²⁴: from here on every float32 is an integer (no fraction left to a lattice or an angle).
FLOAT32_INTEGER_LIMIT = float(2 ** 24)

# ---------------------------------------------------------------------------
# Noise and its octave sum

#: sup |N| of Perlin's improved noise in 3D (about 1.0364, not 1; tests measure it).
NOISE_BOUND = 1.0364
#: The most octaves a marble may sum (the parameter table's bound, and the reference's).
MAX_OCTAVES = 64
#: At the paper's gain ½ octaves from here on change the sum by less than float32 resolves.
MAX_OCTAVES_EVALUATED = 25
#: What the octaves left out from MAX_OCTAVES_EVALUATED on can add: NOISE_BOUND·2^−24.
SKIPPED_OCTAVES_BOUND = NOISE_BOUND * 2.0 ** (1 - MAX_OCTAVES_EVALUATED)

# ---------------------------------------------------------------------------
# Path mode (translucent materials)

#: ``path``'s max_depth in path and preview mode (Mitsuba's count: light reaches the camera
#: over at most this many segments), and the reference preview's (reference/preview.py).
PATH_MAX_DEPTH = 4
#: ``path``'s max_depth in preview mode, and the reference preview's default: direct light
#: only (the camera's surface point lit by next-event estimation and by one BSDF sample that
#: meets the sky or a light), no interreflection. The preview's aim is speed (issue 40: at
#: least 10× the walk at equal spp): depth 2 is the lever that reaches it without touching
#: the walk or the marble, and its price, interreflection, is small beside the bias no depth
#: removes (the walk's glow through thin parts and its blur of the veins). Its cost and
#: bias at depths 4, 3 and 2: docs/benchmarks.md, "Fast preview at max_depth 2"; the bias in
#: words: docs/rendering-model.md, "The fast preview".
PREVIEW_MAX_DEPTH = 2

#: volpath's max_depth for a scene with a translucent material, and the reference random
#: walk's: the most scattering events of a path, each medium scattering and each non-null
#: surface interaction (a refraction through the boundary too) counting one (Mitsuba's
#: volpath.cpp). Light in a white marble scatters hundreds of times, so a low cap darkens it;
#: Russian roulette ends paths long before the cap wherever the albedo is lower. 256 (issue
#: 40 item 3) is Cycles' cap on a random walk (BSSRDF_MAX_STEPS in its
#: subsurface_random_walk.h): a stated bias that both renderers share — the light of walks
#: longer than 256 events is lost, a little at albedo 0.99, more in whiter marble of shorter
#: mean free path — taken for the time that longer caps spend on long (red) walks. The light
#: kept and the time taken at each cap: docs/benchmarks.md, "Walk length and sampler against
#: Cycles".
VOLPATH_MAX_DEPTH = 256
#: volpath's rr_depth where a translucent material's single-scattering albedo may pass
#: ROULETTE_MAX: max_depth, no Russian roulette (elsewhere ROULETTE_DEPTH;
#: mimarble/mitsuba/translate/modes.py, roulette_depth). volpath survives a path with
#: q = min(max β, 0.95), so in a medium of albedo α > 0.95 the weight grows as (α/0.95)ᵏ
#: while the path survives with 0.95ᵏ: white marble (α ≈ 0.9995) becomes a few huge
#: fireflies, and no roulette is the more efficient there, while at α ≤ 0.95 the roulette
#: is (the efficiencies: docs/benchmarks.md, "Russian roulette on white marble"). Where it
#: is off, the media end walks by their albedo instead (the ``roulette_isotropic`` phase
#: function).
VOLPATH_RR_DEPTH = VOLPATH_MAX_DEPTH
#: Russian roulette from this depth on (Mitsuba volpath's default ``rr_depth``; the
#: reference walk's default).
ROULETTE_DEPTH = 5
#: The largest survival probability of the roulette without a depth limit (Mitsuba's):
#: every path ends.
ROULETTE_MAX = 0.95

# ---------------------------------------------------------------------------
# The colour you see: a subsurface's reflectance (docs/rendering-model.md, "The colour
# you see: reflectance")

#: van de Hulst's fit (Multiple Light Scattering, 1980) of the spherical albedo of a
#: semi-infinite, isotropically scattering medium of single-scattering albedo α behind an
#: index-matched boundary: A ≈ (1 − s)(1 − B·s)/(1 + C·s), s = √(1 − α), with B and C
#: these two. Both renderers invert it (each in its own code) to turn a reflectance into
#: α; its largest error against Chandrasekhar's exact A is 0.0021 (at α ≈ 0.57), tested
#: in tests/test_subsurface_reflectance.py.
SPHERICAL_ALBEDO_FIT_B = 0.139
SPHERICAL_ALBEDO_FIT_C = 1.17

#: Adaptive sampling's most samples per pixel when ``max_spp`` is not given (at least the
#: first pass's spp): 1 spp taken to 9 twice (mimarble/mitsuba/rendering/adaptive.py's
#: ladder, 1, 9, 81, whose every level keeps the samples before it).
DEFAULT_MAX_SPP = 81

# ---------------------------------------------------------------------------
# Names

#: The render modes: ``whitted`` (the paper's direct lighting), ``path`` (volpath, for
#: translucent materials) and ``preview`` (path mode with each translucent material's
#: fast preview, ``subsurface_preview``, in place of its walk).
RENDER_MODES = ("whitted", "path", "preview")

#: The most nodes a translucent material's albedo grid may have (mimarble/scene/albedo_grid.py,
#: marble_medium's ``grid_counts``): 2²³ nodes of four half floats, 64 MiB — a cube of 203
#: nodes a side. Past it the walk evaluates the colour at each collision instead.
MAX_GRID_NODES = 2 ** 23
