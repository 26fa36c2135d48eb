"""The translucent Fig. 11 scenes (scenes/translucent/): they render in path mode, and whitted
mode refuses them at their subsurface, in one sentence."""

from pathlib import Path

import numpy as np
import pytest

import mimarble
from mimarble import scene as S
from mimarble.scene_edits import resized

ROOT = Path(__file__).resolve().parent.parent
SCENES = sorted((ROOT / "scenes" / "translucent").glob("*.scene"))


def test_each_fig11_marble_has_a_translucent_twin():
    assert [p.stem for p in SCENES] == [f"fig11{k}-translucent" for k in "abcd"]
    for path in SCENES:
        twin, original = S.load(path), S.load(ROOT / "scenes" / f"{path.stem[:6]}.scene")
        albedo = twin.materials["translucent marble"].subsurface.albedo
        marble = original.materials["marble"].diffuse
        for key in ("scale", "period", "distortion", "octaves", "function", "axis"):
            assert getattr(albedo, key) == getattr(marble, key), (path.stem, key)


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_a_translucent_scene_renders_in_path_mode(llvm, path):
    image = np.asarray(mimarble.render(resized(S.load(path), 16), mode="path", spp=4))
    assert image.shape == (16, 16, 3) and np.isfinite(image).all() and image.max() > 0


def test_whitted_mode_refuses_a_translucent_scene_at_its_subsurface(llvm):
    path = SCENES[0]
    with pytest.raises(ValueError) as info:
        mimarble.render(resized(S.load(path), 16))
    line = next(k for k, text in enumerate(path.read_text().splitlines(), 1) if "subsurface" in text
                and not text.lstrip().startswith("//"))
    assert str(info.value).startswith(f"{path}:{line}:") and "--mode path" in str(info.value)
