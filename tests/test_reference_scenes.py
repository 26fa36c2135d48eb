"""Every shipped scene renders with the reference tracer (at reduced resolution)."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from mimarble import reference, scene

SCENES = sorted((Path(__file__).resolve().parent.parent / "scenes").glob("*.scene"))


def test_there_are_scenes():
    assert len(SCENES) >= 20


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_scene_renders_finite_at_24x24(path):
    s = scene.load(path)
    s = dataclasses.replace(s, image=dataclasses.replace(s.image, width=24, height=24))
    img = reference.render(s, spp=1)
    assert img.shape == (24, 24, 3) and img.dtype == np.float64
    assert np.all(np.isfinite(img))
    assert np.all(img >= 0)
    # the sphere is visible: the centre differs from the background corner
    assert np.any(img[12, 12] != img[0, 0])


def test_render_accepts_a_path(tmp_path):
    f = tmp_path / "tiny.scene"
    f.write_text('image { width 6 height 4 samples 4 background < 0.5 0.5 0.5 > }\n'
                 'material "m" { ambient { color < 1 1 1 > } }\n'
                 'ambient < 0.25 0.25 0.25 >\n'
                 'sphere { center < 0 0 0 > radius 3 material "m" }\n')
    img = reference.render(str(f))
    assert img.shape == (4, 6, 3)
    np.testing.assert_array_equal(img[0, 0], [0.5, 0.5, 0.5])
    assert np.all(img[1:3, 2:4] == 0.25)
