"""The pass renderer's stratified samples (rendering/passes.py, ``stratify``; issue 40): a
translucent scene's sampler (``multijitter``, translate/modes.py ``translucent_sampler``)
draws a pixel's spp samples as one sequence, so that each dimension of a pixel's samples
falls in spp distinct strata — which independent samples do by chance with probability
spp!/sppˢᵖᵖ (5·10⁻⁷ at 16). Its agreement with the float64 walk (unbiased) is
tests/test_translucent_reference.py's ``test_the_pass_renderer_stratified_agrees_with_the_walk``.
"""

import numpy as np
import pytest

import mimarble
from mimarble.scene import model

dr, mi = mimarble.dr, mimarble.mi


def _sphere_scene(subsurface: bool):
    material = model.Material("m", subsurface=model.Subsurface(
        albedo=model.ColorChannel((0.9, 0.9, 0.9)), mean_free_path=0.2, ior=1.5)) \
        if subsurface else model.Material("m", diffuse=model.ColorChannel((0.5, 0.5, 0.5)))
    return model.Scene(image=model.Image(width=4, height=3),
                       camera=model.Camera(eye=(0.0, 0.0, 5.0), lookat=(0.0, 0.0, 0.0), fov=30.0),
                       materials={"m": material}, spheres=(model.Sphere("m", (0, 0, 0), 1.0),))


@pytest.mark.parametrize("spp, kind", [(16, "multijitter"), (48, "multijitter"),
                                       (64, "multijitter"), (10, "independent"),
                                       (1, "multijitter")])
def test_the_translucent_sampler_is_multijitter_where_it_takes_spp_as_it_is(spp, kind):
    """multijitter takes an r × ⌈spp/r⌉ grid, r = ⌊√spp⌋ (10 would become 12:
    independent)."""
    from mimarble.mitsuba.translate.modes import translucent_sampler
    assert translucent_sampler(spp) == {"type": kind, "sample_count": spp}
    loaded = mi.load_dict({"type": kind, "sample_count": spp})
    assert loaded.sample_count() == spp


def _first_draws(scene, spp: int):
    """(pixels, spp) the first 1-D draw after the camera ray of each lane of one pass over
    every pixel of ``scene`` (path mode), and whether the pass stratified."""
    from mimarble.mitsuba.rendering import passes
    from mimarble.mitsuba.rendering.pixel_tracer import PassNumbers, PixelTracer
    from mimarble.mitsuba.translate import scene_dict
    loaded = mi.load_dict(scene_dict.to_mitsuba(scene, "path", spp=spp))
    target = passes.Target.of(loaded, "path")
    stratified = passes.stratify(target, spp, spp)
    pixels = target.width * target.height
    lane = dr.arange(mi.UInt32, pixels * spp)
    tracer = PixelTracer(loaded, "path", target.sampler)
    numbers = PassNumbers(0, 0, spp, spp, 12345, False)
    tracer.ray(lane // spp, lane % spp, numbers)      # seeds the sampler, draws the position
    return target.sampler.next_1d().numpy().reshape(pixels, spp), stratified


@pytest.mark.parametrize("spp", [16, 48])
def test_a_translucent_pixels_samples_fall_in_distinct_strata(spp):
    draws, stratified = _first_draws(_sphere_scene(True), spp)
    assert stratified
    strata = np.sort(np.floor(draws * spp).astype(int), axis=1)
    assert (strata == np.arange(spp)).all()


def test_opaque_scenes_keep_independent_samples():
    """The control: an opaque scene's ``independent`` sampler is left as it was (its
    images unchanged bit for bit), and its pixels' draws repeat strata."""
    draws, stratified = _first_draws(_sphere_scene(False), 16)
    assert not stratified
    strata = np.sort(np.floor(draws * 16).astype(int), axis=1)
    assert not (strata == np.arange(16)).all()


def test_split_pixels_and_odd_spp_draw_independent_samples():
    """A pass holding part of a pixel's samples, or an spp the sampler would round, is not
    stratified (a lane draws sample 0 of a sequence of its own: uniform)."""
    from mimarble.mitsuba.rendering import passes
    from mimarble.mitsuba.translate import scene_dict
    loaded = mi.load_dict(scene_dict.to_mitsuba(_sphere_scene(True), "path", spp=16))
    target = passes.Target.of(loaded, "path")
    assert not passes.stratify(target, 8, 16)
    assert not passes.stratify(target, 10, 10)
    assert passes.stratify(target, 16, 16)
