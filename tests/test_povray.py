"""The POV-Ray peer (mimarble/tools/povray.py): a comparable scene, timed when POV-Ray is installed."""

import shutil

import pytest

import mimarble
from mimarble.tools import povray
from mimarble.scene.edits import resized


def test_scene_text_carries_the_scene():
    scene = mimarble.scene.load("scenes/fig11a.scene")
    text = povray.scene_text(scene, 500)
    assert text.startswith("#version 3.7;")
    assert "location <0.0, 0.0, -9.0>" in text               # z mirrored: left-handed
    assert "angle 30.0" in text and "ambient_light rgb <0.2, 0.2, 0.2>" in text
    assert "sphere { <0.0, 0.0, -0.0>, 2.0" in text
    assert "marble turbulence" in text and text.count(" rgb <1.0, ") >= 8   # the 8-colour ramp
    assert "specular 0.3" in text


@pytest.mark.skipif(shutil.which("povray") is None, reason="POV-Ray is not installed")
def test_povray_is_timed():
    scene = resized(mimarble.scene.load("scenes/fig11a.scene"), 64)
    result = povray.time_povray(scene, 64, repeats=1)
    assert result["trace_s"] >= 0 and result["process_s"] > 0
    assert "POV-Ray" in result["version"]
