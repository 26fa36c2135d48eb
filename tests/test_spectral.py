"""Spectral variants (issue 37, item 5): ``marble``, ``channel_expression``,
``channel_material`` and ``marble_medium`` give spectra there, upsampling their RGB colours
with Mitsuba's sRGB model as ``bitmap`` does (mimarble/texture/srgb_model.py).

Checked against what does not come from that code: Mitsuba's own ``srgb_model_fetch`` (C++,
one colour at a time), the sigmoid of the model written out in NumPy, the RGB variant's
colours, Mitsuba's own ``diffuse`` and ``homogeneous``, and the RGB variant's renders.
"""

import importlib.util
import os
import subprocess
import sys

import numpy as np
import pytest

import mimarble
from mimarble.runtime import environment
from mimarble.texture import srgb_model

dr, mi = mimarble.dr, mimarble.mi
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

SPECTRAL = "llvm_ad_spectral"
RGB = "llvm_ad_rgb"
MARBLE = {"type": "marble", "scale": 1.0, "period": 1.3, "distortion": 3.0, "octaves": 6,
          "ramp": "1 0 0, 1 0.5 0, 0.2 0.6 1, 1 1 0.8"}


#: How far Mitsuba's float32 srgb_model_eval may be from the float64 sigmoid: the quadratic's
#: terms reach ~20 at λ ~ 800 nm, so q is rounded by ~20·2⁻²⁴ ≈ 1.2e-6 a term, and the
#: sigmoid's slope is at most ½ (seen: 2.7e-6).
FLOAT32_SPECTRUM = 1e-5


@pytest.fixture
def restore_variant():
    previous = mi.variant()
    yield
    mi.set_variant(previous)


def use(variant):
    problem = environment.variant_problem(variant)
    if problem:
        pytest.skip(problem)
    mi.set_variant(variant)


def sigmoid_spectrum(coefficients: np.ndarray, wavelengths: np.ndarray) -> np.ndarray:
    """The sRGB model's spectrum, written out in float64: ½ + ½ q/√(1 + q²), q the quadratic
    (q = ±∞ where c₂ is: 0 or 1)."""
    c0, c1, c2 = (coefficients[:, k:k + 1] for k in range(3))
    q = (c0 * wavelengths + c1) * wavelengths + c2
    return np.maximum(0.0, 0.5 + 0.5 * q / np.sqrt(1.0 + q * q))


def mitsubas_coefficients(colours: np.ndarray) -> np.ndarray:
    """Mitsuba's own fetch, one colour at a time (its C++ ``rgb2spec_fetch``)."""
    return np.array([list(mi.srgb_model_fetch(mi.ScalarColor3f(*map(float, c))))
                     for c in colours], dtype=np.float64)


def points(n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(-3.0, 3.0, (n, 3)).astype(np.float32), \
        rng.uniform(360.0, 830.0, (n, 4)).astype(np.float32)


def interaction(xyz, wavelengths=None):
    si = dr.zeros(mi.SurfaceInteraction3f, len(xyz))
    si.p = mi.Point3f(*(mi.Float(xyz[:, k]) for k in range(3)))
    if wavelengths is not None:
        si.wavelengths = mi.Spectrum(*(mi.Float(wavelengths[:, k]) for k in range(4)))
    return si


def as_numpy(value) -> np.ndarray:
    return np.stack([np.array(value[k], dtype=np.float64) for k in range(len(value))], axis=1)


def rgb_colours(texture_dict, xyz, variant=RGB) -> np.ndarray:
    """The texture's RGB colours at ``xyz``, made in the RGB ``variant``."""
    use(variant)
    if variant.startswith("scalar"):
        texture, si = mi.load_dict(texture_dict), dr.zeros(mi.SurfaceInteraction3f)
        out = []
        for p in xyz:
            si.p = mi.Point3f(*map(float, p))
            out.append(list(texture.eval(si)))
        return np.array(out, dtype=np.float64)
    return as_numpy(mi.load_dict(texture_dict).eval(interaction(xyz)))


# ---------------------------------------------------------------------------
# The model, per lane


def test_per_lane_fetch_equals_mitsubas_fetch_bit_for_bit(restore_variant):
    use(SPECTRAL)
    rng = np.random.default_rng(5)
    colours = rng.uniform(-0.3, 1.3, (3000, 3)).astype(np.float32)
    colours[:100] = colours[:100, :1]                      # greys (closed form)
    colours[100:110], colours[110:120] = 0.0, 1.0          # black, white
    colours[120:200, 2] = colours[120:200, 0]              # ties for the largest
    colours[200:300] *= 1e-6                               # near black
    colours[300:310] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [2.0, -1.0, 0.5],
                        [np.inf, 0.2, 0.1], [-np.inf, 0.5, 0.5], [0.3, 0.3, 0.30001],
                        [1.0, 1.0, 0.999], [0.5, 0.0, 0.0], [0.0, 0.0, 1e-30]]
    got = srgb_model.coefficients(srgb_model.model_table(),
                                  mi.Color3f(*(mi.Float(colours[:, k]) for k in range(3))))
    assert np.array_equal(as_numpy(got), mitsubas_coefficients(colours))


def test_a_nan_colour_is_a_nan_spectrum_and_its_neighbours_are_not(restore_variant):
    use(SPECTRAL)
    colour = mi.Color3f(mi.Float([np.nan, 0.5, 0.2]), mi.Float([0.1, np.nan, 0.3]), 0.4)
    value = as_numpy(srgb_model.spectrum(srgb_model.model_table(), colour, mi.Spectrum(550.0)))
    assert np.isnan(value[:2]).all() and np.isfinite(value[2]).all()


# ---------------------------------------------------------------------------
# marble


@pytest.mark.parametrize("variant", [RGB, SPECTRAL, "scalar_spectral"])
def test_marble_eval_is_its_rgb_colour_or_that_colours_upsampled_spectrum(restore_variant, variant):
    xyz, wavelengths = points(8 if variant.startswith("scalar") else 400, seed=3)
    colours = rgb_colours(MARBLE, xyz, variant.replace("_spectral", "_rgb"))
    use(variant)
    marble = mi.load_dict(MARBLE)
    if variant == RGB:
        assert np.array_equal(as_numpy(marble.eval(interaction(xyz))), colours)
        return
    if variant.startswith("scalar"):
        got = []
        for p, w in zip(xyz, wavelengths):
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.p, si.wavelengths = mi.Point3f(*map(float, p)), mi.Spectrum(*map(float, w))
            got.append(list(marble.eval(si)))
        got = np.array(got, dtype=np.float64)
    else:
        got = as_numpy(marble.eval(interaction(xyz, wavelengths)))
    want = sigmoid_spectrum(mitsubas_coefficients(colours.astype(np.float32)),
                            wavelengths.astype(np.float64))
    assert np.max(np.abs(got - want)) < FLOAT32_SPECTRUM
    # eval_1 stays the colour's luminance, eval_3 the colour (bitmap has neither there).
    if not variant.startswith("scalar"):
        si = interaction(xyz, wavelengths)
        assert np.array_equal(as_numpy(marble.eval_3(si)), colours)
        luminance = colours @ np.array([0.212671, 0.715160, 0.072169])
        assert np.allclose(np.array(marble.eval_1(si)), luminance, atol=1e-6)


def test_a_marbles_gradient_reaches_its_ramp_through_the_spectrum(restore_variant):
    """d(spectrum)/d(ramp) by AD against central differences of the spectral eval."""
    use(SPECTRAL)
    xyz, wavelengths = points(64, seed=8)
    marble = mi.load_dict(MARBLE)
    params = mi.traverse(marble)
    si = interaction(xyz, wavelengths)
    dr.enable_grad(params["ramp"])
    params.update()
    dr.backward(dr.sum(dr.sum(marble.eval(si))))
    gradient = np.array(dr.grad(params["ramp"]))           # (3, colours)
    base = np.array(dr.detach(params["ramp"]))
    channel, colour, h = 1, 1, 1e-2                          # the green of the second colour
    values = []
    for sign in (1.0, -1.0):
        moved = base.copy()
        moved[channel, colour] += sign * h
        params["ramp"] = mi.Color3f(moved)
        params.update()
        values.append(float(dr.sum(dr.sum(marble.eval(si)))[0]))
    central = (values[0] - values[1]) / (2 * h)
    assert gradient[channel, colour] != 0.0
    assert abs(gradient[channel, colour] - central) <= 2e-2 * abs(central) + 1e-3


def test_sample_spectrum_draws_its_wavelengths_with_the_density_pdf_spectrum_gives(
        restore_variant):
    """A histogram of the wavelengths ``sample_spectrum`` draws against ``pdf_spectrum``
    integrated over each bin (chi-square, seeded); weight × pdf = eval at every sample; and
    Mitsuba's ``area`` emitter (C++) samples its marble radiance's wavelengths the same way."""
    use(SPECTRAL)
    low, high = float(mi.MI_CIE_MIN), float(mi.MI_CIE_MAX)
    rng = np.random.default_rng(11)
    xyz, _ = points(50_000, seed=12)
    u = rng.random((len(xyz), 4), dtype=np.float32)
    marble, si = mi.load_dict(MARBLE), interaction(xyz)
    wavelengths, weight = marble.sample_spectrum(si, mi.Spectrum(*(mi.Float(u[:, k])
                                                                   for k in range(4))))
    drawn = as_numpy(wavelengths).ravel()
    assert drawn.min() >= low and drawn.max() <= high

    bins, per_bin = 47, 64                                   # 10 nm bins
    edges = np.linspace(low, high, bins + 1)
    fine = (edges[:-1, None] + (np.arange(per_bin) + 0.5)[None] / per_bin
            * np.diff(edges)[:, None]).ravel()
    probe = interaction(np.zeros((len(fine) // 4, 3), np.float32), fine.reshape(-1, 4))
    density = as_numpy(marble.pdf_spectrum(probe)).ravel().reshape(bins, per_bin)
    expected = density.mean(axis=1) * np.diff(edges) * len(drawn)
    assert expected.sum() == pytest.approx(len(drawn), rel=1e-5)   # the pdf integrates to 1
    observed, _ = np.histogram(drawn, edges)
    chi2, dof = float(np.sum((observed - expected) ** 2 / expected)), bins - 1
    z = 4.0                                                  # Wilson–Hilferty, p ≈ 3e-5
    assert chi2 < dof * (1 - 2 / (9 * dof) + z * np.sqrt(2 / (9 * dof))) ** 3

    outside = interaction(np.zeros((1, 3), np.float32), np.array([[300.0, low, high, 900.0]]))
    uniform = float(np.float32(1 / (high - low)))
    assert as_numpy(marble.pdf_spectrum(outside)).tolist() == [[0.0, uniform, uniform, 0.0]]

    moved = interaction(xyz, as_numpy(wavelengths))
    pdf, value = as_numpy(marble.pdf_spectrum(moved)), as_numpy(marble.eval(moved))
    np.testing.assert_allclose(as_numpy(weight) * pdf, value, rtol=1e-6, atol=1e-7)

    emitter = mi.load_dict({"type": "rectangle",
                            "emitter": {"type": "area", "radiance": MARBLE}}).emitter()
    sample = mi.Float(u[:, 0])
    got = emitter.sample_wavelengths(si, sample)
    shifted = u[:, :1] + np.float32([0.0, 0.25, 0.5, 0.75])  # Mitsuba's math::sample_shifted
    shifted -= np.floor(shifted)
    want = marble.sample_spectrum(si, mi.Spectrum(*(mi.Float(shifted[:, k]) for k in range(4))))
    for g, w in zip(got, want):
        np.testing.assert_allclose(as_numpy(g), as_numpy(w), rtol=1e-6)


# ---------------------------------------------------------------------------
# channel_expression


EXPRESSIONS = {
    "multiply": {"type": "channel_expression", "op": "multiply", "operand_0": MARBLE,
                 "operand_1": {"type": "srgb", "color": [0.9, 0.7, 0.3]}},
    "add": {"type": "channel_expression", "op": "add", "operand_0": MARBLE,
            "operand_1": {"type": "srgb", "color": [0.1, 0.2, 0.05]}},
    "mix": {"type": "channel_expression", "op": "mix", "operand_0": MARBLE,
            "operand_1": {"type": "srgb", "color": [0.2, 0.9, 0.4]}, "weight": 0.25},
}


@pytest.mark.parametrize("variant", [RGB, SPECTRAL])
@pytest.mark.parametrize("op", sorted(EXPRESSIONS))
def test_an_expression_combines_its_operands_values(restore_variant, variant, op):
    """RGB: the operands' colours combined; spectral: their spectra (the marble's and the
    constant's, each upsampled independently here) combined the same way."""
    xyz, wavelengths = points(300, seed=4)
    colours = rgb_colours(MARBLE, xyz)
    constant = np.array(EXPRESSIONS[op]["operand_1"]["color"], dtype=np.float32)
    use(variant)
    got = as_numpy(mi.load_dict(EXPRESSIONS[op]).eval(interaction(xyz, wavelengths)
                                                      if variant == SPECTRAL else interaction(xyz)))
    if variant == SPECTRAL:
        a = sigmoid_spectrum(mitsubas_coefficients(colours.astype(np.float32)), wavelengths)
        b = sigmoid_spectrum(mitsubas_coefficients(constant[None]), wavelengths)
    else:
        a, b = colours, constant[None].astype(np.float64)
    want = {"multiply": a * b, "add": a + b, "mix": a * 0.75 + b * 0.25}[op]
    assert np.max(np.abs(got - want)) < 3 * FLOAT32_SPECTRUM


def test_an_expression_of_marbles_keeps_an_rgb_colour_in_spectral(restore_variant):
    expression = {"type": "channel_expression", "op": "multiply", "operand_0": MARBLE,
                  "operand_1": {**MARBLE, "period": 2.1}}
    xyz, wavelengths = points(100, seed=6)
    want = rgb_colours(MARBLE, xyz) * rgb_colours({**MARBLE, "period": 2.1}, xyz)
    use(SPECTRAL)
    got = as_numpy(mi.load_dict(expression).eval_3(interaction(xyz, wavelengths)))
    assert np.max(np.abs(got - want)) < 1e-6


# ---------------------------------------------------------------------------
# channel_material, marble_medium: renders


def sphere(bsdf=None, interior=None, size=16, integrator="path"):
    out = {"type": "scene",
           "integrator": {"type": integrator, "max_depth": 16},
           "sensor": {"type": "perspective", "fov": 30,
                      "to_world": mi.ScalarTransform4f().look_at([0, 0, 5], [0, 0, 0], [0, 1, 0]),
                      "film": {"type": "hdrfilm", "width": size, "height": size,
                               "rfilter": {"type": "box"}},
                      "sampler": {"type": "independent", "sample_count": 16}},
           "sky": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
           "sphere": {"type": "sphere", "bsdf": bsdf or {"type": "dielectric", "int_ior": 1.5}}}
    if interior is not None:
        out["sphere"]["interior"] = interior
    return out


def test_channel_material_in_spectral_is_mitsubas_diffuse_of_the_same_marble(restore_variant):
    use(SPECTRAL)
    ours = mi.render(mi.load_dict(sphere({"type": "channel_material", "diffuse": MARBLE})), seed=1)
    theirs = mi.render(mi.load_dict(sphere({"type": "diffuse", "reflectance": MARBLE})), seed=1)
    assert np.array_equal(np.array(ours), np.array(theirs))
    assert np.array(ours)[..., :3].max() > 0.1


def test_marble_medium_in_spectral_is_homogeneous_for_a_one_colour_marble(restore_variant):
    """A one-colour marble albedo and no density: the medium of Mitsuba's ``homogeneous``
    with that colour as an ``srgb`` albedo (upsampled by Mitsuba's own fetch); the same
    seed and majorant draw the same walks, so the images agree to float rounding."""
    use(SPECTRAL)
    colour = [0.9, 0.5, 0.2]
    ours = {"type": "marble_medium", "albedo": {"type": "marble", "ramp": "0.9 0.5 0.2"}}
    theirs = {"type": "homogeneous", "sigma_t": 1.0,
              "albedo": {"type": "srgb", "color": colour}}
    a = np.array(mi.render(mi.load_dict(sphere(interior=ours, integrator="volpath")), seed=2))
    b = np.array(mi.render(mi.load_dict(sphere(interior=theirs, integrator="volpath")), seed=2))
    assert np.max(np.abs(a - b)) < 1e-4 and a[..., :3].mean() > 0.05


def test_marble_medium_density_is_the_same_number_in_rgb_and_spectral(restore_variant):
    """σ_t at medium points from a marble density: the mean of the RGB colour in both
    variants (made in the RGB variant here); σ_s the albedo's spectrum times σ_t."""
    density = {**MARBLE, "ramp": "0.2 0.2 0.2, 1 0.5 0.1, 0.9 0.9 0.9"}
    xyz, wavelengths = points(200, seed=9)
    d = rgb_colours(density, xyz).mean(axis=1)
    use(SPECTRAL)
    medium = mi.load_dict({"type": "marble_medium", "density": density, "scale": 2.0,
                           "albedo": {"type": "srgb", "color": [0.8, 0.4, 0.2]}})
    mei = dr.zeros(mi.MediumInteraction3f, len(xyz))
    mei.p = mi.Point3f(*(mi.Float(xyz[:, k]) for k in range(3)))
    mei.wavelengths = mi.Spectrum(*(mi.Float(wavelengths[:, k]) for k in range(4)))
    sigma_s, _, sigma_t = medium.get_scattering_coefficients(mei)
    sigma_t, sigma_s = as_numpy(sigma_t), as_numpy(sigma_s)
    assert np.allclose(sigma_t, 2.0 * d[:, None], rtol=1e-6, atol=1e-6)
    albedo = sigmoid_spectrum(mitsubas_coefficients(np.array([[0.8, 0.4, 0.2]], np.float32)),
                              wavelengths)
    assert np.allclose(sigma_s, albedo * sigma_t, rtol=1e-5, atol=1e-6)


def test_a_density_without_an_rgb_colour_is_refused_in_spectral(restore_variant):
    use(SPECTRAL)
    with pytest.raises(Exception, match="density must keep an RGB colour"):
        mi.load_dict({"type": "marble_medium",
                      "density": {"type": "srgb", "color": [0.5, 0.5, 0.5]}})


# ---------------------------------------------------------------------------
# Rendering a paper scene; what stays RGB


#: Path mode, spectral against RGB, image means per channel (docs/benchmarks.md, "Spectral
#: variants"): within this relative difference with roughplastic's internal scattering off
#: (linear in the reflectance: what is left is the model's round trip and the noise)…
LINEAR_TOLERANCE = 0.02
#: … and within this as translated (nonlinear: a spectrum's d/(1 − F·d) is not that of its
#: RGB projection, most for saturated colours near 1, as fig11a's reds).
NONLINEAR_TOLERANCE = 0.2


@pytest.mark.parametrize("nonlinear", [False, True])
def test_a_paper_scene_in_path_mode_agrees_with_rgb_within_the_stated_tolerance(
        restore_variant, nonlinear):
    # The renders of scripts/spectral_check.py (docs/benchmarks.md's figures), loaded by path.
    spec = importlib.util.spec_from_file_location(
        "spectral_check", os.path.join(ROOT, "scripts", "spectral_check.py"))
    spectral_check = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(spectral_check)
    render = spectral_check.render
    from mimarble import scene as scene_language
    from mimarble.scene.edits import with_image_size
    use(SPECTRAL)
    scene = with_image_size(scene_language.load(os.path.join(ROOT, "scenes", "fig11a.scene")),
                            width=32, height=32)
    rgb, spectral = (render(scene, v, 64, nonlinear) for v in (RGB, SPECTRAL))
    means = rgb.mean(axis=(0, 1)), spectral.mean(axis=(0, 1))
    lit = means[0] > 0.02                                 # fig11a's blue is ~0
    relative = np.abs(means[1][lit] / means[0][lit] - 1.0)
    assert relative.max() < (NONLINEAR_TOLERANCE if nonlinear else LINEAR_TOLERANCE), relative


def test_whitted_in_a_spectral_variant_is_one_sentence(restore_variant, tmp_path):
    use(SPECTRAL)
    with pytest.raises(mimarble.EnvironmentProblem, match="whitted integrator .* computes in RGB"):
        mimarble.render("scenes/fig10a.scene")
    with pytest.raises(Exception, match="whitted integrator"):
        mi.load_dict({"type": "whitted"})
    out = tmp_path / "x.png"
    result = subprocess.run([sys.executable, "-m", "mimarble", "--variant", SPECTRAL, "render",
                             "scenes/fig10a.scene", "-o", str(out)], cwd=ROOT,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert "--mode path" in result.stderr and not out.exists()


def test_doctor_lists_the_spectral_variant():
    result = subprocess.run([sys.executable, "-m", "mimarble", "doctor"], cwd=ROOT,
                            capture_output=True, text=True, timeout=300)
    row = [line for line in result.stdout.splitlines() if line.startswith("spectral")]
    assert row and (SPECTRAL in row[0] or "none usable" in row[0])
