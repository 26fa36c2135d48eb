"""Every kind of shape is one record (mimarble/scene/shapes.py) that every list of
kinds reads: the language, the model, the limits and both renderers' tables — and each
kind renders alike in Mitsuba and in the float64 reference."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import mimarble
from mimarble import reference
from mimarble import scene as S
from mimarble.mitsuba.translate.shapes import MITSUBA_SHAPES
from mimarble.reference.shapes import REFERENCE_SHAPES
from mimarble.scene import geometry
from mimarble.scene.grammar import grammar_text
from mimarble.scene.shapes import BY_KEYWORD, SHAPE_KINDS, kind_of
from mimarble.tools.compare import image_metrics

ROOT = Path(__file__).resolve().parent.parent
# The examples' mesh files are the beyond-spheres scenes' (models/vase.ply).
FOLDER = ROOT / "scenes" / "beyond-spheres"
MATERIAL = 'material "m" { diffuse { marble { octaves 4 } } specular { color < 0.3 0.3 0.3 > } }\n'
KINDS = [pytest.param(kind, id=kind.keyword) for kind in SHAPE_KINDS]


def example(kind, view=""):
    """The kind's example in a scene of one material (and ``view``: image, camera, light)."""
    return S.parse(view + MATERIAL + kind.example, str(FOLDER / f"{kind.keyword}.scene"))


def test_every_kind_has_its_entry_in_both_renderers_tables():
    keywords = {kind.keyword for kind in SHAPE_KINDS}
    assert set(MITSUBA_SHAPES) == keywords and set(REFERENCE_SHAPES) == keywords
    assert list(BY_KEYWORD) == [kind.keyword for kind in SHAPE_KINDS]
    assert S.SHAPE_TYPES == tuple(kind.cls for kind in SHAPE_KINDS)


@pytest.mark.parametrize("kind", KINDS)
def test_each_kind_is_a_statement_with_its_keys_and_its_grammar_rule(kind):
    assert kind.keyword in S.STATEMENTS
    assert S.BLOCK_KEYS[kind.keyword] == tuple(k.name for k in kind.keys) + ("material",)
    assert f'\n{kind.keyword}: "{kind.keyword}" "{{" _{kind.keyword}_key* "}}"' in grammar_text()


@pytest.mark.parametrize("kind", KINDS)
def test_each_kinds_example_parses_to_one_shape_of_its_kind(kind):
    scene = example(kind)
    ((shape_id, shape),) = scene.shapes()
    assert shape_id == f"{kind.keyword}_0" and kind_of(shape) is kind
    assert getattr(scene, kind.plural) == (shape,)
    assert scene.shape(shape_id) is shape


@pytest.mark.parametrize("kind", KINDS)
def test_each_kinds_limit_is_refused_in_its_words(kind):
    shape = kind.cls("m", **({"file": "a.ply"} if kind.keyword == "mesh" else {}))
    materials = {"m": S.Material("m")}
    S.Scene(materials=materials, **{kind.plural: [shape] * kind.limit.value})
    with pytest.raises(ValueError, match=f"too many {kind.plural}: a scene holds at most "
                                         f"{kind.limit.value} "):
        S.Scene(materials=materials, **{kind.plural: [shape] * (kind.limit.value + 1)})
    assert S.LIMITS[kind.limit.key] == kind.limit.value


@pytest.mark.parametrize("kind", KINDS)
def test_each_kinds_object_space_and_bounds(kind):
    (shape,) = getattr(example(kind), kind.plural)
    m = geometry.object_to_world(shape)
    assert len(m) == 4 and all(len(row) == 4 for row in m) and m[3] == (0.0, 0.0, 0.0, 1.0)
    if not kind.bounded:
        assert shape.bounds() is None and shape.corners() is None
        return
    centre, radius = shape.bounds()
    corners = shape.corners()
    assert len(corners) == 8
    if kind.keyword != "sphere":                     # a sphere's cube reaches past it
        assert all(math.dist(centre, c) <= radius * (1 + 1e-12) for c in corners)


VIEW = ('image { width 24 height 24 samples 1 }\n'
        'camera { eye < 0 2.5 6 > lookat < 0 0 0 > }\n'
        'light { position < 5 8 6 > color < 1 1 1 > }\n'
        'ambient < 0.2 0.2 0.2 >\n')


@pytest.mark.parametrize("kind", KINDS)
def test_each_kind_renders_alike_in_mitsuba_and_the_reference(llvm, kind):
    scene = example(kind, VIEW)
    expected = reference.render(scene)
    assert np.asarray(expected)[12, 12].max() > 0.05          # the shape is in the middle
    metrics = image_metrics(mimarble.render(scene), expected)
    assert metrics["psnr"] >= 100 and metrics["frac_over_1_255"] <= 0.002, metrics
