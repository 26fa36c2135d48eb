"""The constant sky picked less often at a translucent walk's exit (media.constant_sky_weight,
issue 40): where the weight is given, and that it lowers the noise without moving the mean."""

from __future__ import annotations

import numpy as np
import pytest

from mimarble.mitsuba.translate import scene_dict
from mimarble.mitsuba.translate.media import CONSTANT_SKY_WEIGHT
from mimarble.scene import model

from test_translucent_reference import llvm_variant  # noqa: F401

POINT = model.Light((10.0, 10.0, 10.0), (1.0, 1.0, 1.0))


def scene_of(lights=(POINT,), translucent=True, environment=None, size=32):
    sub = model.Subsurface(reflectance=model.ColorChannel((0.8, 0.7, 0.6)), mean_free_path=0.1)
    material = model.Material("m", subsurface=sub) if translucent else \
        model.Material("m", diffuse=model.ColorChannel((0.8, 0.7, 0.6)))
    return model.Scene(
        image=model.Image(width=size, height=size),
        camera=model.Camera(eye=(0.0, 0.0, 5.0), lookat=(0.0, 0.0, 0.0), fov=30.0),
        ambient=(0.2, 0.2, 0.2), lights=tuple(lights), environment=environment,
        materials={"m": material}, spheres=(model.Sphere("m", (0.0, 0.0, 0.0), 1.0),))


def test_the_weight_is_given_to_a_constant_sky_of_a_lit_translucent_scene_only():
    lit = scene_dict.to_mitsuba(scene_of(), "path", 4)
    assert lit["ambient"]["sampling_weight"] == CONSTANT_SKY_WEIGHT
    assert "sampling_weight" not in lit["light_0"]
    for scene, mode in ((scene_of(lights=()), "path"), (scene_of(translucent=False), "path"),
                        (scene_of(translucent=False), "preview")):
        assert "sampling_weight" not in scene_dict.to_mitsuba(scene, mode, 4)["ambient"]
    sky = scene_of(environment=model.Environment(color=(0.3, 0.3, 0.3)))
    assert scene_dict.to_mitsuba(sky, "path", 4)["environment"]["sampling_weight"] == \
        CONSTANT_SKY_WEIGHT


def test_the_weight_lowers_the_noise_and_keeps_the_mean(llvm_variant):
    """Two renders per weighting (the translation's, and Mitsuba's default 1) of a sphere under
    a point light and the ambient: the relative per-pixel noise drops below 0.8× (measured
    ~0.5× on fig11a-translucent), and the two means agree within 4 standard errors (each
    from its two renders' difference)."""
    import mitsuba as mi
    translated = scene_dict.to_mitsuba(scene_of(), "path", 16)
    plain = {**translated, "ambient": {k: v for k, v in translated["ambient"].items()
                                       if k != "sampling_weight"}}
    stats = []
    for d in (translated, plain):
        loaded = mi.load_dict(d)
        a, b = (np.asarray(mi.render(loaded, seed=s), np.float64) for s in (1, 2))
        inside = (a + b).sum(axis=2) > 0
        a, b = a[inside], b[inside]
        mean = (a + b).mean() / 2
        noise = np.sqrt(np.mean((a - b) ** 2) / 2) / mean
        se = np.sqrt(np.mean((a - b) ** 2) / 2 / a.size / 2)      # of the two renders' mean
        stats.append((mean, noise, se))
    (m1, n1, s1), (m0, n0, s0) = stats
    assert n1 < 0.8 * n0, (n1, n0)
    assert abs(m1 - m0) < 4 * np.hypot(s1, s0), (m1, m0, s1, s0)
