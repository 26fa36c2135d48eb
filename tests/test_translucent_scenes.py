"""The translucent Fig. 11 scenes (scenes/translucent/): they render in path mode, and whitted
mode refuses them at their subsurface, in one sentence."""

from pathlib import Path

import numpy as np
import pytest

import mimarble
from mimarble import scene as S
from mimarble.scene.edits import resized

ROOT = Path(__file__).resolve().parent.parent
SCENES = sorted((ROOT / "scenes" / "translucent").glob("*.scene"))
#: The stones of the gallery's translucent row (issue 40), beside the Fig. 11 twins.
STONES = ("carrara", "onyx", "verde")
FIG11A = ROOT / "scenes" / "translucent" / "fig11a-translucent.scene"


def test_each_fig11_marble_has_a_translucent_twin():
    twins = [p for p in SCENES if p.stem not in STONES]
    assert sorted(p.stem for p in SCENES) == sorted([f"fig11{k}-translucent" for k in "abcd"]
                                                    + list(STONES))
    for path in twins:
        twin, original = S.load(path), S.load(ROOT / "scenes" / f"{path.stem[:6]}.scene")
        albedo = twin.materials["translucent marble"].subsurface.reflectance
        marble = original.materials["marble"].diffuse
        for key in ("scale", "period", "distortion", "octaves", "function", "axis"):
            assert getattr(albedo, key) == getattr(marble, key), (path.stem, key)


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_a_translucent_scene_renders_in_path_mode(llvm, path):
    image = np.asarray(mimarble.render(resized(S.load(path), 16), mode="path", spp=4))
    assert image.shape == (16, 16, 3) and np.isfinite(image).all() and image.max() > 0


def test_whitted_mode_refuses_a_translucent_scene_at_its_subsurface(llvm):
    path = FIG11A
    with pytest.raises(ValueError) as info:
        mimarble.render(resized(S.load(path), 16))
    line = next(k for k, text in enumerate(path.read_text().splitlines(), 1) if "subsurface" in text
                and not text.lstrip().startswith("//"))
    assert str(info.value).startswith(f"{path}:{line}:") and "--mode path" in str(info.value)


def test_a_subsurface_reflectance_bakes_on_a_grid_as_the_reference_marble(tmp_path):
    from mimarble.tools import bake
    from mimarble.reference.channels import channel_color
    scene = S.load(FIG11A)
    lo, hi = bake.bake_volume(scene, "sphere_0", tmp_path / "reflectance.vol", size=4,
                                channel="reflectance")
    data = (tmp_path / "reflectance.vol").read_bytes()
    values = np.frombuffer(data[-4 ** 3 * 3 * 4:], dtype="<f4").reshape(4, 4, 4, 3)  # z, y, x
    centre = (np.asarray(lo) + (np.asarray(hi) - np.asarray(lo)) * (np.array([1, 2, 0]) + 0.5) / 4)
    expected = channel_color(scene.materials["translucent marble"].subsurface.reflectance, centre[None])
    np.testing.assert_allclose(values[0, 2, 1], expected[0], atol=1e-6)


def test_the_mean_bound_bounds_the_mean_of_every_channel_kind():
    # error_budget.mean_bound (the medium's density bound) against the float64 reference's
    # channel values at random points (seeded), for colours, marbles and expressions.
    from mimarble.texture.error_budget import mean_bound
    from mimarble.reference.channels import channel_color
    marble = S.MarbleChannel(octaves=4, ramp=((0, 0, 0), (4, 1, 0.5), (0.2, 3, 0)))
    negative = S.ColorChannel((-1.0, 0.5, 2.0))
    points = np.random.default_rng(3).uniform(-5, 5, (20000, 3))
    for channel in (marble, negative, S.Add((marble, negative)),
                    S.Multiply((marble, negative)), S.Mix(marble, negative, 0.3),
                    S.Mix(negative, marble, S.MarbleChannel(octaves=2))):
        means = channel_color(channel, points).mean(axis=1)
        assert means.max() <= mean_bound(channel) + 1e-12, channel


def test_the_reference_tracer_refuses_a_translucent_scene_at_its_subsurface():
    from mimarble import reference
    with pytest.raises(S.SceneError, match="render_translucent"):
        reference.render(resized(S.load(FIG11A), 8))
