"""docs/mitsuba-scene.md: the XML example loads, every use of marble in it renders."""

import os

import numpy as np

import mimarble

mi = mimarble.mi
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLE = os.path.join(ROOT, "docs", "examples", "marble-in-mitsuba.xml")


def test_the_xml_example_renders_with_every_kind_of_use(llvm):
    scene = mi.load_file(EXAMPLE, resx=48, resy=32, spp=4)
    image = np.array(mi.render(scene))[..., :3]
    assert image.shape == (32, 48, 3) and np.isfinite(image).all()
    assert 0.05 < image.mean() < 2.0
    keys = list(mi.traverse(scene).keys())
    # The shared marble, and marble as principled base colour (with to_world), bump map,
    # and blend weight.
    for suffix in ("veins.period", "base_color.to_world", "bsdf.nested_texture.distortion",
                   "bsdf.weight.ramp"):
        assert any(key.endswith(suffix) for key in keys), suffix
