"""The float64 reference of the fast preview (mimarble/reference/preview.py) against
Mitsuba's preview mode (``path`` + ``subsurface_preview``), which share nothing but the
scene model: the block z-test of tests/test_translucent_reference.py (:func:`agreement`,
Bonferroni over the block-colours at family-wise α = 10⁻³), and planted errors in the
reference that must fail it. Also closed forms: a sphere under a white sky and no light
shows F̄ + (1 − F̄)·A = C on its disk's mean; max_depth 1 renders nothing (the sky is
hidden from camera rays)."""

import numpy as np
import pytest

from mimarble.contract import PATH_MAX_DEPTH, PREVIEW_MAX_DEPTH
from mimarble.reference import preview
from mimarble.reference.subsurface_reflectance import diffuse_fresnel_reflectance
from mimarble.scene import model
from test_translucent_reference import (BACK_LIGHT, POINT_LIGHT, SIDE_LIGHT, agreement,
                                        llvm_variant)  # noqa: F401 (a fixture)
from test_subsurface_reflectance import disk_mean, sphere_scene

SIZE = 24
SEEDS = 24
REF_SPP = 512

VEINS = model.MarbleChannel(function="sine", axis="x", period=1.5, distortion=0.8, octaves=3,
                            space="object",
                            ramp=((0.95, 0.93, 0.9), (0.75, 0.7, 0.6), (0.3, 0.35, 0.4)))


def preview_scene(reflectance=VEINS, ior=1.5, lights=(BACK_LIGHT, POINT_LIGHT),
                  ambient=(0.5, 0.55, 0.6), kind="reflectance"):
    """A veined unit sphere and a smaller one beside it (light passes between them: the
    mirror and the lobe's second vertices), seen from (0, 0.4, 5)."""
    sub = model.Subsurface(**{kind: reflectance}, mean_free_path=0.05, ior=ior)
    small = model.Subsurface(reflectance=model.ColorChannel((0.8, 0.5, 0.3)),
                             mean_free_path=0.05, ior=ior)
    return model.Scene(
        image=model.Image(width=SIZE, height=SIZE),
        camera=model.Camera(eye=(0.0, 0.4, 5.0), lookat=(0.0, 0.0, 0.0), fov=36.0),
        ambient=ambient, lights=tuple(lights),
        materials={"m": model.Material("m", subsurface=sub),
                   "n": model.Material("n", subsurface=small)},
        spheres=(model.Sphere("m", (0.0, 0.0, 0.0), 1.0),
                 model.Sphere("n", (1.45, -0.3, 0.6), 0.4)))


def mitsuba_renders(scene, spp, seeds=SEEDS, max_depth=None):
    """Preview mode's renders of ``scene`` (its integrator's max_depth replaced if given)."""
    import mimarble
    from mimarble.mitsuba.translate.scene_dict import to_mitsuba
    mi = mimarble.mi
    translated = to_mitsuba(scene, "preview", spp=spp)
    if max_depth is not None:
        translated["integrator"]["max_depth"] = max_depth
    loaded = mi.load_dict(translated)
    return np.stack([np.array(mi.render(loaded, seed=s), dtype=np.float64) for s in range(seeds)])


SCENE = preview_scene()


@pytest.fixture(scope="module")
def renders(llvm_variant):  # noqa: F811 (the fixture)
    return mitsuba_renders(SCENE, 64)


def test_the_preview_agrees_with_its_float64_reference(renders):
    image, variance = preview.render_preview(SCENE, REF_SPP, seed=3, variance=True)
    assert image.mean() > 0.05
    ratio, z, m = agreement(SCENE, image, variance, REF_SPP, renders)
    assert ratio < 1, (z, m)


def test_interreflections_agree_at_path_modes_depth(llvm_variant):  # noqa: F811
    """max_depth 4 (path mode's): the coat and the lobe see the other sphere, lit."""
    renders = mitsuba_renders(SCENE, 64, max_depth=PATH_MAX_DEPTH)
    image, variance = preview.render_preview(SCENE, REF_SPP, seed=5, max_depth=PATH_MAX_DEPTH,
                                             variance=True)
    ratio, z, m = agreement(SCENE, image, variance, REF_SPP, renders)
    assert ratio < 1, (z, m)


def _planted(name):
    if name == "ior 1.3":
        return preview_scene(ior=1.3)
    if name == "no point light":
        return preview_scene(lights=(BACK_LIGHT,))
    if name == "albedo for reflectance":             # A read as a single-scattering albedo
        return preview_scene(kind="albedo")
    ramp = tuple(tuple(0.95 * c for c in colour) for colour in VEINS.ramp)
    return preview_scene(reflectance=model.MarbleChannel(
        function="sine", axis="x", period=1.5, distortion=0.8, octaves=3, space="object",
        ramp=ramp))


@pytest.mark.parametrize("planted", ["ior 1.3", "no point light", "albedo for reflectance",
                                     "reflectance × 0.95"])
def test_a_planted_error_fails_the_agreement(planted, renders):
    image, variance = preview.render_preview(_planted(planted), REF_SPP, seed=3, variance=True)
    ratio, z, m = agreement(SCENE, image, variance, REF_SPP, renders)
    assert ratio > 1, (z, m)


def test_a_rectangle_light_alone_agrees(llvm_variant):  # noqa: F811
    scene = preview_scene(lights=(SIDE_LIGHT,), ambient=(0.0, 0.0, 0.0))
    image, variance = preview.render_preview(scene, REF_SPP, seed=4, variance=True)
    assert image.mean() > 0.005
    ratio, z, m = agreement(scene, image, variance, REF_SPP, mitsuba_renders(scene, 64))
    assert ratio < 1, (z, m)


@pytest.mark.parametrize("ior", [1.0, 1.5])
def test_a_sphere_under_a_white_sky_shows_its_colour(ior):
    """No light, a white sky: every path ends in the sky (mirror weight 1, the lobe's weight
    A·(1 − F(μₒ))/(1 − F̄) has mean A), so the disk's mean is F̄ + (1 − F̄)·A = C for
    C ≥ F̄, within the noise (here a few 10⁻³)."""
    colour = (0.2, 0.5, 0.95)
    scene = sphere_scene(colour, ior)
    image = preview.render_preview(scene, 256, seed=1)
    assert diffuse_fresnel_reflectance(ior) < 0.2
    np.testing.assert_allclose(disk_mean(scene, image), colour, rtol=0.01)


def test_max_depth_one_renders_nothing_but_two_the_sky_once_reflected():
    scene = sphere_scene((0.5, 0.5, 0.5), 1.5)
    assert not preview.render_preview(scene, 4, seed=1, max_depth=1).any()
    assert preview.render_preview(scene, 4, seed=1, max_depth=2).any()


def test_preview_mode_is_direct_light_only_where_a_material_is_translucent():
    from mimarble.mitsuba.translate.scene_dict import to_mitsuba
    assert to_mitsuba(SCENE, "preview", spp=4)["integrator"]["max_depth"] == PREVIEW_MAX_DEPTH
