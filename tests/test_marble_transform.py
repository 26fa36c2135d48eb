"""A marble's pattern transform, ``marble { transform { translate rotate scale } }``: what
each step means (against the float64 reference tracer, which composes its own matrices),
that Mitsuba renders the same image as the reference, and the refusals."""

import math
import pickle

import numpy as np
import pytest

import mimarble
from mimarble import reference
from mimarble import scene as S
from mimarble.tools.compare import image_metrics
from mimarble.reference.marble import marble_color, pattern_matrix, stripe
from mimarble.scene import transforms

MARBLE = 'material "m" {{ diffuse {{ marble {{ {} }} }} }}'
STEPS = (("translate", (0.3, -0.2, 0.7)), ("rotate", (20.0, 35.0, 60.0)),
         ("scale", (1.5, 0.7, 2.0)), ("rotate", (-10.0, 0.0, 5.0)))
POINTS = np.random.default_rng(7).uniform(-2.5, 2.5, (500, 3))


def marble_of(text):
    return S.parse(MARBLE.format(text)).materials["m"].diffuse


def scene_with(channel, size=48):
    return S.Scene(image=S.Image(size, size, samples=4),
                   camera=S.Camera(eye=(0, -9, 0.5), up=(0, 0, 1)),
                   ambient=(0.2, 0.2, 0.2), lights=(S.Light((10, -10, 10)),),
                   materials={"m": S.Material("m", ambient=channel, diffuse=channel,
                                              specular=S.ColorChannel((0.3, 0.3, 0.3)))},
                   spheres=(S.Sphere("m", radius=2.0),))


# --- the language and the model -------------------------------------------------------

def test_steps_are_kept_in_the_order_written_and_scale_takes_one_number():
    m = marble_of("period 2 transform { rotate < 0 0 90 > translate <1, 0, 0> scale 2 "
                  "scale < 1 2 3 > translate < 0 0 1 > }")
    assert m.transform == (("rotate", (0.0, 0.0, 90.0)), ("translate", (1.0, 0.0, 0.0)),
                           ("scale", (2.0, 2.0, 2.0)), ("scale", (1.0, 2.0, 3.0)),
                           ("translate", (0.0, 0.0, 1.0)))
    assert m == S.MarbleChannel(period=2.0, transform=[("rotate", (0, 0, 90)), ("translate", (1, 0, 0)),
                                                       ("scale", 2), ("scale", (1, 2, 3)),
                                                       ("translate", (0, 0, 1))])


def test_no_transform_and_an_empty_one_are_the_identity():
    assert marble_of("transform { }") == marble_of("") == S.MarbleChannel()
    assert S.MarbleChannel().to_world == transforms.IDENTITY


def test_the_order_of_steps_matters():
    moved_then_turned = marble_of("transform { translate < 1 0 0 > rotate < 0 0 90 > }")
    turned_then_moved = marble_of("transform { rotate < 0 0 90 > translate < 1 0 0 > }")
    # Where the pattern's origin goes: M·(0 0 0 1), the last column.
    assert np.allclose(np.array(moved_then_turned.to_world)[:, 3], [0, 1, 0, 1], atol=1e-15)
    assert np.allclose(np.array(turned_then_moved.to_world)[:, 3], [1, 0, 0, 1], atol=1e-15)


def test_rotate_turns_about_x_then_y_then_z():
    together = S.MarbleChannel(transform=[("rotate", (30, 40, 50))]).to_world
    one_by_one = S.MarbleChannel(transform=[("rotate", (30, 0, 0)), ("rotate", (0, 40, 0)),
                                            ("rotate", (0, 0, 50))]).to_world
    assert np.allclose(together, one_by_one, rtol=0, atol=1e-15)


def test_rotate_is_right_handed_about_each_axis():
    for axis, (a, b) in enumerate([(1, 2), (2, 0), (0, 1)]):     # y→z, z→x, x→y
        angles = [0.0, 0.0, 0.0]
        angles[axis] = 90.0
        m = np.array(S.MarbleChannel(transform=[("rotate", angles)]).to_world)
        assert np.allclose(m[:3, a], np.eye(3)[b], atol=1e-15)


def test_the_reference_composes_the_same_matrix_independently():
    assert np.allclose(pattern_matrix(STEPS), S.MarbleChannel(transform=STEPS).to_world,
                       rtol=0, atol=1e-14)


def test_refusals_are_at_their_place():
    def error(text):
        with pytest.raises(S.SceneError) as e:
            marble_of(text)
        return e.value
    e = error("transform { scale < 1 0 1 > }")
    assert (e.column, e.message) == (57, "a transform's scale must not be 0 (it would flatten "
                                         "the pattern), found 0")
    e = error("transform { scale 1e-20 scale 1e-20 }")
    assert e.column == 35 and "too far to invert in single precision" in e.message
    e = error("transform { scale 1e30 scale 1e30 }")
    assert e.column == 35 and "past single precision's range" in e.message
    e = error("transform { translate < 1 2 > }")
    assert e.column == 57 and e.message == "translate (a vector < x y z >) needs 3 numbers, found 2"
    e = error("transform { } transform { }")
    assert e.column == 49 and e.message.startswith("duplicate 'transform' in 'marble' block")
    e = error("transform { spin < 1 2 3 > }")
    assert e.message == ("unknown keyword 'spin' in 'transform' block; allowed: 'translate', "
                         "'rotate' or 'scale'")


def test_the_model_refuses_what_the_parser_refuses():
    with pytest.raises(ValueError, match="translate, rotate or scale, found 'spin'"):
        S.MarbleChannel(transform=[("spin", (1, 2, 3))])
    with pytest.raises(ValueError, match="scale must not be 0"):
        S.MarbleChannel(transform=[("scale", 0)])
    with pytest.raises(ValueError, match="needs 3 numbers"):
        S.MarbleChannel(transform=[("translate", (1, 2))])
    with pytest.raises(TypeError):
        S.MarbleChannel(transform="rotate <0 0 90>")


def test_a_transformed_marble_pickles_and_hashes_by_value():
    m = S.MarbleChannel(transform=STEPS)
    assert pickle.loads(pickle.dumps(m)) == m and hash(m) == hash(S.MarbleChannel(transform=STEPS))
    assert m != S.MarbleChannel()


# --- what each step means (the reference tracer) ----------------------------------------

def test_translate_moves_the_pattern_by_t():
    t = (0.75, -1.25, 2.5)
    moved = S.MarbleChannel(octaves=6, distortion=2.0, transform=[("translate", t)])
    assert np.array_equal(marble_color(POINTS, moved),
                          marble_color(POINTS - np.array(t), S.MarbleChannel(octaves=6, distortion=2.0)))


def test_rotating_x_stripes_90_degrees_about_z_gives_y_stripes():
    # Without noise the stripes alone: sine tells +y from −y (abs_sine would not).
    x_turned = S.MarbleChannel(function="sine", distortion=0.0, period=3.0, axis="x",
                               transform=[("rotate", (0, 0, 90))])
    y = S.MarbleChannel(function="sine", distortion=0.0, period=3.0, axis="y")
    assert np.allclose(stripe(POINTS, x_turned), stripe(POINTS, y), rtol=0, atol=1e-14)


def test_rotate_turns_the_noise_with_the_stripes():
    turned = S.MarbleChannel(octaves=6, distortion=2.0, transform=[("rotate", (0, 0, 90))])
    back = POINTS[:, [1, 0, 2]] * (1, -1, 1)             # R_z(−90°)·p = (y, −x, z)
    assert np.allclose(marble_color(POINTS, turned), marble_color(back, S.MarbleChannel(
        octaves=6, distortion=2.0)), rtol=0, atol=1e-12)


def test_transform_scale_is_povrays_the_inverse_of_the_marbles_own_scale():
    plain = S.MarbleChannel(octaves=6, distortion=2.0, period=1.3)
    both = S.MarbleChannel(octaves=6, distortion=2.0, period=1.3, scale=2.0,
                           transform=[("scale", 2.0)])
    assert np.array_equal(marble_color(POINTS, both), marble_color(POINTS, plain))
    coarser = S.MarbleChannel(octaves=6, distortion=2.0, period=1.3, transform=[("scale", 2.0)])
    assert np.array_equal(marble_color(2 * POINTS, coarser), marble_color(POINTS, plain))


# --- Mitsuba against the reference ---------------------------------------------------------

def test_a_transformed_marble_renders_as_the_reference_renders(llvm):
    scene = scene_with(S.MarbleChannel(octaves=6, period=1.3, distortion=2.0, transform=STEPS))
    metrics = image_metrics(mimarble.render(scene), reference.render(scene))
    assert metrics["psnr"] >= 100 and metrics["frac_over_1_255"] == 0, metrics
    untransformed = mimarble.render(scene_with(S.MarbleChannel(octaves=6, period=1.3,
                                                               distortion=2.0)))
    assert image_metrics(mimarble.render(scene), untransformed)["psnr"] < 40   # it moved


def test_mitsuba_turns_x_stripes_into_y_stripes(llvm):
    def stripes(**kw):
        return mimarble.render(scene_with(S.MarbleChannel(function="sine", distortion=0.0,
                                                          period=3.0, **kw)))
    metrics = image_metrics(stripes(axis="x", transform=[("rotate", (0, 0, 90))]), stripes(axis="y"))
    assert metrics["psnr"] >= 100 and metrics["frac_over_1_255"] == 0, metrics


def test_scenes_differing_past_six_digits_of_a_transform_are_two_structures():
    from mimarble.mitsuba.rendering.loaded_scenes import _structure
    from mimarble.mitsuba.translate.scene_dict import to_mitsuba
    a, b = (_structure(to_mitsuba(scene_with(S.MarbleChannel(
        transform=[("translate", (x, 0, 0))]))))[0] for x in (0.1, 0.1000004))
    assert a != b
    assert math.isclose(0.1, 0.1000004, rel_tol=1e-5)


def test_the_prefilter_sees_a_transform_scale_as_it_sees_the_marbles_own(llvm):
    # v = 2·p both ways: the pixel footprint goes through to_world⁻¹ as through the scale.
    def prefiltered(**kw):
        return mimarble.render(scene_with(S.MarbleChannel(octaves=6, period=1.3, distortion=2.0,
                                                          filter="prefilter", **kw)), spp=1)
    metrics = image_metrics(prefiltered(transform=[("scale", 0.5)]), prefiltered(scale=2.0))
    assert metrics["psnr"] >= 100 and metrics["frac_over_1_255"] == 0, metrics
