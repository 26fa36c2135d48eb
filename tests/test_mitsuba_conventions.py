"""The plugins behave as Mitsuba's own do (issue 29): edits through ``mi.traverse`` in every
variant and through every parent, the whole Texture interface, the classes users import,
``mimarble.render`` of a loaded scene, Mitsuba's ``to_string`` form."""

import numpy as np
import pytest

import mimarble
from mimarble import scene as S
from mimarble.mitsuba.plugins.marble import Marble
from mimarble.mitsuba.plugins import sphere_hit
from mimarble.mitsuba.plugins.channel_expression import ChannelExpression
from mimarble.mitsuba.plugins.material import ChannelMaterial
from mimarble.mitsuba.plugins.registration import first_number

dr, mi = mimarble.dr, mimarble.mi


def interaction(points):
    """A SurfaceInteraction3f at NumPy points (N, 3) (the scalar variant: the first)."""
    points = np.asarray(points, dtype=np.float32)
    if not dr.is_jit_v(mi.Float):
        si = mi.SurfaceInteraction3f()
        si.p = mi.Point3f(*map(float, points[0]))
        return si
    si = dr.zeros(mi.SurfaceInteraction3f, len(points))
    si.p = mi.Point3f(*(mi.Float(points[:, a]) for a in range(3)))
    return si


def colours(texture, points):
    return np.array(texture.eval(interaction(points)), dtype=np.float64).reshape(3, -1).T


POINTS = np.random.default_rng(4).uniform(-2, 2, (16, 3))


def test_edits_through_traverse_apply_in_every_variant(variant):
    texture = mi.load_dict({"type": "marble", "ramp": "0 0 0, 1 1 1"})
    before = colours(texture, POINTS)
    params = mi.traverse(texture)
    params["period"] = 2.5
    params["ramp"] = params["ramp"] * 0.5
    params.update()
    after = colours(texture, POINTS)
    fresh = mi.load_dict({"type": "marble", "ramp": "0 0 0, 0.5 0.5 0.5", "period": 2.5})
    np.testing.assert_allclose(after, colours(fresh, POINTS), atol=1e-6)
    assert np.abs(after - before).max() > 0.05
    params["scale"] = 0.0
    with pytest.raises(Exception, match="scale must be > 0, found 0.0"):
        params.update()
    np.testing.assert_allclose(colours(texture, POINTS), after, atol=1e-6)   # restored


def test_shininess_edits_are_checked_and_restored(variant):
    material = mi.load_dict({"type": "channel_material", "shininess": 8.0})
    params = mi.traverse(material)
    params["shininess"] = 16.0
    params.update()
    assert first_number(material.shininess) == 16.0
    params["shininess"] = -1.0
    with pytest.raises(ValueError, match="shininess"):
        params.update()
    assert first_number(material.shininess) == 16.0


def test_an_edit_of_a_shared_operand_reaches_the_expression(variant):
    """mi.traverse tells a node's first parent only: the expression sees the edit anyway."""
    grey = {"type": "marble", "ramp": "0.2 0.2 0.2"}        # one colour: a constant
    scene = mi.load_dict({
        "type": "scene", "shared": grey,
        "first": {"type": "sphere", "bsdf": {"type": "diffuse",
                                             "reflectance": {"type": "ref", "id": "shared"}}},
        "second": {"type": "sphere", "center": [3, 0, 0], "bsdf": {
            "type": "channel_material", "diffuse": {
                "type": "channel_expression", "op": "add",
                "operand_0": {"type": "ref", "id": "shared"},
                "operand_1": {"type": "rgb", "value": 0.1}}}}})
    expression = next(s.bsdf().diffuse for s in scene.shapes()
                      if isinstance(s.bsdf(), ChannelMaterial))
    np.testing.assert_allclose(colours(expression, POINTS), 0.3, atol=1e-6)
    params = mi.traverse(scene)
    (key,) = [k for k in params.keys() if k.endswith(".ramp")]
    params[key] = params[key] * 3.5                           # 0.2 → 0.7
    params.update()
    np.testing.assert_allclose(colours(expression, POINTS), 0.8, atol=1e-6)
    assert first_number(expression.mean()) == pytest.approx(0.8, rel=1e-5)


def test_the_texture_answers_sample_spectrum_and_pdf_spectrum(variant):
    texture = mi.load_dict({"type": "marble"})
    si = interaction(POINTS)
    wavelengths, value = texture.sample_spectrum(si, si.wavelengths)
    np.testing.assert_array_equal(np.array(value), np.array(texture.eval(si)))
    texture.pdf_spectrum(si)


def test_a_marble_area_light_renders_under_ptracer(jit_variant):
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "ptracer"},
        "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 16, "height": 16},
                   "to_world": mi.ScalarTransform4f().look_at([0, 0, 5], [0, 0, 0], [0, 1, 0])},
        "light": {"type": "rectangle",
                  "emitter": {"type": "area", "radiance": {"type": "marble"}}}})
    image = np.array(mi.render(scene, spp=4))
    assert np.isfinite(image).all() and image.max() > 0


def test_inactive_lanes_are_black_and_the_mean_is_differentiable(jit_variant):
    texture = mi.load_dict({"type": "marble", "ramp": "0.2 0.3 0.4, 0.9 0.8 0.7"})
    si = interaction(POINTS)
    active = mi.Bool([k % 2 == 0 for k in range(len(POINTS))])
    value = np.array(texture.eval(si, active)).T
    assert (value[1::2] == 0).all() and (value[0::2] > 0).all()
    params = mi.traverse(texture)
    dr.enable_grad(params["ramp"])
    params.update()
    mean = texture.mean()
    dr.backward(mean)
    gradient = np.array(dr.grad(params["ramp"]))
    # mean = lum(Σ w_k c_k): ∂/∂c_k is the luminance weight times w_k > 0
    assert (gradient > 0).all()


def test_to_world_is_always_in_traverse(variant):
    params = mi.traverse(mi.load_dict({"type": "marble"}))
    assert "to_world" in params.keys()


def test_the_exported_classes_are_the_plugins(variant):
    texture = mi.load_dict({"type": "marble"})
    assert isinstance(texture, Marble) and isinstance(Marble(), Marble)
    assert not isinstance(texture, ChannelExpression)
    props = mi.Properties()
    props["period"] = 2.0
    assert first_number(Marble(props).period) == 2.0
    assert isinstance(mi.load_dict({"type": "channel_material"}), ChannelMaterial)


def tiny_scene():
    return S.Scene(image=S.Image(12, 10), camera=S.Camera(eye=(0, 0, 6)),
                   lights=(S.Light((4, 4, 4)),), ambient=(0.1, 0.1, 0.1),
                   materials={"m": S.Material("m", diffuse=S.MarbleChannel(octaves=4))},
                   spheres=(S.Sphere("m"),))


def test_render_takes_a_loaded_scene_and_keywords(variant):
    model = tiny_scene()
    loaded = mi.load_dict(mimarble.to_mitsuba(model, spp=1))
    np.testing.assert_array_equal(mimarble.render(loaded), mimarble.render(model, spp=1))
    with pytest.raises(ValueError, match="filter applies to a scene model or file"):
        mimarble.render(loaded, filter="prefilter")
    with pytest.raises(TypeError):
        mimarble.render(model, 4)               # mi.render's second argument is params


def test_path_mode_takes_a_seed(jit_variant):
    model = tiny_scene()
    first = mimarble.render(model, spp=4, mode="path")
    assert np.array_equal(first, mimarble.render(model, spp=4, mode="path", seed=0))
    assert not np.array_equal(first, mimarble.render(model, spp=4, mode="path", seed=1))


def test_to_string_is_mitsubas_indented_form(variant):
    empty = mi.load_dict({"type": "channel_material"})
    assert str(empty) == "ChannelMaterial[\n  shininess = 32.0\n]"
    expression = mi.load_dict({"type": "channel_expression", "op": "add",
                               "operand_0": {"type": "marble"}, "operand_1": {"type": "rgb",
                                                                               "value": 0.1}})
    text = str(expression)
    assert text.startswith("ChannelExpression[\n  op = add,\n  operand_0 = Marble[\n")
    assert "    function = abs_sine," in text and text.endswith("\n]")


def test_whitted_builds_its_sphere_table_once(variant, monkeypatch):
    built = []
    original = sphere_hit.SphereTable.__init__
    monkeypatch.setattr(sphere_hit.SphereTable, "__init__",
                        lambda self, scene: (built.append(1), original(self, scene))[1])
    scene = mi.load_dict(mimarble.to_mitsuba(tiny_scene(), spp=1))
    mimarble.render(scene)
    mimarble.render(scene)
    assert len(built) == 1
