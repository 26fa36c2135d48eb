"""``gallery --size N``: N is each image's longer side; the scene's aspect is kept (issue 30)."""

import pytest
from commands import mimarble_cli  # noqa: E402
from PIL import Image

import mimarble
from mimarble.tools.gallery import fitted

SCENE = """image { width 320 height 240 samples 1 }
camera { eye < 0 0 6 > lookat < 0 0 0 > up < 0 1 0 > fov 30 }
light { position < 5 5 5 > color < 1 1 1 > }
material "m" { diffuse { marble { octaves 2 } } }
sphere { center < 0 0 0 > radius 1 material "m" }
"""


@pytest.mark.parametrize("width, height, size, expected", [
    (320, 240, 160, (160, 120)),
    (240, 320, 160, (120, 160)),
    (500, 500, 160, (160, 160)),     # the paper's scenes: unchanged
    (320, 240, 640, (640, 480)),     # larger than the scene
    (1000, 3, 160, (160, 1)),        # never below one pixel
    (3, 2, 5, (5, 3)),               # 3.33 → 3
    (4, 3, 2, (2, 2)),               # 1.5 → 2: halves round up
])
def test_the_longer_side_is_the_size_and_the_aspect_is_kept(width, height, size, expected):
    scene = mimarble.scene.parse(SCENE.replace("width 320 height 240",
                                               f"width {width} height {height}"))
    image = fitted(scene, size).image
    assert (image.width, image.height) == expected


def test_gallery_renders_a_320x240_scene_at_its_aspect(tmp_path):
    (tmp_path / "wide.scene").write_text(SCENE)
    (tmp_path / "tall.scene").write_text(SCENE.replace("width 320 height 240",
                                                       "width 240 height 320"))
    result = mimarble_cli("gallery", "wide.scene", "tall.scene", "--size", "16", "-o", "g",
                          cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert Image.open(tmp_path / "g" / "wide.png").size == (16, 12)
    assert Image.open(tmp_path / "g" / "tall.png").size == (12, 16)
