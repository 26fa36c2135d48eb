"""The marble's knobs that POV-Ray has (issue 30): ramp colours at positions (POV-Ray's
``color_map``), its triangle and sawtooth waves, gain and lacunarity (``omega``,
``lambda``). Each renders through Mitsuba and through the float64 reference and agrees;
each is in the error budget, the filters, the gradient, and refused out of range.
"""

import dataclasses
import math

import numpy as np
import pytest

import mimarble
from mimarble.texture import error_budget, noise
from mimarble import reference
from mimarble import scene as S
from mimarble.tools.compare import image_metrics
from mimarble.parameters import MAX_LACUNARITY, ParameterError, parse_positioned_ramp, ramp_text
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.mitsuba.rendering.silhouettes import edge_mask
from mimarble.reference import marble as reference_marble
from mimarble.reference.prefilter import phase_average
from mimarble.scene.edits import resized, with_marbles
from mimarble.texture.stripes import STRIPES

dr, mi = mimarble.dr, mimarble.mi

SCENE = """image {{ width 40 height 40 samples 4 }}
camera {{ eye < 0 -9 0.5 > lookat < 0 0 0 > up < 0 0 1 > fov 30 }}
ambient < 0.2 0.2 0.2 >
light {{ position < 10 -10 10 > }}
material "m" {{ ambient {{ {marble} }} diffuse {{ {marble} }} specular {{ color < 0.3 0.3 0.3 > }} }}
sphere {{ radius 2 material "m" }}
"""
BASE = "octaves 6 period 1.3 distortion 2"
POV_MAP = "ramp { 0 < 0.9 0.9 0.85 > 0.5 < 0.5 0.4 0.3 > 0.8 #404040 1 < 0.1 0.1 0.1 > }"
THREE = ((0.9, 0.8, 0.7), (0.2, 0.5, 0.1), (0.05, 0.1, 0.6))


def scene_of(marble_keys: str) -> S.Scene:
    return S.parse(SCENE.format(marble=f"marble {{ {marble_keys} }}"), "knobs.scene")


def marble_of(marble_keys: str) -> S.MarbleChannel:
    return scene_of(marble_keys).materials["m"].diffuse


def texture(channel: S.MarbleChannel, tolerance: float = 0.0):
    from mimarble.mitsuba.translate.scene_dict import texture_dict
    return mi.load_dict(texture_dict(channel, tolerance))


def surface_points(points):
    si = dr.zeros(mi.SurfaceInteraction3f, len(points))
    si.p = mi.Point3f(*(mi.Float(np.asarray(points[:, a], np.float32)) for a in range(3)))
    return si


def colours(tex, points):
    return np.array(tex.eval(surface_points(points)), dtype=np.float64).T


POINTS = np.random.default_rng(30).uniform(-2, 2, (4000, 3)).astype(np.float32)


# ---------------------------------------------------------------------------
# Mitsuba against the reference, through the language

AGREEING = {
    "gain": f"{BASE} gain 0.65",
    "lacunarity": f"{BASE} lacunarity 2.7",
    "gain-lacunarity-turbulence": "octaves 8 period 1.1 distortion 3 gain 0.6 lacunarity 1.7 "
                                  "turbulence true",
    "triangle": f"{BASE} function triangle",
    "sawtooth": f"{BASE} function sawtooth",
    "positions": f"{BASE} {POV_MAP}",
    "positions-step": f"{BASE} ramp {{ 0.1 < 1 1 1 > 0.5 < 0.2 0.2 0.2 > 0.5 < 0.8 0.3 0.1 > "
                      f"0.9 < 0 0 0 > }}",
    "povray-marble": f"octaves 6 period 1 distortion 2.5 gain 0.5 lacunarity 2 function "
                     f"triangle {POV_MAP}",
}


@pytest.mark.parametrize("keys", AGREEING.values(), ids=AGREEING.keys())
def test_each_knob_renders_the_same_through_mitsuba_and_the_reference(llvm, keys):
    scene = scene_of(keys)
    metrics = image_metrics(mimarble.render(scene), reference.render(scene))
    assert metrics["psnr"] >= 100 and metrics["frac_over_1_255"] == 0, metrics


@pytest.mark.parametrize("keys", [AGREEING["gain-lacunarity-turbulence"],
                                  AGREEING["positions"], AGREEING["triangle"]],
                         ids=["gain-lacunarity", "positions", "triangle"])
def test_the_texture_agrees_with_the_reference_marble_at_points_in_every_variant(variant, keys):
    channel = marble_of(keys)
    tex = texture(channel)
    points = POINTS[:200] if variant == "scalar_rgb" else POINTS
    if variant == "scalar_rgb":
        ours = []
        for p in points:
            si = mi.SurfaceInteraction3f()
            si.p = mi.Point3f(*map(float, p))
            c = tex.eval(si)
            ours.append([c[0], c[1], c[2]])
        ours = np.array(ours)
    else:
        ours = colours(tex, points)
    expected = reference_marble.marble_color(points.astype(np.float64), channel)
    assert np.abs(ours - expected).max() < 3e-5


# ---------------------------------------------------------------------------
# Positions

def test_positions_on_even_keys_give_the_bits_of_the_evenly_spaced_ramp(variant):
    """0, ½, 1 (and 0, ¼, ½, ¾, 1) are exact in binary: the positioned lookup's
    (t − p_k)/(p_{k+1} − p_k) is the even one's t·(K−1) − k, bit for bit."""
    five = THREE + ((1.0, 1.0, 1.0), (0.0, 0.3, 0.3))
    points = POINTS[:100] if variant == "scalar_rgb" else POINTS
    for ramp, positions in ((THREE, (0.0, 0.5, 1.0)), (five, (0.0, 0.25, 0.5, 0.75, 1.0))):
        even = S.MarbleChannel(octaves=5, period=1.3, distortion=2.0, ramp=ramp)
        placed = dataclasses.replace(even, ramp_positions=positions)
        if variant == "scalar_rgb":
            a, b = texture(even), texture(placed)
            for p in points:
                si = mi.SurfaceInteraction3f()
                si.p = mi.Point3f(*map(float, p))
                assert list(a.eval(si)) == list(b.eval(si))
        else:
            np.testing.assert_array_equal(colours(texture(placed), points),
                                          colours(texture(even), points))
        exact = points.astype(np.float64)
        np.testing.assert_array_equal(reference_marble.marble_color(exact, placed),
                                      reference_marble.marble_color(exact, even))


def test_the_language_and_the_plugin_read_the_same_positions(llvm):
    channel = marble_of(f"{BASE} {POV_MAP}")
    assert channel.ramp_positions == (0.0, 0.5, 0.8, 1.0)
    assert channel.ramp[2] == pytest.approx((0.0512694,) * 3, abs=1e-6)    # #404040, sRGB
    inline = ", ".join(f"{p!r} {' '.join(map(repr, c))}" for p, c in
                       zip(channel.ramp_positions, channel.ramp))
    by_string = mi.load_dict({"type": "marble", "octaves": 6, "period": 1.3, "distortion": 2.0,
                              "tolerance": 0.0, "ramp": inline})
    by_key = mi.load_dict({"type": "marble", "octaves": 6, "period": 1.3, "distortion": 2.0,
                           "tolerance": 0.0, "ramp": ramp_text(channel.ramp),
                           "ramp_positions": "0, 0.5, 0.8, 1"})
    expected = colours(texture(channel), POINTS)
    np.testing.assert_array_equal(colours(by_string, POINTS), expected)
    np.testing.assert_array_equal(colours(by_key, POINTS), expected)
    assert parse_positioned_ramp("0 1 1 1, 0.5 #808080, 1 0 0 0")[1] == (0.0, 0.5, 1.0)


def test_outside_the_positions_the_end_colours_hold_and_a_step_takes_the_upper_colour(llvm):
    ramp = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 1.0, 1.0))
    positions = (0.25, 0.5, 0.5, 0.75)
    t = np.array([0.0, 0.1, 0.25, 0.375, 0.4999, 0.5, 0.625, 0.75, 0.9, 1.0])
    expected = np.array([[1, 0, 0], [1, 0, 0], [1, 0, 0], [0.5, 0.5, 0], [0.0004, 0.9996, 0],
                         [0, 0, 1], [0.5, 0.5, 1], [1, 1, 1], [1, 1, 1], [1, 1, 1]])
    np.testing.assert_allclose(reference_marble.ramp(t, ramp, positions), expected, atol=1e-12)
    tex = texture(S.MarbleChannel(ramp=ramp, ramp_positions=positions))
    ours = np.array(tex.ramp(mi.Float(t)), dtype=np.float64).T
    np.testing.assert_allclose(ours, expected, atol=1e-6)


def test_the_prefilter_integrates_a_positioned_ramp_as_the_float64_quadrature(llvm):
    positions = (0.1, 0.3, 0.35, 0.8, 0.9)
    ramp = tuple(map(tuple, np.random.default_rng(6).uniform(0, 1, (5, 3))))
    for function in ("abs_sine", "sine", "triangle", "sawtooth"):
        tex = texture(S.MarbleChannel(function=function, ramp=ramp, ramp_positions=positions,
                                      filter="prefilter"))
        rng = np.random.default_rng(7)
        # float32's numbers, which the texture is given (the sawtooth's jump would show
        # the rounding of the phase as an error of jump·1e-6/width)
        phase = rng.uniform(-20, 20, 200).astype(np.float32).astype(np.float64)
        width = np.concatenate([10 ** rng.uniform(-5, 1.5, 198), [3.0, 100.0]]).astype(
            np.float32).astype(np.float64)
        mean, defined = tex.pixel_filter.average(mi.Float(phase), mi.Float(width))
        point = tex.ramp(tex.stripe.t(mi.Float(phase)))
        ours = np.array(dr.select(defined, mean, point)).T
        expected = phase_average(phase, width, function, ramp, positions=positions)
        np.testing.assert_allclose(ours, expected, atol=2e-5, err_msg=function)
        # the texture's mean (a period's integral) is the quadrature's too
        period = STRIPES[function].shape.period
        mean_colour = np.array(tex.ramp.mean(tex.stripe), dtype=np.float64).ravel()
        np.testing.assert_allclose(mean_colour, phase_average([0.3], [period], function, ramp,
                                                              positions=positions)[0], atol=1e-6)


def test_editing_positions_gain_and_lacunarity_reuses_the_compiled_kernel(llvm):
    from test_marble import compiled_kernels, scene_with
    scene = scene_with({"type": "diffuse", "reflectance": {
        "type": "marble", "tolerance": 0.0, "ramp": "0 1 1 1, 0.4 0.5 0.2 0.1, 1 0 0 0"}})
    params = mi.traverse(scene)
    first = compiled_kernels(scene)
    key = "sphere.bsdf.reflectance."
    for name, value in [("ramp_positions", mi.Float([0.1, 0.6, 0.9])), ("gain", 0.45),
                        ("lacunarity", 2.2)]:
        params[key + name] = value
        params.update()
        assert compiled_kernels(scene) == first, name


@pytest.mark.parametrize("filter", ["none", "prefilter"])
@pytest.mark.parametrize("key, first, second", [
    ("gain", 0.45, 0.34), ("lacunarity", 2.6, 1.9),
    ("ramp_positions", [0.1, 0.5, 0.9], [0.05, 0.25, 0.45])])
def test_an_edit_of_the_knobs_replays_what_a_fresh_trace_renders(llvm, monkeypatch, filter, key,
                                                                first, second):
    """A recorded pass (dr.freeze) takes the new values as inputs: never stale."""
    from test_replay import SCENE as REPLAY, assert_replay_is_fresh, edit, recorded
    text = REPLAY.replace("FILTER", filter).replace(
        "ramp { < 1 0 0 > < 1 0.5 0 > < 1 1 0.5 > }",
        "gain 0.6 lacunarity 2.2 function triangle ramp { 0 < 1 0 0 > 0.4 < 1 0.5 0 > "
        "1 < 1 1 0.5 > }")
    scene = mi.load_dict(mimarble.to_mitsuba(S.parse(text)))
    value = (lambda v: mi.Float(v)) if isinstance(first, list) else float
    before = recorded(scene)
    edit(scene, **{f"texture_2__{key}": value(first)})      # the diffuse marble
    recorded(scene)
    edit(scene, **{f"texture_2__{key}": value(second)})
    assert_replay_is_fresh(scene, monkeypatch, recorded_again=False)
    assert not np.array_equal(before, render_in_passes(scene, 1))


# ---------------------------------------------------------------------------
# The waves

def test_the_triangle_and_sawtooth_waves_at_known_phases(variant):
    phase = [0.0, 0.125, 0.25, 0.5, 0.75, 0.875, 1.0, -0.25, 3.1, -2.6]
    triangle = [0.0, 0.25, 0.5, 1.0, 0.5, 0.25, 0.0, 0.5, 0.2, 0.8]
    sawtooth = [0.0, 0.125, 0.25, 0.5, 0.75, 0.875, 0.0, 0.75, 0.1, 0.4]
    for name, expected in (("triangle", triangle), ("sawtooth", sawtooth)):
        np.testing.assert_allclose(reference_marble.stripe_of_phase(np.array(phase), name),
                                   expected, atol=1e-15)
        stripe = STRIPES[name]
        if dr.is_jit_v(mi.Float):
            ours = np.array(stripe.t(mi.Float(phase)), dtype=np.float64)
        else:
            ours = np.array([stripe.t(float(p)) for p in phase])
        np.testing.assert_allclose(ours, expected, atol=1e-6)


def test_the_slope_of_each_wave_is_its_bound():
    phase = np.linspace(-3, 3, 600_001)
    for function in ("triangle", "sawtooth"):
        t = reference_marble.stripe_of_phase(phase, function)
        slopes = np.abs(np.diff(t)) / (phase[1] - phase[0])
        smooth = slopes[slopes < 10]                     # the sawtooth's jumps aside
        assert smooth.max() == pytest.approx(STRIPES[function].slope_bound, rel=1e-6)
    assert STRIPES["sawtooth"].jumps and not STRIPES["triangle"].jumps


def test_eval_1_grad_of_the_new_knobs_is_the_derivative_of_the_reference(llvm):
    luminance = np.array([0.212671, 0.715160, 0.072169])
    for keys in (AGREEING["gain-lacunarity-turbulence"], f"{BASE} function triangle",
                 f"{BASE} {POV_MAP}"):
        channel = marble_of(keys)
        tex = texture(channel)
        rng = np.random.default_rng(5)
        pts = POINTS.astype(np.float64)
        du = rng.normal(size=pts.shape)
        si = surface_points(pts)
        si.dp_du = mi.Vector3f(*(mi.Float(du[:, a].astype(np.float32)) for a in range(3)))
        si.dp_dv = mi.Vector3f(0.0, 0.0, 0.0)
        ours = np.array(tex.eval_1_grad(si))[0]
        d = du.astype(np.float32).astype(np.float64)
        h = 1e-7

        def f(q):
            return reference_marble.marble_color(q, channel) @ luminance
        ahead, here, behind = f(pts + h * d), f(pts), f(pts - h * d)
        forward, backward = (ahead - here) / h, (here - behind) / h
        smooth = np.abs(forward - backward) < 1e-2 * (1 + np.abs(forward))
        expected = (ahead - behind) / (2 * h)
        assert smooth.mean() > 0.9
        error = np.abs(ours - expected)[smooth] / (1 + np.abs(expected[smooth]))
        assert np.quantile(error, 0.999) < 2e-3, keys


# ---------------------------------------------------------------------------
# Gain and lacunarity: the noise, the budget, the filters

def test_the_octaves_float32_can_add_depend_on_the_gain():
    assert noise.max_octaves_evaluated(0.5) == noise.MAX_OCTAVES_EVALUATED == 25
    counts = [noise.max_octaves_evaluated(g) for g in (0.1, 0.3, 0.5, 0.6, 0.7, 0.75, 0.8, 0.95)]
    assert counts == sorted(counts) and counts[-1] == 64 and counts[0] < 10
    for gain in (0.3, 0.6, 0.7):
        k = noise.max_octaves_evaluated(gain)
        # the tail from k on is within float32's resolution, the one from k − 1 is not
        assert gain ** k / (1 - gain) <= 2.0 ** -24 < gain ** (k - 1) / (1 - gain)
    tex = mi.load_dict({"type": "marble", "octaves": 64, "tolerance": 0.0, "gain": 0.7})
    assert tex.octaves_evaluated == noise.max_octaves_evaluated(0.7) > 25


def test_the_noise_sum_is_the_reference_sum_at_another_gain_and_lacunarity(jit_variant):
    pts = np.random.default_rng(4).uniform(-5, 5, (5000, 3))
    for gain, lacunarity, turbulence in ((0.7, 2.5, False), (0.35, 1.6, True), (0.5, 3.0, False)):
        ours = noise.fractal(pts, 8, turbulence, gain, lacunarity)
        expected = reference.noise.fractal3(pts.astype(np.float32).astype(np.float64), 8,
                                            turbulence, gain, lacunarity)
        # float32 rounds λ^i·p (not exact, unlike 2^i·p) by up to U·5λ^i, which moves
        # octave i by ω^i·|∇N|·U·5λ^i (|∇N| ≤ 2.5 here, generously)
        bound = 1e-6 + 2.5 * 2.0 ** -24 * 5 * sum((gain * lacunarity) ** i for i in range(8))
        assert np.abs(ours - expected).max() <= bound, (gain, lacunarity)


@pytest.mark.parametrize("gain", [0.3, 0.7])
@pytest.mark.parametrize("function, ramp, positions", [
    ("abs_sine", THREE, None),
    ("triangle", THREE, (0.1, 0.7, 0.9)),
    ("sawtooth", THREE + (THREE[0],), None),         # equal ends: no jump in colour
], ids=["abs_sine", "triangle-positions", "sawtooth"])
@pytest.mark.parametrize("tolerance", [1e-2, 1e-4])
def test_the_budget_holds_at_another_gain(gain, function, ramp, positions, tolerance):
    """In float64, no float32 involved: the reference's colour with the octaves the
    budget keeps against the reference's colour with every octave float32 could add."""
    octaves = noise.max_octaves_evaluated(gain)
    channel = S.MarbleChannel(octaves=octaves, distortion=2.0, period=1.3, gain=gain,
                              lacunarity=2.3, function=function, ramp=ramp,
                              ramp_positions=positions)
    k = error_budget.octaves_needed(tolerance, octaves, 2.0, ramp, function, gain=gain,
                                    positions=positions)
    assert 0 < k < octaves                          # it does leave octaves out
    p = np.random.default_rng(3).uniform(-3, 3, (4096, 3))
    full = reference_marble.marble_color(p, channel)
    cut = reference_marble.marble_color(p, dataclasses.replace(channel, octaves=k))
    assert np.abs(cut - full).max() <= tolerance * (1 + 1e-9)


def test_the_texture_at_a_tolerance_is_within_it_of_every_octave_at_another_gain(llvm):
    channel = S.MarbleChannel(octaves=40, distortion=2.0, period=1.3, gain=0.7, lacunarity=2.2,
                              function="triangle", ramp=THREE, ramp_positions=(0.0, 0.6, 1.0))
    budgeted, every = texture(channel, 1e-3), texture(channel, 0.0)
    assert budgeted.octaves_evaluated < every.octaves_evaluated == 40
    difference = np.abs(colours(budgeted, POINTS) - colours(every, POINTS)).max()
    assert difference <= 1e-3 + 1e-5      # the tolerance, plus float32's rounding


def test_what_the_budget_cannot_bound_keeps_every_octave():
    """A hard step in the ramp, or the sawtooth's jump between different end colours: the
    colour can move by the jump however little the phase moves."""
    step = error_budget.octaves_needed(1e-2, 20, 2.0, THREE, "abs_sine",
                                       positions=(0.0, 0.5, 0.5))
    jump = error_budget.octaves_needed(1e-2, 20, 2.0, THREE, "sawtooth")
    assert step == jump == 20
    assert error_budget.octaves_needed(1e-2, 20, 0.0, THREE, "sawtooth") == 0   # no noise


def test_a_band_at_another_lacunarity_keeps_the_octaves_below_the_footprint(llvm):
    pts = np.random.default_rng(2).uniform(-20, 20, (2000, 3)).astype(np.float32)
    p = mi.Point3f(*(mi.Float(pts[:, a]) for a in range(3)))
    lacunarity, gain = 2.5, 0.6
    spectrum = noise.Spectrum(gain, lacunarity, mi.Float(gain), mi.Float(lacunarity),
                              opaque=True, octaves=8)
    # margin 1 and λ^2.1·footprint = ½: n = 1 + 2.1, three whole octaves, none faded in.
    footprint = dr.full(mi.Float, 0.5 * lacunarity ** -2.1, dr.width(p))
    band = noise.band_limit(footprint, 8, 1.0, spectrum)
    assert np.allclose(np.array(band[0]), 3.0) and np.allclose(np.array(band[1]), 0.0)
    banded = noise.fractal_gradient(p, 8, spectrum=spectrum, band=band)
    three = noise.fractal_gradient(p, 3, spectrum=spectrum)
    np.testing.assert_allclose(np.array(banded.value), np.array(three.value), atol=1e-6)
    np.testing.assert_allclose(np.array(banded.gradient), np.array(three.gradient), atol=1e-5)
    _, variance = noise.left_out(band, 8, False, spectrum)
    np.testing.assert_allclose(np.array(variance), noise.NOISE_VARIANCE
                               * sum(gain ** (2 * i) for i in range(3, 8)), rtol=1e-5)
    mean, _ = noise.left_out(band, 8, True, spectrum)
    np.testing.assert_allclose(np.array(mean), noise.ABS_NOISE_MEAN
                               * sum(gain ** i for i in range(3, 8)), rtol=1e-5)


def test_one_prefiltered_sample_of_the_new_knobs_is_closer_to_the_pixel_average(llvm):
    scene = with_marbles(resized(S.load("scenes/fig11a.scene"), 48), octaves=2, gain=0.6,
                         lacunarity=2.5, function="triangle")
    scene = dataclasses.replace(scene, lights=(), ambient=(1.0, 1.0, 1.0))

    def image(spp, filter="none"):
        return render_in_passes(mi.load_dict(to_mitsuba(scene, spp=spp, filter=filter)), spp)

    truth = image(144)
    inside = ~edge_mask(mi.load_dict(to_mitsuba(scene, spp=16)), 16)
    error = {f: np.sqrt(np.mean(((image(1, f) - truth) ** 2)[inside]))
             for f in ("none", "bandlimit", "prefilter")}
    assert error["prefilter"] < 0.5 * error["none"], error
    assert error["bandlimit"] < 1.2 * error["none"], error


# ---------------------------------------------------------------------------
# Refused, in the language (FILE:LINE:COL) and in the plugin (ParameterError)

@pytest.mark.parametrize("keys, at, words", [
    ("gain 1", "1", "gain must be > 0 and < 1, found 1"),
    ("gain 0", "0", "gain must be > 0 and < 1, found 0"),
    ("gain -0.5", "-0.5", "gain must be > 0 and < 1, found -0.5"),
    ("lacunarity 1", "1", "lacunarity must be > 1 and ≤ 3, found 1"),
    ("lacunarity 3.5", "3.5", "lacunarity must be > 1 and ≤ 3, found 3.5"),
    ("function wave", "wave", "function must be one of abs_sine, sine, cosine, triangle or "
                              "sawtooth, found wave"),
    ("ramp { 0.5 < 1 1 1 > 0.2 < 0 0 0 > }", "0.2", "ramp position 0.2 (colour 2) is below "
                                                    "the one before it, 0.5: positions must "
                                                    "not decrease"),
    ("ramp { 0 < 1 1 1 > 1.5 < 0 0 0 > }", "1.5", "ramp position 1.5 (colour 2) must be in "
                                                  "[0, 1]"),
    ("ramp { -0.1 < 1 1 1 > 1 < 0 0 0 > }", "-0.1", "ramp position -0.1 (colour 1) must be "
                                                    "in [0, 1]"),
    ("ramp { 0 < 1 1 1 > < 0 0 0 > }", "< 0 0 0 >", "ramp colour 2 has no position, where "
                                                    "others have one"),
    ("ramp { 0 < 1 1 1 > 0.5 }", "0.5", "ramp position 0.5 has no colour after it"),
    ("ramp { 0 0.5 < 1 1 1 > }", "0 0.5", "ramp position 0 has no colour after it"),
])
def test_bad_knobs_are_refused_at_their_token(keys, at, words):
    prefix = 'material "m" { diffuse { marble { '
    text = prefix + keys + ' } } }\nsphere { material "m" }\n'
    column = len(prefix) + keys.index(at, 1 if keys.startswith("ramp") else 0) + 1
    with pytest.raises(S.SceneError) as info:
        S.parse(text, "bad.scene")
    assert str(info.value).startswith(f"bad.scene:1:{column}: "), str(info.value)
    assert words in str(info.value)


@pytest.mark.parametrize("props, words", [
    ({"gain": 1.0}, "gain must be > 0 and < 1, found 1.0"),
    ({"gain": 0.0}, "gain must be > 0 and < 1"),
    ({"gain": 0.999999999}, "gain must be > 0 and < 1 in single precision"),
    ({"lacunarity": 1.0}, "lacunarity must be > 1 and ≤ 3"),
    ({"lacunarity": 4.0}, "lacunarity must be > 1 and ≤ 3, found 4.0"),
    ({"ramp": "0 1 1 1, 0 0 0"}, "give every colour a position or none"),
    ({"ramp": "0.5 1 1 1, 0.2 0 0 0"}, "positions must not decrease"),
    ({"ramp": "0 1 1 1, 2 0 0 0"}, "must be in [0, 1]"),
    ({"ramp": "1 1 1, 0 0 0, 1 0 0", "ramp_positions": "0, 1"},
     "ramp_positions has 2 positions for 3 colours"),
    ({"ramp": "0 1 1 1, 1 0 0 0", "ramp_positions": "0, 1"}, "not both"),
])
def test_bad_knobs_are_a_parameter_error_in_the_plugin(variant, props, words):
    with pytest.raises(Exception, match=None) as info:
        mi.load_dict({"type": "marble", **props})
    assert words in str(info.value)
    with pytest.raises(ParameterError):      # the same from the parameter table itself
        from mimarble.parameters import MarbleParameters
        MarbleParameters.from_properties(props)


def test_an_edit_that_breaks_the_positions_is_nan_until_mended(llvm):
    """Positions set as an array live on the device: the update reads nothing back, the
    kernel checks them (docs/design-decisions.md, "The update path"): NaN everywhere while
    they decrease, check_values says why, and valid ones render as before."""
    tex = mi.load_dict({"type": "marble", "ramp": "0 1 1 1, 0.4 0.5 0.2 0.1, 1 0 0 0"})
    params = mi.traverse(tex)
    before = colours(tex, POINTS[:50])
    params["ramp_positions"] = mi.Float([0.5, 0.2, 1.0])
    params.update()
    assert np.isnan(colours(tex, POINTS[:50])).all()
    with pytest.raises(ParameterError, match="positions must not decrease"):
        tex.check_values()
    params["ramp_positions"] = mi.Float([0.0, 0.4, 1.0])
    params.update()
    np.testing.assert_array_equal(colours(tex, POINTS[:50]), before)


def test_the_lacunarity_bound_keeps_the_finest_octave_finite():
    """λ ≤ 3: λ^63 times the largest point the noise sees (< 2^24) stays in float32."""
    assert MAX_LACUNARITY ** 63 * 2.0 ** 24 < 2.0 ** 125 < 3.2 ** 63 * 2.0 ** 24
    pts = np.array([[1.6e7, -1.2e7, 3.3], [0.1, 0.2, 0.3]])
    out = noise.fractal(pts, 64, False, 0.9, MAX_LACUNARITY)
    assert np.isfinite(out).all()
    assert math.isfinite(noise.max_octaves_evaluated(0.9))
