"""The marble texture's exact ``eval_1_grad`` (issue 13): against float64 finite
differences of the reference marble, and inside Mitsuba's ``bumpmap`` BSDF."""

import numpy as np
import pytest

import mimarble
from mimarble.reference import marble as reference_marble
from mimarble.scene import MarbleChannel

dr, mi = mimarble.dr, mimarble.mi
LUMINANCE = np.array([0.212671, 0.715160, 0.072169])
RAMP = ((0.1, 0.0, 0.05), (0.9, 0.6, 0.2), (0.3, 0.8, 1.0), (1.0, 1.0, 0.9))


def reference_luminance(points, channel, to_texture=None):
    p = points if to_texture is None else points @ to_texture[:3, :3].T + to_texture[:3, 3]
    return reference_marble.marble_color(p, channel) @ LUMINANCE


def smooth_central_difference(f, pts, direction, h=1e-7):
    """(derivative, smooth): the central difference along ``direction`` in float64, and
    where the two one-sided differences agree (no ramp key or |sin| kink inside ±h)."""
    ahead, here, behind = f(pts + h * direction), f(pts), f(pts - h * direction)
    forward, backward = (ahead - here) / h, (here - behind) / h
    smooth = np.abs(forward - backward) < 1e-2 * (1 + np.abs(forward))
    return (ahead - behind) / (2 * h), smooth


@pytest.mark.parametrize("function", ["abs_sine", "sine", "cosine"])
@pytest.mark.parametrize("turbulence", [False, True])
@pytest.mark.parametrize("transformed", [False, True])
def test_eval_1_grad_is_the_derivative_of_the_reference_marble(llvm, function, turbulence,
                                                               transformed):
    channel = MarbleChannel(scale=1.7, period=1.3, distortion=2.5, octaves=6, function=function,
                            turbulence=turbulence, ramp=RAMP)
    props = {"type": "marble", "scale": 1.7, "period": 1.3, "distortion": 2.5, "octaves": 6,
             "function": function, "turbulence": turbulence, "tolerance": 0.0,
             "ramp": ", ".join(" ".join(map(str, c)) for c in RAMP)}
    to_texture = None
    if transformed:
        to_world = mi.ScalarTransform4f().translate([0.3, -1, 2]).rotate([1, 2, 3], 40).scale([2, 1, 0.5])
        props["to_world"] = to_world
        to_texture = np.linalg.inv(np.array(to_world.matrix, dtype=np.float64))
    tex = mi.load_dict(props)

    rng = np.random.default_rng(5)
    pts = rng.uniform(-2, 2, (3000, 3)).astype(np.float32).astype(np.float64)
    du, dv = rng.normal(size=(3000, 3)), rng.normal(size=(3000, 3))
    si = dr.zeros(mi.SurfaceInteraction3f, len(pts))
    si.p = mi.Point3f(*(mi.Float(pts[:, a].astype(np.float32)) for a in range(3)))
    si.dp_du = mi.Vector3f(*(mi.Float(du[:, a].astype(np.float32)) for a in range(3)))
    si.dp_dv = mi.Vector3f(*(mi.Float(dv[:, a].astype(np.float32)) for a in range(3)))
    ours = np.array(tex.eval_1_grad(si))

    def f(q):
        return reference_luminance(q, channel, to_texture)
    for k, d in enumerate((du.astype(np.float32), dv.astype(np.float32))):
        expected, smooth = smooth_central_difference(f, pts, d)
        assert smooth.mean() > 0.9
        error = np.abs(ours[k] - expected)[smooth]
        # float32 against float64: relative 1e-3 of the slope's scale (slopes reach ~100).
        assert np.quantile(error / (1 + np.abs(expected[smooth])), 0.999) < 2e-3
        assert error.max() < 0.05 * (1 + np.abs(expected).max())


def finite_difference_marble():
    """The marble with ``eval_1_grad`` by central differences (the former implementation):
    an independent check of what ``bumpmap`` makes of the exact gradient."""
    class FiniteDifferenceMarble(mimarble.mitsuba.plugins.registration.bound_class("marble")):
        def eval_1_grad(self, si, active=True):
            step = 1e-3 / self.scale
            out = []
            def colour(p):
                moved = mi.SurfaceInteraction3f(si)
                moved.p = p
                return mi.luminance(self.eval(moved))
            for dp in (si.dp_du, si.dp_dv):
                ahead, behind = colour(si.p + dp * step), colour(si.p - dp * step)
                out.append((ahead - behind) / (2 * step))
            return mi.Vector2f(*out)
    return FiniteDifferenceMarble


def bump_scene(texture_type, bumped=True):
    marble = {"type": texture_type, "scale": 2.0, "period": 1.0, "distortion": 2.0, "octaves": 4,
              "ramp": "0 0 0, 1 1 1"}
    bsdf = {"type": "diffuse"}
    if bumped:
        bsdf = {"type": "bumpmap", "arbitrary": marble, "scale": 0.05, "bsdf": bsdf}
    return mi.load_dict({
        "type": "scene", "integrator": {"type": "direct"},
        "sensor": {"type": "perspective", "fov": 30,
                   "to_world": mi.ScalarTransform4f().look_at([0, 0, 5], [0, 0, 0], [0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 48, "height": 48, "rfilter": {"type": "box"}},
                   "sampler": {"type": "stratified", "sample_count": 4, "jitter": False}},
        "sphere": {"type": "sphere", "bsdf": bsdf},
        "light": {"type": "directional", "direction": [-1, -1, -1], "irradiance": 3.0}})


def test_a_bump_mapped_marble_matches_finite_differences(llvm):
    """Mitsuba's ``bumpmap`` with the exact gradient and with central differences: the
    same bent normals, so the images agree far better than either agrees with the
    unbumped sphere."""
    cls = finite_difference_marble()
    mi.register_texture("marble_fd", lambda props: cls(props))
    exact = np.array(mi.render(bump_scene("marble")))[..., :3]
    numeric = np.array(mi.render(bump_scene("marble_fd")))[..., :3]
    plain = np.array(mi.render(bump_scene("marble", bumped=False)))[..., :3]
    assert exact.mean() > 0.05
    assert np.abs(exact - plain).mean() > 0.01            # the bumps show
    assert np.abs(exact - numeric).mean() < 0.05 * np.abs(exact - plain).mean()
