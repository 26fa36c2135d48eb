"""Numerical stability: float32 error of the fractal and the marble colour, measured and bounded.

``run_stress()`` measures, for rows of magnitudes R (points p uniform in [−R, R]³,
drawn in float64) and columns of octave counts K, the largest difference between
the float32 Dr.Jit evaluation (the point rounded to float32, as Mitsuba hands it
to a texture) and the float64 reference noise (:mod:`mimarble.reference.noise`,
at the exact float64 point), next to the a-priori bound
:func:`fractal_error_bound`. It does the same for the marble colour of a paper
marble (:func:`colour_error_bound`), measures what evaluating in float64 would
gain, and times float64 against float32. ``format_report(data)`` renders the
result as text; ``data`` is JSON-serialisable (``mimarble stress --json``).

The derivation is in ``docs/numerical-stability.md``. In short, with u = 2⁻²⁴,
v = scale·R, Δv = c·u·v (c = 1 for the rounding of p, +1 when scale·p is
rounded, +1 when scale itself is not a float32), L = sup‖∇N‖₁ and K' = min(K, 25)::

    ΔF(R, K) ≤ Σ_{i<K'} [min(L·Δv, 2B·2⁻ⁱ) + E·2⁻ⁱ] + (K'−1)·u·2B + [K > 25]·B·u

with B = 1.0364 (sup |N|) and E = 4e-6 the float32 arithmetic error of one noise
evaluation at a given float32 point.
"""

from __future__ import annotations

import contextlib
import math
import statistics
import time

import numpy as np

from mimarble.contract import FLOAT32_INTEGER_LIMIT, FLOAT32_UNIT_ROUNDOFF
from mimarble.runtime import environment
from mimarble.texture import error_budget
from mimarble.texture.finite_arithmetic import finite_product
from mimarble.texture.noise import (MAX_OCTAVES_EVALUATED, NOISE_BOUND, SKIPPED_OCTAVES_BOUND,
                                    fractal3, octaves_evaluated)
from mimarble.reference import marble as reference_marble
from mimarble.reference import noise as reference_noise
from mimarble.scene.model import FIG5_RAMP, MarbleChannel
from mimarble.texture.stripes import STRIPES

dr, mi = environment.import_drjit_and_mitsuba()

__all__ = ["U", "LIPSCHITZ_L1", "NOISE_ARITHMETIC_ERROR", "DEFAULT_MAGNITUDES", "DEFAULT_OCTAVES",
           "PAPER_MARBLE", "input_error_factor", "fractal_error_bound", "colour_error_bound",
           "meaningful_limit", "run_stress", "format_report"]

#: Unit roundoff of float32 (round to nearest): |fl(x) − x| ≤ U·|x|.
U = FLOAT32_UNIT_ROUNDOFF
#: sup over R³ of ‖∇N‖₁ (the Lipschitz constant of N for the max-norm of the step).
#: Measured: 5.24 by hill-climbing from the 2000 steepest of 2·10⁶ random points
#: (float64 central differences); the largest single partial derivative is 3.12.
LIPSCHITZ_L1 = 5.3
#: Float32 arithmetic error of one noise evaluation at a given float32 point
#: (tests/test_noise.py's tolerance; the worst seen over 10⁶ points is 1.9e-6).
NOISE_ARITHMETIC_ERROR = 4e-6
#: Error of Dr.Jit's float32 sin/cos: ≤ 9e-8 measured for |x| ≤ 10⁴; beyond 2¹³ its
#: range reduction loses about |x|·2⁻²⁴ (measured 9.6e-7 at 10⁵, 0.031 at 10⁶).
SIN_ERROR = 1.5e-7
_SIN_EXACT_RANGE = 2.0 ** 13

DEFAULT_MAGNITUDES = (1e-30, 1e-3, 1.0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 2.0 ** 23, 1e8, 1e20)
DEFAULT_OCTAVES = (1, 4, 8, 12, 25, 64)
#: The marble of the colour table: Fig. 11(a) (scale 1, period 1.3, distortion 3, 12 octaves).
PAPER_MARBLE = MarbleChannel(scale=1.0, period=1.3, distortion=3.0, octaves=12,
                             function="abs_sine", axis="x", ramp=FIG5_RAMP)


# ---------------------------------------------------------------------------
# The bounds

def _is_float32(x: float) -> bool:
    return float(np.float32(x)) == float(x)


def _is_power_of_two(x: float) -> bool:
    m, _ = math.frexp(abs(x))
    return x != 0 and m == 0.5


def input_error_factor(scale: float) -> int:
    """c in |v₃₂ − scale·p| ≤ c·U·|scale·p|: roundings of p, of scale, of the product."""
    return 1 + (not _is_float32(scale)) + (not _is_power_of_two(float(np.float32(scale))))


def fractal_error_bound(magnitude: float, octaves: int, scale: float = 1.0) -> float:
    """Bound on |F₃₂(fl(scale)·fl(p)) − F₆₄(scale·p)| for ‖p‖∞ ≤ ``magnitude``; the same
    for turbulence (| |a| − |b| | ≤ |a − b|).
    """
    k_eval = octaves_evaluated(int(octaves))
    if k_eval == 0:
        return 0.0
    v = abs(scale) * magnitude
    dv = input_error_factor(scale) * U * v * (1 + 1e-6) + 2.0 ** -149   # + subnormal spacing
    total = 0.0
    for i in range(k_eval):
        weight = 2.0 ** -i
        total += min(LIPSCHITZ_L1 * dv, 2 * NOISE_BOUND * weight) + NOISE_ARITHMETIC_ERROR * weight
    total += (k_eval - 1) * U * 2 * NOISE_BOUND                      # the float32 running sum
    if octaves > MAX_OCTAVES_EVALUATED:
        total += SKIPPED_OCTAVES_BOUND                                # the skipped tail
    return total


def _sin_error(x_max: float) -> float:
    return SIN_ERROR + (x_max * U if x_max > _SIN_EXACT_RANGE else 0.0)


def colour_error_bound(magnitude: float, channel: MarbleChannel = PAPER_MARBLE) -> float:
    """Bound on the largest colour-component error of the float32 ``marble`` texture.

    For world points with ‖p‖∞ ≤ ``magnitude`` (no ``to_world``), against the
    float64 formula at the exact point (:func:`mimarble.reference.marble.marble_color`).
    """
    ramp = np.asarray(channel.ramp, dtype=np.float64).reshape(-1, 3)
    c_max = float(np.abs(ramp).max())
    storage = U * c_max                      # the ramp is stored in float32
    if len(ramp) == 1:
        return storage
    scale, period, distortion = float(channel.scale), float(channel.period), float(channel.distortion)
    v = abs(scale) * magnitude
    dv = input_error_factor(scale) * U * v * (1 + 1e-6) + 2.0 ** -149
    uses_noise = distortion != 0.0 and channel.octaves > 0
    dF = fractal_error_bound(magnitude, channel.octaves, scale) if uses_noise else 0.0
    f_max = 2 * NOISE_BOUND if uses_noise else 0.0
    stripe = STRIPES[channel.function]
    p_eff = abs(period) if stripe.uses_period else 1.0
    a = p_eff * v                             # |period·v_a|
    b = abs(distortion) * f_max               # |distortion·F|
    c_p = 1 + (not _is_float32(period)) if stripe.uses_period else 0
    c_d = 1 + (not _is_float32(distortion))
    d_phi = p_eff * dv + abs(distortion) * dF + U * (c_p * a + c_d * b + (a + b))
    # t = A·f(ω·φ) (mimarble/texture/stripes.py). ω = π is not a float32: its rounding (0.47 U)
    # and the product ω·φ (U) add 2U·x; A = ½ adds the rounding of ½(f + 1) (U).
    x_max = stripe.angular_frequency * (a + b)
    dx = stripe.angular_frequency * d_phi + (2 * U * x_max if stripe.angular_frequency != 1.0
                                             else 0.0)
    dt = stripe.amplitude * (dx + _sin_error(x_max)) + (U if stripe.amplitude != 1.0 else 0.0)
    dt = min(dt, 1.0)
    lipschitz = error_budget.ramp_lipschitz(ramp)
    spread = float((ramp.max(axis=0) - ramp.min(axis=0)).max())
    return min(lipschitz * (dt + U), spread) + 4 * U * c_max + storage


def meaningful_limit(scale: float = 1.0) -> dict:
    """Where float32 stops resolving the noise, in |p| (texture/world units)."""
    s = abs(scale)
    return {
        "no_fraction": 2.0 ** 23 / s,          # v has no fractional bits: the lattice itself
        "all_even_integers": FLOAT32_INTEGER_LIMIT / s,    # every octave sits on lattice points: N = 0
        "steps_per_cell_16": 2.0 ** 19 / s,    # a lattice cell is resolved in only 16 steps
    }


# ---------------------------------------------------------------------------
# Measurement

@contextlib.contextmanager
def _jit_variant():
    """The current variant if it is a JIT one, else llvm_ad_rgb for the duration."""
    previous = mi.variant()
    if previous and not previous.startswith("scalar"):
        yield previous
        return
    problem = environment.variant_problem("llvm_ad_rgb")
    if problem:
        raise environment.EnvironmentProblem(f"mimarble stress needs a JIT variant: {problem}")
    mi.set_variant("llvm_ad_rgb")
    try:
        yield "llvm_ad_rgb"
    finally:
        if previous:
            mi.set_variant(previous)


def _types():
    backend = dr.cuda.ad if mi.variant().startswith("cuda") else dr.llvm.ad
    return backend.Float, backend.Array3f, backend.Float64, backend.Array3f64


def _array3(array_type, float_type, pts):
    return array_type(*(float_type(np.ascontiguousarray(pts[:, a])) for a in range(3)))


def _sample(rng, magnitude, n):
    return rng.uniform(-magnitude, magnitude, (n, 3))


def _fractal_f32(pts64, octaves, scale):
    Float, Array3f, _, _ = _types()
    p = _array3(Array3f, Float, pts64.astype(np.float32))
    return np.array(fractal3(p * Float(np.float32(scale)), octaves), dtype=np.float64)


def _fractal_f64(pts64, octaves, scale):
    _, _, Float64, Array3f64 = _types()
    p = _array3(Array3f64, Float64, pts64)
    return np.array(fractal3(p * Float64(scale), octaves), dtype=np.float64)


def _texture(channel, tolerance: float = 0.0):
    """The ``marble`` texture of ``channel``; tolerance 0: every octave, float32's error alone."""
    from mimarble.mitsuba.translate.scene_dict import texture_dict
    return mi.load_dict(texture_dict(channel, tolerance))


def tolerance_error(channel: MarbleChannel, tolerance: float, points: int = 1 << 16,
                    magnitude: float = 2.0, seed: int = 7) -> dict:
    """The texture's colour with an error budget against the float64 reference's full sum.

    At ``points`` random world points with ‖p‖∞ ≤ ``magnitude``: the largest
    component error, and what it may be — the tolerance, plus float32's own
    error there (:func:`colour_error_bound`), plus what the octaves past
    ``MAX_OCTAVES_EVALUATED`` (never evaluated in float32) can add.
    """
    with _jit_variant():
        tex = _texture(channel, tolerance)
        pts = _sample(np.random.default_rng(seed), magnitude, points)
        ours = _colour_f32(tex, pts)
        full = reference_marble.marble_color(pts.astype(np.float32).astype(np.float64), channel)
        skipped = error_budget.colour_change_bound(MAX_OCTAVES_EVALUATED, channel.octaves,
                                                   channel.distortion, channel.ramp,
                                                   channel.function)
        return {"max_error": float(np.abs(ours - full).max()), "tolerance": tolerance,
                "float32_bound": colour_error_bound(magnitude, channel),
                "skipped_bound": skipped,
                "octaves": channel.octaves, "octaves_evaluated": tex.octaves_evaluated}


def _colour_f32(tex, pts64):
    si = dr.zeros(mi.SurfaceInteraction3f, len(pts64))
    si.p = _array3(mi.Point3f, mi.Float, pts64.astype(np.float32))
    return np.array(tex.eval(si), dtype=np.float64).T


def _colour_f64(tex, pts64, channel):
    """What a ``precision="double"`` texture would give: its formula on Float64.

    scale, period and distortion as Float64 (as such an option would store them); the
    ramp colours stay float32. The point is the float32 one Mitsuba provides, so its
    rounding is still there.
    """
    _, _, Float64, Array3f64 = _types()
    p = _array3(Array3f64, Float64, pts64.astype(np.float32).astype(np.float64))
    v = p * Float64(channel.scale)
    F = fractal3(v, tex.octaves_evaluated, tex.turbulence) if tex.needs_noise else None
    noise = 0.0 if F is None else finite_product(Float64(channel.distortion), F)
    phase = tex.stripe.phase(v, tex.axis_index, Float64(channel.period), noise)
    return np.array(tex.ramp(tex.stripe.t(phase)), dtype=np.float64).T


def _reference_terms(v64, k_max):
    """Per-octave float64 reference terms N(2^i v)/2^i, i < k_max, as (k_max, n)."""
    terms = np.empty((k_max, len(v64)))
    for i in range(k_max):
        o = float(2 ** i)
        terms[i] = reference_noise.noise(v64[:, 0] * o, v64[:, 1] * o, v64[:, 2] * o) / o
    return terms


def _timed(fn, repeats):
    fn()                          # warm-up: trace and compile (or load the kernel cache)
    times = []
    for _ in range(repeats):
        dr.sync_thread()
        start = time.perf_counter()
        fn()
        dr.sync_thread()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _timing(points, octaves, repeats, seed):
    Float, Array3f, Float64, Array3f64 = _types()
    pts = np.random.default_rng(seed).uniform(-100, 100, (points, 3))
    p32 = _array3(Array3f, Float, pts.astype(np.float32))
    p64 = _array3(Array3f64, Float64, pts)
    dr.eval(p32, p64)
    t32 = _timed(lambda: dr.eval(fractal3(p32, octaves)), repeats)
    t64 = _timed(lambda: dr.eval(fractal3(p64, octaves)), repeats)
    return {"points": points, "octaves": octaves, "repeats": repeats,
            "float32_s": t32, "float64_s": t64, "ratio": t64 / t32}


def run_stress(points: int = 2048, magnitudes=DEFAULT_MAGNITUDES, octaves=DEFAULT_OCTAVES,
               scale: float = 1.0, channel: MarbleChannel = PAPER_MARBLE, seed: int = 0,
               timing_points: int = 1_000_000, timing_octaves: int = 8,
               timing_repeats: int = 5) -> dict:
    """Measure float32 (and float64) error against the float64 reference; see the module doc.

    Returns a JSON-serialisable dict: ``fractal`` rows (one per magnitude, with
    per-octave ``measured``/``bound``/``measured_f64``), ``colour`` rows for
    ``channel``, ``timing`` (``timing_points`` = 0 skips it), ``limits`` and the
    constants the bounds use. Runs in the current JIT variant (llvm_ad_rgb when
    the current one is scalar).
    """
    if points < 1:
        raise ValueError(f"points must be at least 1, got {points}")
    magnitudes = [float(m) for m in magnitudes]
    octaves = [int(k) for k in octaves]
    k_max = max(octaves)
    rng = np.random.default_rng(seed)
    started = time.perf_counter()
    with _jit_variant() as variant:
        samples = [_sample(rng, m, points) for m in magnitudes]
        allp = np.concatenate(samples)
        v64 = allp * scale
        terms = np.cumsum(_reference_terms(v64, k_max), axis=0) if k_max else None
        fractal_rows = [{"magnitude": m, "measured": {}, "bound": {}, "measured_f64": {}}
                        for m in magnitudes]
        for k in octaves:
            ref = terms[k - 1] if k else np.zeros(len(allp))
            err32 = np.abs(_fractal_f32(allp, k, scale) - ref).reshape(len(magnitudes), points)
            # float64 evaluation of the float32 point: what a double-precision option keeps
            p32as64 = allp.astype(np.float32).astype(np.float64)
            err64 = np.abs(_fractal_f64(p32as64, k, scale) - ref).reshape(len(magnitudes), points)
            for row, e32, e64 in zip(fractal_rows, err32, err64):
                row["measured"][str(k)] = float(e32.max())
                row["measured_f64"][str(k)] = float(e64.max())
                row["bound"][str(k)] = fractal_error_bound(row["magnitude"], k, scale)
        # float64 Dr.Jit at the float64 point: the same code must equal the reference
        exact = max(np.abs(_fractal_f64(allp, k, scale) - (terms[k - 1] if k else 0.0)).max()
                    for k in octaves)

        tex = _texture(channel)
        colour_rows = []
        for m, pts in zip(magnitudes, samples):
            ref = reference_marble.marble_color(pts, channel)
            colour_rows.append({
                "magnitude": m,
                "measured": float(np.abs(_colour_f32(tex, pts) - ref).max()),
                "measured_f64": float(np.abs(_colour_f64(tex, pts, channel) - ref).max()),
                "bound": colour_error_bound(m, channel),
            })
        timing = (_timing(timing_points, timing_octaves, timing_repeats, seed)
                  if timing_points else None)
    return {
        "variant": variant, "points": points, "seed": seed, "scale": scale,
        "octaves": octaves, "magnitudes": magnitudes,
        "fractal": fractal_rows,
        "float64_drjit_vs_reference": float(exact),
        "channel": {"scale": channel.scale, "period": channel.period,
                    "distortion": channel.distortion, "octaves": channel.octaves,
                    "function": channel.function, "axis": channel.axis,
                    "ramp_colours": len(channel.ramp)},
        "colour": colour_rows,
        "timing": timing,
        "limits": meaningful_limit(scale),
        "constants": {"U": U, "L1": LIPSCHITZ_L1, "E": NOISE_ARITHMETIC_ERROR,
                      "B": NOISE_BOUND, "sin_error": SIN_ERROR,
                      "input_factor": input_error_factor(scale)},
        "seconds": time.perf_counter() - started,
    }


def _e(x: float) -> str:
    return f"{x:8.1e}"


def format_report(data: dict) -> str:
    """The tables of :func:`run_stress` as text (measured | bound per cell)."""
    ks = [str(k) for k in data["octaves"]]
    c = data["constants"]
    lines = [
        f"mimarble stress — float32 vs float64 reference ({data['variant']}, "
        f"{data['points']} random points per cell in [-|p|, |p|]^3, scale {data['scale']:g}, "
        f"seed {data['seed']})",
        "",
        "Fractal F: max |F32 - F64|  measured / bound",
        "  bound = sum_(i<min(K,25)) [min(L*dv, 2B*2^-i) + E*2^-i] + (K'-1)*u*2B (+ B*u if K>25),",
        f"  dv = {c['input_factor']}*u*|p|*scale, u = 2^-24, L = {c['L1']}, "
        f"B = {c['B']}, E = {c['E']:g}",
        "",
        "     |p| " + "".join(f" | K={k:<17}" for k in ks),
    ]
    for row in data["fractal"]:
        cells = "".join(f" | {_e(row['measured'][k])} {_e(row['bound'][k])}" for k in ks)
        lines.append(f"{row['magnitude']:8.1e} {cells}")
    lines += ["", "Float64 evaluation of the float32 point (what precision=\"double\" would give): "
              "max |F - F64|", "     |p| " + "".join(f" | K={k:<8}" for k in ks)]
    for row in data["fractal"]:
        lines.append(f"{row['magnitude']:8.1e} "
                     + "".join(f" | {_e(row['measured_f64'][k])}" for k in ks))
    lines.append(f"(float64 Dr.Jit at the float64 point vs the reference: "
                 f"{data['float64_drjit_vs_reference']:.1e}, the skipped octaves >= 25 included)")
    ch = data["channel"]
    lines += ["", f"Marble colour (scale {ch['scale']:g}, period {ch['period']:g}, distortion "
                  f"{ch['distortion']:g}, {ch['octaves']} octaves, {ch['function']}, "
                  f"{ch['ramp_colours']} colours): max component error",
              "     |p| |  float32 |    bound |  float64"]
    for row in data["colour"]:
        lines.append(f"{row['magnitude']:8.1e} | {_e(row['measured'])} | {_e(row['bound'])} | "
                     f"{_e(row['measured_f64'])}")
    if any(not math.isfinite(row["measured"]) for row in data["colour"]):
        lines.append("  nan: the float32 texture returned NaN at finite points — a bug: finite "
                     "input must give a finite colour (see docs/numerical-stability.md)")
    lim = data["limits"]
    lines += [
        "",
        f"Where float32 stops being meaningful (scale {data['scale']:g}): beyond |p| ~ "
        f"{lim['steps_per_cell_16']:.2g} a lattice cell is resolved in 16 steps or fewer; "
        f"beyond {lim['no_fraction']:.3g} (2^23/scale) the float32 point has no fractional part "
        f"(the noise is evaluated on the lattice only), and beyond {lim['all_even_integers']:.3g} "
        f"(2^24/scale) every coordinate is an even integer: F32 = 0 while F64 is anything in "
        f"[-2B, 2B]. The colour's 8-bit precision (1/255) is lost once the colour bound "
        f"passes 3.9e-3.",
    ]
    first_bad = next((r["magnitude"] for r in data["colour"] if r["bound"] > 1 / 255), None)
    if first_bad is not None:
        lines.append(f"  (colour bound > 1/255 from |p| = {first_bad:.1e} in this table)")
    t = data.get("timing")
    if t:
        lines += ["", f"Cost of float64 ({_cpu()}): fractal3, {t['points']:,} points, {t['octaves']} octaves, "
                      f"median of {t['repeats']} after warm-up: float32 {t['float32_s'] * 1e3:.1f} ms, "
                      f"float64 {t['float64_s'] * 1e3:.1f} ms ({t['ratio']:.2f}x)"]
    lines.append(f"({data['seconds']:.1f} s)")
    return "\n".join(lines)


def _cpu() -> str:
    """The machine a timing belongs to (CPU model and cores)."""
    from mimarble.runtime.machine import machine_facts
    facts = machine_facts()
    return f"{facts['processor']}, {facts['cores']} cores"


if __name__ == "__main__":   # python -m mimarble.tools.stress
    print(format_report(run_stress()))
