"""Every differentiable marble parameter has the derivative of the float64 reference.

For each parameter the table marks differentiable (mimarble/parameters.py), the
texture's forward-mode derivative of the colour, at random points, against central
differences of the reference marble (mimarble/reference/marble.py, float64) — in general,
at distortion 0 (no noise, yet ∂/∂distortion = F) and with a flat ramp (no colour changes,
yet ∂/∂ramp depends on t): the cases where the error budget, which bounds the colour and
not its derivatives, once left out what the derivative needs.
"""

import dataclasses

import numpy as np
import pytest

import mimarble
from mimarble.mitsuba.plugins.marble import Marble
from mimarble.parameters import PARAMETERS
from mimarble.mitsuba.translate.scene_dict import texture_dict
from mimarble.reference import marble as reference_marble
from mimarble.reference.channels import channel_color
from mimarble.scene import ColorChannel, MarbleChannel, Mix, Multiply

dr, mi = mimarble.dr, mimarble.mi

DIFFERENTIABLE = [p.name for p in PARAMETERS if p.in_place]
GREY = ((0.5, 0.5, 0.5),) * 4
CASES = {
    "general": MarbleChannel(scale=1.3, period=1.7, distortion=2.5, octaves=8,
                             ramp=((0.1, 0.0, 0.05), (0.9, 0.6, 0.2), (0.3, 0.8, 1.0))),
    "distortion 0": MarbleChannel(scale=1.3, period=1.7, distortion=0.0, octaves=8,
                                  ramp=((0.1, 0.0, 0.05), (0.9, 0.6, 0.2), (0.3, 0.8, 1.0))),
    "flat ramp": MarbleChannel(scale=1.3, period=1.7, distortion=2.5, octaves=8, ramp=GREY),
    # POV-Ray's knobs (issue 30): another gain and lacunarity, a ramp at positions.
    "gain and lacunarity": MarbleChannel(scale=1.3, period=1.7, distortion=2.5, octaves=6,
                                         gain=0.62, lacunarity=2.3, function="triangle",
                                         ramp=((0.1, 0.0, 0.05), (0.9, 0.6, 0.2),
                                               (0.3, 0.8, 1.0))),
    "positions": MarbleChannel(scale=1.3, period=1.7, distortion=2.5, octaves=8,
                               ramp=((0.1, 0.0, 0.05), (0.9, 0.6, 0.2), (0.3, 0.8, 1.0),
                                     (1.0, 1.0, 0.9)),
                               ramp_positions=(0.1, 0.35, 0.8, 0.95)),
}
#: The ramp colour and component whose derivative is taken.
KEY, COMPONENT = 1, 0


def moved(channel, name, h):
    """The channel with parameter ``name`` moved by h (ramp: colour KEY's COMPONENT;
    positions: position KEY)."""
    if name == "ramp_positions":
        positions = list(channel.ramp_positions)
        positions[KEY] += h
        return dataclasses.replace(channel, ramp_positions=tuple(positions))
    if name != "ramp":
        return dataclasses.replace(channel, **{name: getattr(channel, name) + h})
    ramp = [list(c) for c in channel.ramp]
    ramp[KEY][COMPONENT] += h
    return dataclasses.replace(channel, ramp=tuple(map(tuple, ramp)))


def texture_derivative(channel, name, points):
    """∂colour/∂name of the ``marble`` texture, forward mode, at float32 points."""
    props = {"type": "marble"}
    for p, value in channel.items():
        if p.name != "tolerance":
            props[p.name] = p.property_value(value)
    texture = mi.load_dict(props)
    params = mi.traverse(texture)
    value = params[name]
    dr.enable_grad(value)
    params.update()
    si = dr.zeros(mi.SurfaceInteraction3f, len(points))
    si.p = mi.Point3f(*(mi.Float(points[:, a]) for a in range(3)))
    colour = texture.eval(si)
    if name == "ramp":
        direction = dr.zeros(mi.Color3f, len(channel.ramp))
        direction[COMPONENT] = mi.Float([1.0 if k == KEY else 0.0
                                         for k in range(len(channel.ramp))])
        dr.set_grad(value, direction)
    elif name == "ramp_positions":
        dr.set_grad(value, mi.Float([1.0 if k == KEY else 0.0
                                     for k in range(len(channel.ramp))]))
    else:
        dr.set_grad(value, 1.0)
    dr.forward_to(colour)
    return np.array(dr.grad(colour), dtype=np.float64).T


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("name", DIFFERENTIABLE)
def test_each_differentiable_parameter_has_the_reference_derivative(llvm, case, name):
    channel = CASES[case]
    if name == "ramp_positions" and channel.ramp_positions is None:
        pytest.skip("evenly spaced: no positions to move (having them is structural)")
    points = np.random.default_rng(3).uniform(-2, 2, (3000, 3)).astype(np.float32)
    exact = points.astype(np.float64)
    h = 1e-6
    ahead = reference_marble.marble_color(exact, moved(channel, name, h))
    behind = reference_marble.marble_color(exact, moved(channel, name, -h))
    here = reference_marble.marble_color(exact, channel)
    forward, backward = (ahead - here) / h, (here - behind) / h
    smooth = (np.abs(forward - backward) < 2e-2 * (1 + np.abs(forward))).all(axis=1)
    truth = (ahead - behind) / (2 * h)
    ours = texture_derivative(channel, name, points)
    assert smooth.mean() > 0.8
    error = np.abs(ours - truth)[smooth]
    # float32 against float64: the derivative's own rounding (|truth| reaches ~30).
    assert np.quantile(error / (1 + np.abs(truth[smooth])), 0.99) < 5e-3, (case, name)
    if np.abs(truth[smooth]).max() > 1e-3:   # a derivative that is there is not lost
        assert np.abs(ours[smooth]).max() > 0.5 * np.abs(truth[smooth]).max()


# ---------------------------------------------------------------------------
# Derivatives that are 0 by structure (issue 37, item 4): the colour does not depend on
# the parameter at all — one octave (ω⁰ = 1, λ⁰ = 1), one ramp colour, a factor 0 or a
# mix weight 0 around the marble. The dependence stays attached: through Mitsuba's prb
# and dr.backward the gradient is 0, not prb's "not attached to the AD graph" error.

ONE_COLOUR = ((0.3, 0.5, 0.7),)
VEINED = dict(scale=1.3, period=1.7, distortion=2.5, octaves=3,
              ramp=((0.1, 0.0, 0.05), (0.9, 0.6, 0.2), (0.3, 0.8, 1.0)))
ZERO_BY_STRUCTURE = {
    "one octave": (MarbleChannel(**{**VEINED, "octaves": 1}), ("gain", "lacunarity")),
    "one colour": (MarbleChannel(**{**VEINED, "ramp": ONE_COLOUR}),
                   ("scale", "period", "distortion", "gain", "lacunarity")),
    "one colour at a position": (MarbleChannel(**{**VEINED, "ramp": ONE_COLOUR,
                                                  "ramp_positions": (0.4,)}),
                                 ("scale", "period", "distortion", "gain", "lacunarity",
                                  "ramp_positions")),
    "times a constant 0": (Multiply((ColorChannel((0.0, 0.0, 0.0)), MarbleChannel(**VEINED))),
                           tuple(DIFFERENTIABLE)),
    "mixed in with weight 0": (Mix(ColorChannel((0.2, 0.4, 0.6)), MarbleChannel(**VEINED), 0.0),
                               tuple(DIFFERENTIABLE)),
}
ROWS = [(case, name) for case, (_, names) in ZERO_BY_STRUCTURE.items() for name in names
        if name != "ramp_positions" or case == "one colour at a position"]


def marble_of(channel):
    return channel if isinstance(channel, MarbleChannel) else \
        next(c for c in (getattr(channel, "operands", None) or (channel.a, channel.b))
             if isinstance(c, MarbleChannel))


def with_marble_moved(channel, name, h):
    marble = marble_of(channel)
    if name == "ramp_positions" and len(marble.ramp) == 1:
        return dataclasses.replace(marble, ramp_positions=(marble.ramp_positions[0] + h,))
    if channel is marble:
        return moved(channel, name, h)
    if isinstance(channel, Mix):
        return dataclasses.replace(channel, b=moved(marble, name, h))
    return dataclasses.replace(channel, operands=tuple(
        moved(c, name, h) if c is marble else c for c in channel.operands))


def test_every_differentiable_row_has_a_structural_zero_case():
    assert {name for _, name in ROWS} == set(DIFFERENTIABLE)


@pytest.mark.parametrize("case, name", ROWS)
def test_a_derivative_zero_by_structure_is_a_gradient_of_zero_through_prb(llvm, case, name):
    channel, _ = ZERO_BY_STRUCTURE[case]
    # The reference's colours do not move with the parameter: the derivative is 0.
    points = np.random.default_rng(4).uniform(-2, 2, (500, 3))
    here = channel_color(channel, points)
    for h in (1e-3, -1e-3):
        np.testing.assert_array_equal(channel_color(with_marble_moved(channel, name, h), points),
                                      here)
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "prb", "max_depth": 2},
        "sensor": {"type": "perspective", "fov": 40,
                   "to_world": mi.ScalarTransform4f().look_at([0, 0, 4], [0, 0, 0], [0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 8, "height": 8},
                   "sampler": {"type": "independent", "sample_count": 1}},
        "sky": {"type": "constant"},
        "ball": {"type": "sphere", "bsdf": {"type": "diffuse",
                                             "reflectance": texture_dict(channel)}}})
    params = mi.traverse(scene)
    (key,) = [k for k in params.keys() if k.endswith("." + name)
              and isinstance(params.properties[k][2], Marble)]
    dr.enable_grad(params[key])
    params.update()
    image = mi.render(scene, params, spp=1, seed=0)
    assert np.array(image).max() > 0
    dr.backward(dr.mean(image, axis=None))
    gradient = np.array(dr.grad(params[key]))
    assert gradient.size and (gradient == 0).all(), (case, name, gradient)
