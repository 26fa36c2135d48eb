"""A path fit for the GPU (issue 37, item 7). The marble's update reads nothing back:
``params.update()`` of values on the device (an optimiser's, arrays) waits for nothing;
their rules are checked in the kernel (NaN everywhere while one is broken); what they
render equals a texture loaded with the same values. Expressions' updates and means, the
sphere table, likewise; the passes sum samples in float32 with compensation."""

import math
import warnings

import numpy as np
import pytest

import mimarble
from mimarble.parameters import ParameterError

mi, dr = mimarble.mi, mimarble.dr

RAMP = "0.95 0.92 0.85, 0.5 0.5 0.5, 0.12 0.08 0.06"


def points(n=300, seed=3):
    rng = np.random.default_rng(seed)
    p = rng.uniform(-2.0, 2.0, (n, 3))
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.p = mi.Point3f(*(mi.Float(p[:, k]) for k in range(3)))
    return si


def colours(texture, si):
    return np.array(texture.eval(si)).T.astype(np.float64)


def on_device(value: float):
    """``value`` as a computed Dr.Jit value: no literal the host could read for free."""
    return dr.opaque(mi.Float, value) + dr.zeros(mi.Float, 1)


def test_an_optimisers_update_waits_for_nothing(llvm):
    """Notebook 02's update — period, distortion and the ramp, differentiated, computed on
    the device — under Dr.Jit's ForbidSynchronization: any wait raises. (Before: the
    update read every value back, the ramp through numpy().)"""
    texture = mi.load_dict({"type": "marble", "octaves": 5, "ramp": RAMP})
    params = mi.traverse(texture)
    period, distortion = on_device(1.35), on_device(2.25)
    vein = mi.Color3f(0.5, 0.5, 0.5)
    dr.enable_grad(period, distortion, vein)
    known = mi.Color3f(params["ramp"])
    free = dr.arange(mi.UInt32, 3) == 1
    dr.eval(period, distortion, vein, known)
    with dr.scoped_set_flag(dr.JitFlag.ForbidSynchronization, True):
        params["period"], params["distortion"] = period, distortion
        params["ramp"] = dr.select(free, vein, known)
        params.update()
        dr.eval(texture.eval(points(64)))      # the kernel runs, nothing is read


@pytest.mark.parametrize("name, value, rule", [
    ("scale", -1.0, "scale must be > 0"),
    ("period", float("nan"), "period must be a finite number"),
    ("gain", 1.5, "gain must be > 0 and < 1"),
    ("lacunarity", 0.5, "lacunarity must be > 1"),
])
def test_a_device_edit_that_breaks_a_rule_is_nan_everywhere(llvm, name, value, rule):
    texture = mi.load_dict({"type": "marble", "ramp": RAMP})
    si = points()
    before = colours(texture, si)
    params = mi.traverse(texture)
    params[name] = on_device(value)
    params.update()                             # not checked here: nothing is read
    assert np.isnan(colours(texture, si)).all()
    with pytest.raises(ParameterError, match=rule):
        texture.check_values()
    params[name] = float(mi.load_dict({"type": "marble"}).editable[name][0])
    params.update()                             # a literal again: checked on the host
    np.testing.assert_array_equal(colours(texture, si), before)


def test_a_non_finite_ramp_colour_on_the_device_is_nan_everywhere(llvm):
    texture = mi.load_dict({"type": "marble", "ramp": RAMP})
    params = mi.traverse(texture)
    params["ramp"] = mi.Color3f([0.1, np.inf, 0.3], [0.2, 0.2, 0.2], [0.3, 0.3, 0.3])
    params.update()
    assert np.isnan(colours(texture, points())).all()
    with pytest.raises(ParameterError, match="non-finite"):
        texture.check_values()


def test_a_literal_edit_is_still_refused_at_update(llvm):
    texture = mi.load_dict({"type": "marble", "ramp": RAMP})
    params = mi.traverse(texture)
    params["scale"] = -1.0
    with pytest.raises(ParameterError, match="scale must be > 0, found -1.0"):
        params.update()


def test_device_edits_render_as_a_texture_loaded_with_those_values(llvm):
    """Every in-place value and to_world set as computed values: the colours of a texture
    loaded with the same numbers (tolerance 0: the budget's octaves, which a value on the
    device always keeps, are then the same). gain and lacunarity's constants are derived
    on the device in single precision: within 1e-5."""
    values = {"scale": 1.7, "period": 2.1, "distortion": 1.4, "gain": 0.55,
              "lacunarity": 2.3}
    ramp = [(0.9, 0.1, 0.2), (0.3, 0.6, 0.1), (0.05, 0.2, 0.8)]
    moved = mi.ScalarTransform4f().translate([0.3, -0.2, 0.1]) @ \
        mi.ScalarTransform4f().rotate([0, 0, 1], 30.0)
    fresh = mi.load_dict({"type": "marble", "tolerance": 0.0, "octaves": 6, "to_world": moved,
                          "ramp": ", ".join(" ".join(map(str, c)) for c in ramp), **values})
    edited = mi.load_dict({"type": "marble", "tolerance": 0.0, "octaves": 6, "ramp": RAMP})
    params = mi.traverse(edited)
    for name, value in values.items():
        params[name] = on_device(value)
    params["ramp"] = mi.Color3f(*(mi.Float(list(column)) for column in zip(*ramp)))
    matrix = mi.Matrix4f(np.array(moved.matrix, dtype=np.float64).reshape(4, 4).tolist())
    params["to_world"] = mi.Transform4f(matrix + dr.zeros(mi.Matrix4f, 1))
    params.update()
    assert edited.spectrum.gain_value is None          # held on the device only
    si = points(500, seed=11)
    np.testing.assert_allclose(colours(edited, si), colours(fresh, si), atol=1e-5)
    assert edited.max() == pytest.approx(0.9)           # read when asked


def sphere_scene(centre=(1.0, 2.0, 3.0)):
    return mi.load_dict({"type": "scene",
                         "small": {"type": "sphere", "center": list(centre), "radius": 0.5},
                         "floor": {"type": "sphere", "center": [0, -1e4, 0], "radius": 1e4}})


def looked_up(table, scene):
    shapes = mi.ShapePtr([s for s in scene.shapes()])
    centre, radius = table.lookup(shapes)
    return np.array(centre).T.tolist(), np.array(radius).tolist()


def test_the_sphere_table_holds_each_spheres_centre_and_radius(llvm):
    """Its columns are the spheres' centres and radii as the scene gives them, looked up
    by the hit shape's id."""
    from mimarble.mitsuba.plugins.sphere_hit import SphereTable
    scene = sphere_scene()
    table = SphereTable(scene)
    centres, radii = looked_up(table, scene)
    assert centres == [[1.0, 2.0, 3.0], [0.0, -1e4, 0.0]] and radii == [0.5, 1e4]
    assert table.large                         # |c| + r = 2·10⁴ > 419


def test_an_unfrozen_trace_reuses_the_table_until_a_sphere_moves(llvm):
    from mimarble.mitsuba.plugins.sphere_hit import SphereTable
    scene = sphere_scene()
    first = SphereTable.for_trace(scene)
    assert SphereTable.for_trace(scene) is first
    params = mi.traverse(scene)
    params["small.to_world"] = mi.ScalarTransform4f().translate([4.0, 5.0, 6.0]).scale(0.25)
    params.update()
    moved = SphereTable.for_trace(scene)
    assert moved is not first
    centres, radii = looked_up(moved, scene)
    assert centres[0] == [4.0, 5.0, 6.0] and radii[0] == 0.25
    SphereTable.forget(scene)


def test_an_expressions_update_and_mean_read_nothing_back(llvm):
    """An edit of a marble inside a sum: params.update() and mean() (which Mitsuba's BSDFs
    call when their parameters change) wait for nothing, and the mean is the edited
    marble's mean plus the colour's luminance, as a marble loaded with that ramp gives."""
    from mimarble import scene as S
    from mimarble.mitsuba import texture_dict
    red = (0.8, 0.1, 0.1)
    expression = mi.load_dict(texture_dict(S.Add((S.MarbleChannel(octaves=6),
                                                  S.ColorChannel(red)))))
    expression.mean()                            # at load: made once (may read)
    params = mi.traverse(expression)
    key = next(k for k in params.keys() if k.endswith("ramp"))
    ramp = [(0.2, 0.3, 0.4), (0.9, 0.5, 0.1)]
    dr.eval(new := mi.Color3f(*(mi.Float(list(column)) for column in zip(*ramp))))
    with dr.scoped_set_flag(dr.JitFlag.ForbidSynchronization, True):
        params[key] = new
        params.update()
        mean = expression.mean()
        dr.eval(mean)
    fresh = mi.load_dict({"type": "marble", "ramp": "0.2 0.3 0.4, 0.9 0.5 0.1"})
    red_luminance = 0.212671 * red[0] + 0.715160 * red[1] + 0.072169 * red[2]
    assert float(mean[0]) == pytest.approx(float(fresh.mean()[0]) + red_luminance, rel=1e-5)


def test_compensated_sums_hold_the_exact_sum(llvm):
    """Runs of float32 values of mixed sizes and signs: the compensated sum is the exact
    sum (math.fsum of the same numbers) to 2⁻⁴⁰ of Σ|x|, where float32's plain running
    sum is far off."""
    from mimarble.mitsuba.rendering.passes import compensated_block_sum
    rng = np.random.default_rng(5)
    block, runs = 64, 500
    values = (rng.standard_normal((runs, block)) * 10.0 ** rng.integers(-6, 4, (runs, block))
              ).astype(np.float32)
    ours = np.array(compensated_block_sum(mi.Float(values.ravel()), block,
                                          dr.opaque(mi.UInt32, block)))
    exact = np.array([math.fsum(map(float, run)) for run in values])
    scale = np.abs(values.astype(np.float64)).sum(axis=1)
    assert (np.abs(ours - exact) <= 2.0 ** -40 * scale).all()
    plain = np.cumsum(values, axis=1, dtype=np.float32)[:, -1].astype(np.float64)
    assert (np.abs(plain - exact) > 2.0 ** -30 * scale).mean() > 0.5


@pytest.mark.parametrize("block", [1, 3, 4, 16])
def test_compensated_sums_of_huge_and_non_finite_samples_are_the_float64_sums(llvm, block):
    """Samples up to float32's largest, ±∞ and NaN: the sum is float64's (math.fsum of the
    same numbers; ∞ and NaN where float64 gives them), never a NaN made by the
    compensation (∞ − ∞) nor an overflow of the float32 running total."""
    from mimarble.mitsuba.rendering.passes import compensated_block_sum
    rng = np.random.default_rng(11)
    big = np.float32(3.4e38)
    runs = [np.full(block, big), np.full(block, -big), rng.uniform(-1, 1, block) * big,
            np.r_[np.full(block - 1, 1.0), np.inf], np.r_[np.full(block - 1, big), -np.inf],
            np.r_[np.full(block - 1, 2.0), np.nan], rng.standard_normal(block)]
    values = np.array(runs, dtype=np.float32)
    for opaque in (None, dr.opaque(mi.UInt32, block)):
        ours = np.array(compensated_block_sum(mi.Float(values.ravel()), block, opaque))
        for run, got in zip(values, ours):
            as_double = run.astype(np.float64)
            expected = math.fsum(as_double) if np.isfinite(as_double).all() \
                else float(np.sum(as_double))
            if np.isnan(expected):
                assert np.isnan(got)
            else:
                assert got == pytest.approx(expected, rel=1e-12, abs=0.0), (run, got)


@pytest.mark.parametrize("block", [1, 2])
def test_a_compensated_sum_of_negative_zeros_is_positive_zero(llvm, block):
    """0 + (−0) + … is +0 in the loop's arithmetic; a run of one sample (no loop) gives it
    too, not the sample's −0."""
    from mimarble.mitsuba.rendering.passes import compensated_block_sum
    values = np.full(3 * block, -0.0, np.float32)
    for opaque in (None, dr.opaque(mi.UInt32, block)):
        ours = np.array(compensated_block_sum(mi.Float(values), block, opaque))
        assert np.array_equal(ours, np.zeros(3)) and not np.signbit(ours).any()


@pytest.mark.parametrize("block", [2, 8, 72])
def test_compensated_sums_find_each_runs_extremes_with_the_sum_unchanged(llvm, block):
    """``extremes_of`` (an adaptive round's shapes and colours): each run's least and largest
    value of every array, as NumPy finds them, and the sum bit for bit the one without."""
    from mimarble.mitsuba.rendering.passes import compensated_block_sum
    rng = np.random.default_rng(block)
    runs = 300
    values = rng.standard_normal((runs, 3, block)).astype(np.float32)
    shapes = rng.integers(0, 5, (runs, block)).astype(np.uint32)
    colour = mi.Color3f(*(mi.Float(values[:, c].ravel()) for c in range(3)))
    opaque = dr.opaque(mi.UInt32, block)
    alone = compensated_block_sum(colour, block, opaque)
    total, ((least, most), (low, high)) = compensated_block_sum(
        colour, block, opaque, extremes_of=(mi.UInt32(shapes.ravel()), colour))
    for c in range(3):
        assert np.array_equal(np.array(total[c]), np.array(alone[c]))
        assert np.array_equal(np.array(low[c]), values[:, c].min(axis=1))
        assert np.array_equal(np.array(high[c]), values[:, c].max(axis=1))
    assert np.array_equal(np.array(least), shapes.min(axis=1))
    assert np.array_equal(np.array(most), shapes.max(axis=1))


def test_a_runs_extremes_skip_nan_samples_as_numpys_nan_extremes_do(llvm):
    """A NaN sample takes no part in its run's least and largest colour (NumPy's nanmin /
    nanmax; a run of NaNs only keeps the range's ends, +∞ and −∞), on every back end alike."""
    from mimarble.mitsuba.rendering.passes import compensated_block_sum
    block = 4
    values = np.array([[1.0, np.nan, 2.0, -3.0],      # one NaN among numbers
                       [np.nan, 5.0, np.nan, 4.0],
                       [np.nan] * 4,                  # nothing but NaN
                       [0.5, 0.25, 0.75, 1.0]], np.float32)
    colour = mi.Color3f(*(mi.Float(values.ravel()) for _ in range(3)))
    _, ((low, high),) = compensated_block_sum(colour, block, extremes_of=(colour,))
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)     # nanmin of an all-NaN run
        expected_low = np.where(np.isnan(values).all(axis=1), np.inf, np.nanmin(values, axis=1))
        expected_high = np.where(np.isnan(values).all(axis=1), -np.inf,
                                 np.nanmax(values, axis=1))
    for c in range(3):
        assert np.array_equal(np.array(low[c]), expected_low)
        assert np.array_equal(np.array(high[c]), expected_high)


def test_the_kernel_that_traces_the_samples_computes_in_float32(llvm):
    """The pass's widest kernel (every sample) holds no float64 operation (before: each
    sample's radiance was converted to float64 for the sums there)."""
    from mimarble import scene as S
    from mimarble.mitsuba.rendering.render import render_in_passes
    from mimarble.scene.edits import resized
    scene = S.load("scenes/fig11a.scene")
    loaded = mi.load_dict(mimarble.to_mitsuba(resized(scene, 16), spp=4))
    render_in_passes(loaded, 4)
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        render_in_passes(loaded, 4)
        kernels = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    widest = max(kernels, key=lambda k: k["size"])
    assert widest["size"] == 16 * 16 * 4 and "double" not in widest["ir"].getvalue()


def test_a_media_update_waits_for_nothing_and_a_broken_scale_on_the_device_is_nan(llvm):
    """marble_medium: a scale computed on the device is not read at the update (before:
    scale and the bound read back); a negative one makes the medium's coefficients NaN —
    volpath's paths through it NaN (under JitFlag.Debug, where volpath's NaN handling
    ends them, 0: never the valid image) —, where a literal -1 is still refused."""
    from mimarble.mitsuba.plugins.marble_medium import MarbleMediumError
    medium = {"type": "marble_medium", "albedo": {"type": "marble", "ramp": RAMP},
              "density": {"type": "marble", "ramp": RAMP}}
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "volpath", "max_depth": 64},
        "sensor": {"type": "perspective", "fov": 30,
                   "to_world": mi.ScalarTransform4f().look_at([0, 0, 5], [0, 0, 0], [0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 16, "height": 16},
                   "sampler": {"type": "independent", "sample_count": 4}},
        "sky": {"type": "constant"},
        "sphere": {"type": "sphere", "bsdf": {"type": "null"}, "interior": medium}})
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("interior_medium.scale"))
    before = np.array(mi.render(scene, spp=4))
    centre = before[6:10, 6:10]
    assert np.isfinite(before).all() and centre.mean() < 0.99 * before[0, 0].mean()
    with dr.scoped_set_flag(dr.JitFlag.ForbidSynchronization, True):
        params[key] = on_device(-1.0)
        params.update()
    medium_object = next(n for n in params.hierarchy if type(n).__name__ == "MarbleMedium")
    mei = dr.zeros(mi.MediumInteraction3f, 3)
    mei.p = mi.Point3f([0.0, 0.1, -0.2], [0.0, 0.3, 0.1], [0.0, -0.4, 0.2])
    for sigma in medium_object.get_scattering_coefficients(mei, True):
        assert np.isnan(np.array(sigma)).all()
    broken = np.array(mi.render(scene, spp=4))[6:10, 6:10]
    assert np.isnan(broken).all() or (dr.flag(dr.JitFlag.Debug) and (broken == 0).all())
    params[key] = -1.0
    with pytest.raises(MarbleMediumError, match="scale=-1.0 must be a finite number > 0"):
        params.update()


RAMP_A = ((0.95, 0.92, 0.85), (0.5, 0.5, 0.5), (0.12, 0.08, 0.06))
RAMP_B = ((0.9, 0.1, 0.2), (0.3, 0.6, 0.1), (0.05, 0.2, 0.8))


def colour3(ramp):
    """A ramp as the Color3f mi.traverse holds: not a literal, so "on the device"."""
    return mi.Color3f(*(mi.Float(list(column)) for column in zip(*ramp)))


def whitted_dict(ramp=RAMP_A):
    from mimarble import scene as S
    scene = S.Scene(image=S.Image(16, 16), camera=S.Camera(eye=(0, 0, 5)),
                    lights=(S.Light((4, 4, 4)),),
                    materials={"m": S.Material("m", diffuse=S.MarbleChannel(
                        octaves=20, distortion=2.0, ramp=ramp))},
                    spheres=(S.Sphere("m"),))
    return mimarble.to_mitsuba(scene, spp=1)


def test_a_ramp_the_host_holds_edited_and_put_back_renders_as_a_fresh_load(llvm):
    """Whitted mode: a ramp written through mi.traverse is never a literal, so it counts as
    on the device (every octave evaluated) unless the writer tells the marble the values it
    wrote (``Marble.hold``): edited and put back so, it renders the bits it had when loaded
    (the error budget's octaves). A value computed after it is not taken for the told one."""
    scene = mi.load_dict(whitted_dict())
    fresh = mimarble.render(scene)
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith(".ramp"))
    marble = next(n for n in params.hierarchy if type(n).__name__ == "Marble")
    budget = marble.octaves_evaluated
    assert budget < 20
    for ramp in (RAMP_B, RAMP_A):
        params[key] = colour3(ramp)
        marble.hold("ramp", ramp)
        params.update()
        assert marble.octaves_evaluated < 20
    assert marble.octaves_evaluated == budget
    np.testing.assert_array_equal(mimarble.render(scene), fresh)
    params[key] = colour3(RAMP_A)                # the same numbers, not told: on the device
    params.update()
    assert marble.octaves_evaluated == 20
    marble.parameters_changed()                  # every key: still not the told one
    assert marble.octaves_evaluated == 20


def path_dict():
    marble = {"type": "marble", "octaves": 6, "ramp": ", ".join(
        " ".join(map(str, c)) for c in RAMP_A)}
    return {"type": "scene", "integrator": {"type": "path"},
            "sensor": {"type": "perspective", "fov": 30,
                       "to_world": mi.ScalarTransform4f().look_at([0, 0, 6], [0, 0, 0],
                                                                   [0, 1, 0]),
                       "film": {"type": "hdrfilm", "width": 16, "height": 16},
                       "sampler": {"type": "independent", "sample_count": 4}},
            "light": {"type": "point", "position": [4, 4, 6],
                      "intensity": {"type": "rgb", "value": 60.0}},
            # Light from everywhere: paths sampled by the BSDF (its lobe chosen by the
            # diffuse mean) reach it.
            "sky": {"type": "constant", "radiance": {"type": "rgb", "value": 0.5}},
            "sphere": {"type": "sphere", "bsdf": {
                "type": "roughplastic", "diffuse_reflectance": {
                    "type": "channel_expression", "op": "multiply", "operand_0": marble,
                    "operand_1": {**marble, "period": 3.0, "axis": "y"}}}}}


def test_an_expression_edited_and_put_back_renders_as_a_fresh_load_in_path_mode(llvm):
    """roughplastic weighs its sampling by its diffuse texture's mean(), asked again at
    every update of a texture below it: an expression's mean is one definition whatever
    the edits before (the operands' means combined, evaluated), so a period edited on the
    device and put back renders the bits the scene had when loaded (before: sampled at
    load, combined after an edit). (The same scene: another loaded beside it has other
    instance ids in the traced code, and mi.render's bits may differ by an ulp.) Compared
    within a few float32 ulps: in a whole suite's process the two renders have differed by
    up to 9e-8 (2026-12-04, Zen 4, --jit-debug; the test alone gave the same bits), while a
    mean sampled at load instead of combined moves the lobe choice and the image by far more."""
    scene = mi.load_dict(path_dict())
    fresh = np.array(mi.render(scene, spp=4, seed=0))
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("operand_1.period"))
    for value in (on_device(1.7), 3.0):
        params[key] = value
        params.update()
    np.testing.assert_allclose(np.array(mi.render(scene, spp=4, seed=0)), fresh,
                               rtol=2e-6, atol=1e-7)
