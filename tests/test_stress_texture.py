"""Stress suite for the ``marble`` texture (issue 7): colours stay on the ramp, the stated
colour error bound holds, small moves give small changes, NaN policy, determinism.

Expected colours come from ``mimarble.reference.marble`` (float64 NumPy on the
reference noise), never from the texture itself.
"""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mimarble
from mimarble.tools import stress
from mimarble.reference import marble as reference_marble
from mimarble.scene.model import FIG5_RAMP, MarbleChannel

dr, mi = mimarble.dr, mimarble.mi
U = 2.0 ** -24


def stress_settings(n):
    return settings(max_examples=n, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow])


def texture(channel):
    return mi.load_dict({
        "type": "marble", "scale": channel.scale, "period": channel.period,
        "distortion": channel.distortion, "octaves": channel.octaves,
        "function": channel.function, "axis": channel.axis, "turbulence": channel.turbulence,
        "ramp": ", ".join(" ".join(repr(float(x)) for x in c) for c in channel.ramp)})


def eval_at(tex, points):
    points = np.asarray(points, dtype=np.float32)
    si = dr.zeros(mi.SurfaceInteraction3f, len(points))
    si.p = mi.Point3f(*(mi.Float(np.ascontiguousarray(points[:, a])) for a in range(3)))
    return np.array(tex.eval(si), dtype=np.float64).T


def random_ramp(k, seed):
    return tuple(map(tuple, np.random.default_rng(seed).uniform(0, 1, (k, 3)).astype(np.float32)
                     .astype(np.float64)))


def on_a_ramp_segment(colours, ramp, tol):
    """Whether each colour lies (within tol) on the segment between two adjacent ramp keys."""
    ramp = np.asarray(ramp, dtype=np.float64)
    if len(ramp) == 1:
        return np.all(np.abs(colours - ramp[0]) <= tol, axis=1)
    a, b = ramp[:-1], ramp[1:]                                   # (S, 3) segments
    d = b - a
    dd = np.maximum((d * d).sum(axis=1), 1e-300)
    rel = colours[:, None, :] - a[None]                          # (N, S, 3)
    f = np.clip((rel * d[None]).sum(axis=2) / dd[None], 0.0, 1.0)
    closest = a[None] + f[..., None] * d[None]
    dist = np.abs(colours[:, None, :] - closest).max(axis=2).min(axis=1)
    return dist <= tol


@st.composite
def world_points(draw, max_exponent=17.0):
    """Up to 64 points, coordinates of magnitude 1e-30..10^max_exponent, both signs."""
    n = draw(st.integers(1, 64))
    seed = draw(st.integers(0, 2**31))
    rng = np.random.default_rng(seed)
    exps = rng.uniform(-30, max_exponent, (n, 3))
    pts = 10.0 ** exps * rng.choice([-1.0, 1.0], (n, 3))
    small = rng.uniform(-5, 5, (n, 3))
    pick = rng.random((n, 3)) < 0.4
    return np.where(pick, small, pts).astype(np.float32)


@st.composite
def channels(draw):
    k = draw(st.sampled_from([1, 2, 8, 256]))
    ramp = FIG5_RAMP if k == 8 else random_ramp(k, draw(st.integers(0, 1000)))
    return MarbleChannel(
        scale=draw(st.sampled_from([1e-6, 1e-2, 1.0, 3.3, 1e3, 1e6])),
        period=draw(st.sampled_from([0.0, 1e-6, 1.3, -20.0, 1e6])),
        distortion=draw(st.sampled_from([0.0, 3.0, -1e6, 1e6])),
        octaves=draw(st.sampled_from([0, 1, 8, 25, 64])),
        function=draw(st.sampled_from(["abs_sine", "sine", "cosine"])),
        axis=draw(st.sampled_from(["x", "y", "z"])),
        turbulence=draw(st.booleans()),
        ramp=ramp)


@stress_settings(50)
@given(ch=channels(), pts=world_points())
def test_colour_is_finite_and_on_the_ramp_for_extreme_parameters(llvm, ch, pts):
    colours = eval_at(texture(ch), pts)
    ramp = np.asarray(ch.ramp, dtype=np.float64)
    assert np.all(np.isfinite(colours))
    tol = 8 * U * max(1.0, np.abs(ramp).max())
    assert np.all(colours >= ramp.min(axis=0) - tol)
    assert np.all(colours <= ramp.max(axis=0) + tol)
    assert np.all(on_a_ramp_segment(colours, ramp, tol))


@pytest.mark.parametrize("function", ["abs_sine", "sine", "cosine"])
def test_finite_point_far_out_gives_a_finite_colour(llvm, function):
    ch = MarbleChannel(function=function, octaves=4)
    colours = eval_at(texture(ch), np.float32([[1e20, 1e20, 1e20], [-3e38, 2.0, 1.0]]))
    assert np.all(np.isfinite(colours))


def test_non_finite_points_give_nan_colours_and_leave_other_lanes_alone(llvm):
    tex = texture(MarbleChannel(octaves=8))
    rng = np.random.default_rng(3)
    good = rng.uniform(-3, 3, (30, 3)).astype(np.float32)
    bad = good.copy()
    bad[0, 0], bad[1, 1], bad[2, 2] = np.nan, np.inf, -np.inf
    out, ref = eval_at(tex, bad), eval_at(tex, good)
    assert np.all(np.isnan(out[:3]))
    np.testing.assert_array_equal(out[3:], ref[3:])


def test_one_colour_ramp_is_exactly_that_colour_everywhere(llvm):
    colour = (0.25, 0.5, 0.75)
    tex = texture(MarbleChannel(ramp=(colour,), octaves=64, distortion=1e6, scale=1e6))
    pts = np.float32([[1e20, -1e-30, 0.0], [3.0, 1e10, -7.0], [np.nan, 0, 0]])
    out = eval_at(tex, pts)
    np.testing.assert_array_equal(out, np.float32([colour] * 3).astype(np.float64))


# ---------------------------------------------------------------------------
# The stated colour error bound (docs/numerical-stability.md)

def measured_colour_error(ch, magnitude, n=1024, seed=0):
    p = np.random.default_rng(seed).uniform(-magnitude, magnitude, (n, 3))
    return np.abs(eval_at(texture(ch), p.astype(np.float32))
                  - reference_marble.marble_color(p, ch)).max()


@pytest.mark.parametrize("magnitude", [1e-3, 1.0, 10.0, 100.0, 1e3, 1e4, 1e5, 1e7])
def test_paper_marble_colour_error_is_within_the_stated_bound(llvm, magnitude):
    ch = stress.PAPER_MARBLE
    measured = measured_colour_error(ch, magnitude)
    bound = stress.colour_error_bound(magnitude, ch)
    assert measured <= bound
    if 1.0 <= magnitude <= 1e3:
        assert bound <= 100 * measured


@stress_settings(30)
@given(ch=channels(), magnitude=st.sampled_from([1e-3, 1.0, 30.0, 1e3, 1e5]),
       seed=st.integers(0, 1000))
def test_colour_bound_holds_for_extreme_parameters(llvm, ch, magnitude, seed):
    assert measured_colour_error(ch, magnitude, n=256, seed=seed) <= \
        stress.colour_error_bound(magnitude, ch)


@stress_settings(25)
@given(seed=st.integers(0, 2**31), step=st.floats(1e-3, 1e-2),
       function=st.sampled_from(["abs_sine", "sine", "cosine"]))
def test_small_moves_give_small_colour_changes(llvm, seed, step, function):
    """|c(p+δ) − c(p)| ≤ L_ramp·|dt/dp|·‖δ‖ + twice the float32 error (|p| ≤ 10, δ ≥ 1e-3)."""
    ch = MarbleChannel(scale=1.0, period=1.3, distortion=3.0, octaves=12, function=function)
    rng = np.random.default_rng(seed)
    p = rng.uniform(-10, 10, (1024, 3)).astype(np.float32)
    q = (p + rng.uniform(-step, step, (1024, 3))).astype(np.float32)
    delta = np.abs(q.astype(np.float64) - p).max(axis=1)
    tex = texture(ch)
    jump = np.abs(eval_at(tex, q) - eval_at(tex, p)).max(axis=1)
    # dφ/dp ≤ period + distortion·K·L1 (max-norm); dt/dφ ≤ π (abs_sine) or ½ (sine, cosine)
    slope = (np.pi if function == "abs_sine" else 0.5) * (1.3 + 3.0 * 12 * stress.LIPSCHITZ_L1)
    lipschitz_ramp = 7 * 0.125
    assert np.all(jump <= lipschitz_ramp * slope * delta + 2 * stress.colour_error_bound(10.0, ch))


def test_texture_is_bit_identical_from_run_to_run(llvm):
    ch = MarbleChannel(scale=1.7, period=1.3, distortion=3.0, octaves=64, turbulence=True)
    pts = np.random.default_rng(5).uniform(-1e4, 1e4, (50_000, 3)).astype(np.float32)
    a = eval_at(texture(ch), pts)
    b = eval_at(texture(ch), pts)
    np.testing.assert_array_equal(a, b)


def test_scalar_variant_texture_agrees_to_float32_rounding(llvm):
    """scalar_rgb runs the same code (Python doubles, with scale·p stored as float32 in a
    Point3f): within the stated bound of the reference, and of the LLVM result."""
    ch = MarbleChannel(scale=1.7, period=1.3, distortion=3.0, octaves=12)
    pts = np.random.default_rng(6).uniform(-5, 5, (64, 3)).astype(np.float32)
    ours = eval_at(texture(ch), pts)
    mi.set_variant("scalar_rgb")
    try:
        tex = texture(ch)
        scalar = []
        for p in pts:
            si = mi.SurfaceInteraction3f()
            si.p = mi.Point3f(*map(float, p))
            c = tex.eval(si)
            scalar.append([c[0], c[1], c[2]])
    finally:
        mi.set_variant("llvm_ad_rgb")
    ref = reference_marble.marble_color(pts.astype(np.float64), ch)
    bound = stress.colour_error_bound(5.0, ch)
    assert np.all(np.isfinite(scalar))
    assert np.abs(np.array(scalar) - ref).max() <= bound
    assert np.abs(ours - np.array(scalar)).max() <= 2 * bound


@pytest.mark.parametrize("function", ["abs_sine", "sine", "cosine"])
@pytest.mark.parametrize("huge", [{"scale": 3e38}, {"period": 3e38}, {"distortion": -3e38},
                                  {"period": 3e38, "distortion": 3e38}])
def test_overflowing_but_finite_parameters_give_finite_colours_and_nan_stays_nan(llvm, function, huge):
    tex = texture(MarbleChannel(function=function, octaves=4, **huge))
    colours = eval_at(tex, np.float32([[2.0, 1.0, 1.0], [0.5, -3.0, 7.0], [np.nan, 1.0, 1.0]]))
    assert np.all(np.isfinite(colours[:2]))
    assert np.all(np.isnan(colours[2]))
