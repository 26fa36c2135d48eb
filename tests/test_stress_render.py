"""Stress suite, rendering (issue 7): paper scenes with extreme but valid marble parameters
render without NaN or infinite pixels, and rendering is bit-identical from run to run."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import mimarble
from mimarble import scene as scene_language

SCENES = Path(__file__).resolve().parent.parent / "scenes"


def fig11a(**marble):
    """Fig. 11(a) at 32×32, one sample, with its marble channels changed as given."""
    s = scene_language.load(SCENES / "fig11a.scene")
    material = s.materials["marble"]
    channels = {name: dataclasses.replace(ch, **marble)
                for name, ch in material.channels().items()
                if isinstance(ch, scene_language.MarbleChannel)}
    material = dataclasses.replace(material, **channels)
    image = dataclasses.replace(s.image, width=32, height=32, samples=1)
    return dataclasses.replace(s, image=image, materials={"marble": material})


RAMP_256 = tuple(tuple(float(x) for x in c) for c in
                 np.random.default_rng(0).uniform(0, 1, (256, 3)).astype(np.float32))

EXTREMES = {
    "scale_1e-6": dict(scale=1e-6),
    "scale_1e6": dict(scale=1e6),
    "octaves_0": dict(octaves=0),
    "octaves_64": dict(octaves=64),
    "distortion_+1e6": dict(distortion=1e6),
    "distortion_-1e6": dict(distortion=-1e6, octaves=64),
    "period_1e6": dict(period=1e6),
    "period_1e6_scale_1e6": dict(period=1e6, scale=1e6, distortion=1e6),
    "ramp_1": dict(ramp=((0.3, 0.6, 0.9),)),
    "ramp_256": dict(ramp=RAMP_256, octaves=25),
    "sine_extreme": dict(function="sine", scale=1e6, distortion=-1e6, turbulence=True),
    "cosine_extreme": dict(function="cosine", scale=1e-6, period=1e6, octaves=64, axis="z"),
}


@pytest.mark.parametrize("name", list(EXTREMES))
def test_extreme_parameters_render_without_nan(llvm, name):
    image = mimarble.render(fig11a(**EXTREMES[name]))
    assert image.shape == (32, 32, 3)
    assert np.all(np.isfinite(image))
    assert image.min() >= 0.0
    # The sphere is lit: the image is not all background.
    assert image.max() > 0.05


def test_one_colour_ramp_renders_as_a_constant_material(llvm):
    colour = (0.3, 0.6, 0.9)
    image = mimarble.render(fig11a(ramp=(colour,)))
    reference = mimarble.render(fig11a(ramp=(colour,), scale=1e6, distortion=-1e6, octaves=64))
    np.testing.assert_array_equal(image, reference)


def test_render_is_bit_identical_from_run_to_run(llvm):
    scene = fig11a(octaves=64, scale=3.7)
    np.testing.assert_array_equal(mimarble.render(scene), mimarble.render(scene))


def test_huge_but_valid_scale_renders_without_nan(llvm):
    assert np.all(np.isfinite(mimarble.render(fig11a(scale=1e19))))
