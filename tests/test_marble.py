"""The ``marble`` Mitsuba texture: values, loading, BSDF use, gradients, kernel reuse, errors."""

import math

import numpy as np
import pytest

import mimarble
from mimarble.parameters import ParameterError
import marble64

dr, mi = mimarble.dr, mimarble.mi

FUNCTIONS = ["abs_sine", "sine", "cosine"]
AXES = ["x", "y", "z"]


def texture(**params):
    return mi.load_dict({"type": "marble", **params})


def eval_at(tex, points):
    """Texture colours at NumPy points (N, 3), through Mitsuba's Texture.eval."""
    points = np.asarray(points, dtype=np.float32)
    if dr.is_jit_v(mi.Float):
        si = dr.zeros(mi.SurfaceInteraction3f, len(points))
        si.p = mi.Point3f(*(mi.Float(points[:, a]) for a in range(3)))
        return np.array(tex.eval(si), dtype=np.float64).T   # Color3f converts as (3, N)
    out = []
    for p in points:
        si = mi.SurfaceInteraction3f()
        si.p = mi.Point3f(*map(float, p))
        c = tex.eval(si)
        out.append([c[0], c[1], c[2]])
    return np.array(out)


def random_points(n, half=3.0, seed=0):
    return np.random.default_rng(seed).uniform(-half, half, (n, 3)).astype(np.float32)


# Float32 error of the colour: F carries ≤ ~4e-6 (see test_noise), the phase
# period·v_a is rounded to ~1 ulp of |phase| ≤ 40 (4e-6), so t moves by at most
# π·(4e-6 + distortion·4e-6) ≈ 5e-5 and the colour by (K−1)·Δramp·Δt ≤ 5e-5.
COLOUR_TOL = 2e-4


@pytest.mark.parametrize("function", FUNCTIONS)
@pytest.mark.parametrize("axis", AXES)
def test_values_match_float64_formula(jit_variant, function, axis):
    params = dict(scale=1.7, period=1.3, distortion=3.0, octaves=12, function=function, axis=axis)
    # A seed per case that every run draws alike (hash() of strings changes with
    # PYTHONHASHSEED).
    pts = random_points(4000, seed=10 * FUNCTIONS.index(function) + AXES.index(axis))
    ours = eval_at(texture(**params), pts)
    ref = marble64.colour(pts.astype(np.float64), **params)
    assert np.abs(ours - ref).max() <= COLOUR_TOL


@pytest.mark.parametrize("turbulence", [False, True])
def test_values_match_in_every_variant(variant, turbulence):
    params = dict(scale=0.6, period=2.0, distortion=1.5, octaves=6, turbulence=turbulence,
                  ramp="0 0 0, 1 1 1, 0.2 0.4 0.8")
    pts = random_points(200 if variant.startswith("scalar") else 4000, seed=11)
    ours = eval_at(texture(**params), pts)
    ramp = [(0, 0, 0), (1, 1, 1), (0.2, 0.4, 0.8)]
    ref = marble64.colour(pts.astype(np.float64), ramp_colours=ramp,
                          **{k: v for k, v in params.items() if k != "ramp"})
    assert np.abs(ours - ref).max() <= COLOUR_TOL


def test_to_world_moves_the_texture(jit_variant):
    shift = np.array([0.25, -1.0, 3.0])
    tex = texture(to_world=mi.ScalarTransform4f().translate(shift.tolist()), octaves=4)
    pts = random_points(2000, seed=12)
    ref = marble64.colour(pts.astype(np.float64) - shift, octaves=4)
    assert np.abs(eval_at(tex, pts) - ref).max() <= COLOUR_TOL


def test_zero_distortion_skips_the_noise(llvm):
    def operations(tex):
        si = dr.zeros(mi.SurfaceInteraction3f, 64)
        si.p = mi.Point3f(dr.linspace(mi.Float, 0, 1, 64), 0.5, 0.25)
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
            dr.eval(tex.eval(si))
            return sum(k.get("operation_count", 0) for k in dr.kernel_history())   # debug mode adds non-kernel entries

    plain, noisy = texture(distortion=0.0, octaves=8), texture(distortion=1.0, octaves=8)
    assert not plain.needs_noise and noisy.needs_noise
    assert operations(plain) + 250 < operations(noisy)      # the noise: hundreds of operations
    pts = random_points(1000, seed=13)
    assert np.abs(eval_at(plain, pts) - marble64.colour(pts, distortion=0.0)).max() <= COLOUR_TOL


def test_one_colour_ramp_is_a_constant(variant):
    tex = texture(ramp="0.25 0.5 0.75")
    assert not tex.is_spatially_varying()
    np.testing.assert_allclose(eval_at(tex, random_points(10)), [[0.25, 0.5, 0.75]] * 10)
    assert tex.max() == 0.75


def test_mean_matches_a_large_sample(llvm):
    for function in FUNCTIONS:
        tex = texture(function=function, period=1.0, distortion=0.7)
        pts = random_points(400_000, half=200.0, seed=14)
        luminance = eval_at(tex, pts) @ np.array([0.212671, 0.715160, 0.072169])
        assert abs(float(tex.mean()[0]) - luminance.mean()) < 0.01, function


def test_eval_1_is_luminance_and_eval_3_is_eval(llvm):
    tex = texture(octaves=5, ramp="0 0 0, 0.2 0.9 0.4")
    si = dr.zeros(mi.SurfaceInteraction3f, 100)
    si.p = mi.Point3f(dr.linspace(mi.Float, -2, 2, 100), 0.3, -0.7)
    np.testing.assert_allclose(np.array(tex.eval_1(si)), np.array(mi.luminance(tex.eval(si))), atol=1e-7)
    np.testing.assert_array_equal(np.array(tex.eval_3(si)), np.array(tex.eval(si)))


def test_eval_1_grad_matches_the_analytic_derivative(llvm):
    # Without noise the luminance is L(t(x)) with t = |sin(π·period·scale·x)|.
    period, scale = 0.7, 1.3
    tex = texture(distortion=0.0, period=period, scale=scale, ramp="0 0 0, 1 1 1")
    x = np.linspace(0.05, 0.6, 50)                 # away from the kink of |sin| at x = 0
    si = dr.zeros(mi.SurfaceInteraction3f, len(x))
    si.p = mi.Point3f(mi.Float(x), 0.2, 0.1)
    si.dp_du, si.dp_dv = mi.Vector3f(2, 0, 0), mi.Vector3f(0, 0, 1)   # u runs along x at twice the speed
    grad = np.array(tex.eval_1_grad(si))
    k = np.pi * period * scale
    dt_dx = k * np.cos(k * x) * np.sign(np.sin(k * x))
    np.testing.assert_allclose(grad[0], 2 * dt_dx, rtol=2e-3, atol=2e-3)
    np.testing.assert_allclose(grad[1], 0, atol=2e-3)


def test_loads_from_xml_with_every_parameter(variant):
    scene = mi.load_string("""
        <scene version="3.0.0">
          <texture type="marble" id="m">
            <float name="scale" value="2"/> <float name="period" value="0.5"/>
            <float name="distortion" value="1.5"/> <integer name="octaves" value="3"/>
            <string name="function" value="sine"/> <string name="axis" value="z"/>
            <boolean name="turbulence" value="true"/>
            <string name="ramp" value="1 0 0, 0 1 0, #0000ff"/>
            <transform name="to_world"><translate x="1"/></transform>
          </texture>
        </scene>""")
    params = mi.traverse(mi.load_string("""
        <texture version="3.0.0" type="marble">
            <float name="scale" value="2"/> <integer name="octaves" value="3"/>
            <string name="ramp" value="1 0 0, 0 1 0, #0000ff"/>
        </texture>"""))
    assert "Marble" in str(scene)
    assert params["octaves"] == 3 or int(params["octaves"][0]) == 3
    ramp = np.array(params["ramp"]).reshape(3, -1) if dr.is_jit_v(mi.Float) else None
    if ramp is not None:
        np.testing.assert_allclose(ramp, np.eye(3))


def scene_with(bsdf, integrator=None, res=16):
    return mi.load_dict({
        "type": "scene",
        "integrator": integrator or {"type": "path", "max_depth": 3},
        "sensor": {"type": "perspective", "fov": 30,
                   "to_world": mi.ScalarTransform4f().look_at([0, 0, 5], [0, 0, 0], [0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": res, "height": res, "rfilter": {"type": "box"}},
                   "sampler": {"type": "stratified", "sample_count": 1, "jitter": False}},
        "sphere": {"type": "sphere", "radius": 1.0, "bsdf": bsdf},
        "light": {"type": "constant", "radiance": 1.0},
    })


@pytest.mark.parametrize("bsdf", [
    {"type": "diffuse", "reflectance": {"type": "marble", "scale": 2.0}},
    {"type": "roughplastic", "diffuse_reflectance": {"type": "marble", "scale": 2.0},
     "specular_reflectance": {"type": "marble", "ramp": "0.1 0.1 0.1, 0.5 0.5 0.5"}},
    {"type": "principled", "base_color": {"type": "marble", "scale": 2.0}},
])
def test_renders_under_standard_bsdfs(jit_variant, bsdf):
    image = np.array(mi.render(scene_with(bsdf), spp=4))
    centre = image[4:12, 4:12]
    assert np.all(np.isfinite(image))
    assert centre.mean() > 0.05 and centre.std() > 1e-3   # lit, and the marble varies


def test_aov_albedo_is_the_marble_at_the_hit_point(jit_variant):
    params = dict(scale=1.5, period=1.0, distortion=2.0, octaves=6)
    bsdf = {"type": "diffuse", "reflectance": {"type": "marble", **params}}
    scene = scene_with(bsdf, {"type": "aov", "aovs": "a:albedo,p:position"}, res=32)
    image = np.array(mi.render(scene, spp=1)).reshape(-1, 6)
    hit = np.any(image[:, 3:] != 0, axis=1)
    assert hit.sum() > 200
    ref = marble64.colour(image[hit, 3:].astype(np.float64), **params)
    # positions come back rounded to float32 like everything else: same tolerance
    assert np.abs(image[hit, :3] - ref).max() <= COLOUR_TOL


def differentiable_scene():
    return scene_with({"type": "diffuse", "reflectance": {
        "type": "marble", "scale": 1.2, "period": 0.8, "distortion": 1.1, "octaves": 4,
        "ramp": "0.1 0.2 0.3, 0.9 0.6 0.2"}}, {"type": "prb", "max_depth": 2}, res=24)


@pytest.mark.parametrize("key", ["period", "distortion", "scale"])
def test_gradient_matches_central_differences_of_the_image(jit_variant, key):
    scene = differentiable_scene()
    params = mi.traverse(scene)
    name = f"sphere.bsdf.reflectance.{key}"
    x0 = float(params[name][0])

    def render(value, grad=False):
        params[name] = mi.Float(value)
        if grad:
            dr.enable_grad(params[name])
        params.update()
        # The gradient pass samples with seed_grad: the differences use that seed
        # too, so both see the same sample paths and agree up to O(h²) and rounding.
        return mi.render(scene, params, spp=4, seed=1, seed_grad=7) if grad else \
            mi.render(scene, params, spp=4, seed=7)

    dr.backward(dr.mean(render(x0, grad=True), axis=None))
    ad = float(dr.grad(params[name])[0])
    h = 1e-3
    fd = (np.array(render(x0 + h)).mean() - np.array(render(x0 - h)).mean()) / (2 * h)
    assert abs(ad - fd) <= 0.02 * abs(fd) + 1e-4, (ad, fd)
    assert abs(fd) > 1e-3          # the test moves the image at all


def test_ramp_colours_carry_gradients(jit_variant):
    scene = differentiable_scene()
    params = mi.traverse(scene)
    key = "sphere.bsdf.reflectance.ramp"
    dr.enable_grad(params[key])
    params.update()
    dr.backward(dr.mean(mi.render(scene, params, spp=4, seed=0), axis=None))
    grad = np.array(dr.grad(params[key]))
    assert grad.shape == (3, 2) and np.all(np.isfinite(grad)) and np.all(grad > 0)


def compiled_kernels(scene, spp=1):
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        image = mi.render(scene, spp=spp)
        dr.eval(image)
        dr.sync_thread()
        return {k["hash"] for k in dr.kernel_history() if k.get("type") == dr.KernelType.JIT}


def test_sweeping_period_and_distortion_reuses_the_compiled_kernel(jit_variant):
    scene = scene_with({"type": "diffuse", "reflectance": {"type": "marble"}})
    params = mi.traverse(scene)
    first = compiled_kernels(scene)
    for key, value in [("period", 2.5), ("distortion", 0.3), ("scale", 4.0)]:
        params[f"sphere.bsdf.reflectance.{key}"] = value
        params.update()
        assert compiled_kernels(scene) == first, key
    # while an octave change is structural: a new kernel (and this test can fail)
    params["sphere.bsdf.reflectance.octaves"] = 3
    params.update()
    assert compiled_kernels(scene) != first


@pytest.mark.parametrize("bad, words", [
    ({"octaves": 65}, ["octaves", "65"]),
    ({"octaves": -1}, ["octaves", "-1"]),
    ({"ramp": ""}, ["ramp"]),
    ({"ramp": "1 0, 0 1 0"}, ["ramp", "1 0"]),
    ({"ramp": "1 0 nan"}, ["ramp", "non-finite"]),
    ({"scale": math.inf}, ["scale", "inf"]),
    ({"period": math.nan}, ["period", "nan"]),
    ({"function": "tan"}, ["function", "tan"]),
    ({"axis": "w"}, ["axis", "w"]),
    ({"scale": 0.0}, ["scale", "> 0"]),
    ({"scale": -1.0}, ["scale", "-1"]),
    ({"to_world": "singular"}, ["to_world", "singular"]),
    ({"turbulence": "false"}, ["turbulence", "true or false"]),   # a word is not a boolean
    ({"octaves": 8.0}, ["octaves", "integer"]),
])
def test_invalid_parameters_name_the_parameter_and_value(variant, bad, words):
    if bad.get("to_world") == "singular":
        bad = {"to_world": mi.ScalarTransform4f().scale([1.0, 0.0, 1.0])}
    with pytest.raises(Exception) as err:
        texture(**bad)
    for word in words:
        assert word in str(err.value)


def test_parameters_checked_after_traverse_updates(llvm):
    tex = texture(octaves=5)
    params = mi.traverse(tex)
    before = eval_at(tex, random_points(50, seed=15))
    params["octaves"] = 70
    with pytest.raises(ParameterError, match="octaves must be in 0..64, found 70"):
        params.update()
    params["period"] = float("nan")
    with pytest.raises(ParameterError, match="period must be a finite number, found nan"):
        params.update()
    # the texture went back to its last valid values
    assert tex.octaves == 5 and float(tex.period[0]) == 1.0
    np.testing.assert_array_equal(eval_at(tex, random_points(50, seed=15)), before)


def test_xml_ramps_as_rgb_colours(variant):
    one = mi.load_string('<texture version="3.0.0" type="marble">'
                         '<rgb name="ramp" value="0.2 0.4 0.6"/></texture>')
    np.testing.assert_allclose(eval_at(one, random_points(5)), [[0.2, 0.4, 0.6]] * 5, atol=1e-6)
    two = mi.load_string('<texture version="3.0.0" type="marble"><rgb name="ramp_0" value="1 0 0"/>'
                         '<rgb name="ramp_1" value="0 0 1"/></texture>')
    same = texture(ramp="1 0 0, 0 0 1")
    np.testing.assert_allclose(eval_at(two, random_points(50)), eval_at(same, random_points(50)),
                               atol=1e-6)
    with pytest.raises(Exception, match="without gaps"):
        mi.load_string('<texture version="3.0.0" type="marble"><rgb name="ramp_0" value="1 0 0"/>'
                       '<rgb name="ramp_2" value="0 0 1"/></texture>')


def test_to_world_is_in_traverse_and_edits_apply(llvm):
    moved = mi.load_dict({"type": "marble", "to_world": mi.ScalarTransform4f().translate([0.3, 0, 0])})
    plain = texture()
    pts = random_points(200)
    assert np.abs(eval_at(moved, pts) - eval_at(plain, pts)).max() > 0.05
    params = mi.traverse(moved)
    params["to_world"] = mi.Transform4f()
    params.update()
    np.testing.assert_allclose(eval_at(moved, pts), eval_at(plain, pts), atol=1e-6)
    params["to_world"] = mi.Transform4f().scale([1.0, 0.0, 1.0])
    with pytest.raises(ParameterError, match="singular"):
        params.update()
    np.testing.assert_allclose(eval_at(moved, pts), eval_at(plain, pts), atol=1e-6)   # restored
