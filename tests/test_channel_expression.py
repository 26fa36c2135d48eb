"""Channel expressions on the Mitsuba side: the ``channel_expression`` texture."""

import dataclasses

import numpy as np
import pytest

import mimarble
from mimarble import scene as S
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering.render import render_in_passes

dr, mi = mimarble.dr, mimarble.mi

RED, BLUE = S.ColorChannel((0.8, 0.1, 0.1)), S.ColorChannel((0.1, 0.2, 0.9))
MARBLE = S.MarbleChannel(octaves=6)
OTHER_MARBLE = S.MarbleChannel(octaves=12, period=3.0, ramp=((0, 0, 0), (1, 1, 1)))


def texture(channel):
    return mi.load_dict(mimarble.mitsuba.texture_dict(channel))


def points(n=2000, seed=0):
    pts = np.random.default_rng(seed).uniform(-3, 3, (n, 3)).astype(np.float32)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.p = mi.Point3f(*(mi.Float(pts[:, k]) for k in range(3)))
    si.uv = mi.Point2f(mi.Float(np.linspace(0, 1, n, dtype=np.float32)), mi.Float(0.3))
    return si


def colour(tex, si):
    return np.array(tex.eval(si)).T


@pytest.mark.parametrize("channel, expected", [
    (S.Add((RED, BLUE)), lambda r, b, m: r + b),
    (S.Multiply((RED, MARBLE)), lambda r, b, m: r * m),
    (S.Add((MARBLE, MARBLE, RED)), lambda r, b, m: 2 * m + r),
    (S.Mix(RED, BLUE, 0.25), lambda r, b, m: 0.75 * r + 0.25 * b),
    (S.Mix(RED, BLUE, MARBLE), lambda r, b, m: r * (1 - m) + b * m),
    (S.Mix(MARBLE, BLUE, S.ColorChannel((0.0, 0.5, 1.0))), lambda r, b, m: m * [1, .5, 0] + b * [0, .5, 1]),
])
def test_operators_combine_their_operands_componentwise(jit_variant, channel, expected):
    si = points()
    m = colour(texture(MARBLE), si)
    r, b = np.array(RED.rgb), np.array(BLUE.rgb)
    np.testing.assert_allclose(colour(texture(channel), si),
                               np.broadcast_to(expected(r, b, m), m.shape), atol=2e-6)


def test_nested_expressions_in_the_scalar_variant_too(variant):
    si = dr.zeros(mi.SurfaceInteraction3f, 1) if dr.is_jit_v(mi.Float) else mi.SurfaceInteraction3f()
    si.p = mi.Point3f(0.3, -0.2, 0.7)
    nested = S.Multiply((S.Add((RED, BLUE)), S.Mix(RED, BLUE, 0.5)))
    expected = (np.array(RED.rgb) + BLUE.rgb) * (0.5 * np.array(RED.rgb) + 0.5 * np.array(BLUE.rgb))
    np.testing.assert_allclose(np.ravel(np.array(texture(nested).eval(si))), expected, rtol=1e-6)


def render_kernel_operations(channel, size=8):
    """Operations in the render kernel of a one-sphere scene whose diffuse is ``channel``."""
    scene = S.Scene(image=S.Image(size, size), camera=S.Camera(eye=(0, 0, 5)),
                    lights=(S.Light((4, 4, 4)),),
                    materials={"m": S.Material("m", diffuse=channel)}, spheres=(S.Sphere("m"),))
    mitsuba_scene = mi.load_dict(to_mitsuba(scene, spp=1))
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        render_in_passes(mitsuba_scene, 1)
        kernels = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    return max(k["operation_count"] for k in kernels)


def test_what_is_not_needed_is_not_traced(llvm):
    marble = render_kernel_operations(MARBLE)
    black = render_kernel_operations(S.ColorChannel((0.0, 0.0, 0.0)))
    assert marble > black + 300          # the noise is hundreds of operations
    # A product with a constant 0, a mix whose weight is 0 or 1, constants folded:
    assert render_kernel_operations(S.Multiply((S.ColorChannel((0, 0, 0)), MARBLE))) <= black + 5
    assert render_kernel_operations(S.Mix(MARBLE, OTHER_MARBLE, 0.0)) <= marble + 5
    assert render_kernel_operations(S.Mix(OTHER_MARBLE, MARBLE, 1.0)) <= marble + 5
    assert render_kernel_operations(S.Add((RED, BLUE, S.Multiply((RED, BLUE))))) <= black + 5


def test_equal_operands_are_evaluated_once(llvm):
    once = render_kernel_operations(MARBLE)
    # The same marble three times (a sum, and the weight of a mix of it with itself).
    thrice = render_kernel_operations(S.Add((MARBLE, S.Mix(MARBLE, RED, MARBLE))))
    assert thrice <= once + 30, (once, thrice)


def test_mean_is_the_mean_luminance_linear_where_it_can_be_sampled_where_not(llvm):
    marble_mean = float(np.array(texture(MARBLE).mean())[0])
    red_luminance = 0.212671 * 0.8 + 0.715160 * 0.1 + 0.072169 * 0.1
    added = float(np.array(texture(S.Add((MARBLE, RED))).mean())[0])
    assert added == pytest.approx(marble_mean + red_luminance, rel=1e-5)
    grey = S.ColorChannel((0.5, 0.5, 0.5))
    assert float(np.array(texture(S.Multiply((grey, MARBLE))).mean())[0]) == \
        pytest.approx(0.5 * marble_mean, rel=1e-5)
    # A product of two marbles: the mean of the product over many points.
    product = texture(S.Multiply((MARBLE, OTHER_MARBLE)))
    si = points(200_000, seed=3)
    direct = float(np.mean(np.array(product.eval_1(si))))
    assert float(np.array(product.mean())[0]) == pytest.approx(direct, rel=0.03)


def test_parameters_are_reachable_and_refolded(llvm):
    tex = texture(S.Multiply((S.ColorChannel((0.0, 0.0, 0.0)), MARBLE)))
    params = mi.traverse(tex)
    assert "operand_0.value" in params and "operand_1.period" in params
    si = points(100)
    assert np.all(colour(tex, si) == 0)
    params["operand_0.value"] = mi.Color3f(1.0, 1.0, 1.0)
    params.update()
    np.testing.assert_allclose(colour(tex, si), colour(texture(MARBLE), si), atol=1e-6)


def test_weight_gradient_reaches_a_number_weight(llvm):
    tex = texture(S.Mix(RED, BLUE, 0.25))
    params = mi.traverse(tex)
    dr.enable_grad(params["weight"])
    params.update()
    value = dr.sum(tex.eval(points(10)).x)
    dr.backward(value)
    assert float(np.array(dr.grad(params["weight"]))[0]) == pytest.approx(10 * (0.1 - 0.8), rel=1e-5)


def test_eval_1_grad_of_a_sum_is_its_operands_and_of_a_product_a_difference(llvm):
    si = points(500, seed=5)
    si.dp_du, si.dp_dv = mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0)
    m = texture(MARBLE)
    summed = texture(S.Add((MARBLE, RED)))
    np.testing.assert_allclose(np.array(summed.eval_1_grad(si)), np.array(m.eval_1_grad(si)), atol=1e-6)
    scaled = texture(S.Multiply((S.ColorChannel((0.5, 0.5, 0.5)), MARBLE)))
    exact = 0.5 * np.array(m.eval_1_grad(si))
    numeric = np.array(scaled.eval_1_grad(si))
    close = np.abs(numeric - exact) <= 0.05 * np.abs(exact) + 0.02
    assert close.mean() > 0.97           # central differences, away from the ramp's kinks


@pytest.mark.parametrize("props, words", [
    ({"op": "divide"}, "op='divide'"),
    ({"op": "add", "operand_0": {"type": "rgb", "value": 1.0}}, "two or more"),
    ({"op": "add", "operand_0": {"type": "rgb", "value": 1.0},
      "operand_2": {"type": "rgb", "value": 1.0}}, "without gaps"),
    ({"op": "mix", "operand_0": {"type": "rgb", "value": 1.0},
      "operand_1": {"type": "rgb", "value": 0.0}}, "needs a weight"),
    ({"op": "add", "operand_0": {"type": "rgb", "value": 1.0},
      "operand_1": {"type": "rgb", "value": 0.0}, "weight": 0.5}, "belongs to mix"),
])
def test_invalid_expressions_are_refused_in_one_sentence(llvm, props, words):
    with pytest.raises(Exception, match=words.replace("(", r"\(")):
        mi.load_dict({"type": "channel_expression", **props})


def test_usable_from_xml(llvm):
    tex = mi.load_string("""<texture type="channel_expression" version="3.0.0">
        <string name="op" value="multiply"/>
        <rgb name="operand_0" value="1 0.95 0.9"/>
        <texture type="marble" name="operand_1"><integer name="octaves" value="4"/></texture>
    </texture>""")
    si = points(50)
    np.testing.assert_allclose(colour(tex, si),
                               colour(texture(S.MarbleChannel(octaves=4)), si) * [1, 0.95, 0.9],
                               atol=1e-6)


@pytest.mark.parametrize("start", [0.0, 1.0])
def test_a_weight_being_differentiated_is_not_folded_away_at_0_or_1(llvm, start):
    tex = texture(S.Mix(RED, BLUE, start))
    params = mi.traverse(tex)
    dr.enable_grad(params["weight"])
    params.update()
    dr.backward(dr.sum(tex.eval(points(10)).x))
    assert float(np.array(dr.grad(params["weight"]))[0]) == pytest.approx(10 * (0.1 - 0.8), rel=1e-5)


@pytest.mark.parametrize("channel", [
    S.Add((RED, MARBLE, OTHER_MARBLE)),
    S.Multiply((RED, OTHER_MARBLE)),
    S.Mix(MARBLE, BLUE, 0.3),
    S.Mix(MARBLE, BLUE, 1.7),
    S.Mix(RED, OTHER_MARBLE, S.Multiply((OTHER_MARBLE, S.ColorChannel((0.5, 0.5, 0.5))))),
])
def test_max_is_the_bound_of_the_channel_model(variant, channel):
    # max() (made from the operands' held maxima, issue 37 item 2) against the same rules
    # applied to the scene model in float64 (error_budget.channel_bound), and against the
    # colours; a mix whose weight texture stays ≤ 1: the larger side.
    from mimarble.texture import error_budget
    expected = error_budget.channel_bound(channel)
    if isinstance(channel, S.Mix) and not isinstance(channel.weight, float):
        expected = max(error_budget.channel_bound(channel.a), error_budget.channel_bound(channel.b))
    assert texture(channel).max() == pytest.approx(expected, rel=1e-6)
    if dr.is_jit_v(mi.Float):
        assert colour(texture(channel), points()).max() <= expected * (1 + 1e-6)


def test_a_shortcut_is_kept_after_an_unrelated_edit(llvm):
    """A product by a constant 0 and a mix at a weight texture 0 skip their unused operands
    after an update that left the constants' variables as they were (an edit of the other
    operand, here computed on the device); an edit of the constant itself, on the device,
    turns the skipping off (before: any update turned it off for good)."""
    product = texture(S.Multiply((S.ColorChannel((0.0, 0.0, 0.0)), MARBLE)))
    mix = texture(S.Mix(MARBLE, OTHER_MARBLE, S.ColorChannel((0.0, 0.0, 0.0))))
    assert product.zero_product and mix.mix_side == "a"
    for tex in (product, mix):
        params = mi.traverse(tex)
        params["operand_1.period"] = dr.opaque(mi.Float, 2.5) + dr.zeros(mi.Float, 1)
        params.update()
    assert product.zero_product and product._shortcuts()
    assert mix.mix_side == "a" and mix._shortcuts()
    si = points(100)
    assert np.all(colour(product, si) == 0)
    np.testing.assert_array_equal(colour(mix, si), colour(texture(MARBLE), si))
    params = mi.traverse(product)
    params["operand_0.value"] = mi.Color3f(dr.opaque(mi.Float, 0.5) + dr.zeros(mi.Float, 1))
    params.update()
    assert not product.zero_product
    edited = texture(dataclasses.replace(MARBLE, period=2.5))   # its period edited above
    np.testing.assert_allclose(colour(product, si), 0.5 * colour(edited, si), atol=1e-6)
