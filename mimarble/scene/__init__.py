"""The mimarble scene language: text -> immutable scene model.

    >>> from mimarble import scene
    >>> s = scene.parse('material "red" { diffuse { color < 1 0 0 > } }')
    >>> s.materials["red"].diffuse
    ColorChannel(rgb=(1.0, 0.0, 0.0))

``load(path)`` and ``parse(text)`` raise :class:`SceneError` (``FILE:LINE:COL:
message``, source line, caret) for every user error. This package imports only
the standard library and lark: no mitsuba, drjit or numpy. The language is
described in docs/scene-language.md and, formally, in ``scene.lark`` with the
marble's rules, written from its parameter table (``grammar.py``).
"""

from .errors import SceneError
from .grammar import GRAMMAR_PATH
from .keywords import BLOCK_KEYS, STATEMENTS
from .parser import LIMITS, load, parse
from .shapes import SHAPE_KINDS, ShapeKind

# The model's classes load on first use (PEP 562): a scene that fails to parse is
# answered without building them (the start-up of a malformed scene's error, issue 39).
_MODEL_NAMES = frozenset({
    "AXES",
    "CHANNEL_TYPES",
    "EXPRESSIONS",
    "FIG5_RAMP",
    "MARBLE_FILTERS",
    "MARBLE_FUNCTIONS",
    "RGB",
    "Add",
    "Axis",
    "Camera",
    "Channel",
    "ColorChannel",
    "FrozenMap",
    "Image",
    "ImageChannel",
    "Environment",
    "Light",
    "MarbleChannel",
    "MarbleFunction",
    "Material",
    "Subsurface",
    "Mix",
    "Multiply",
    "Pos",
    "RectangleArea",
    "Scene",
    "Sphere",
    "SphereArea",
    "Plane",
    "Box",
    "Mesh",
    "SHAPE_TYPES",
    "SPACES",
    "Vec3",
    "replace_marbles",
    "walk",
})


def __getattr__(name: str):
    if name in _MODEL_NAMES:
        from . import model
        return getattr(model, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = [
    "load",
    "parse",
    "SceneError",
    "Scene",
    "Image",
    "Camera",
    "Environment",
    "Light",
    "RectangleArea",
    "SphereArea",
    "Material",
    "Subsurface",
    "Channel",
    "ColorChannel",
    "MarbleChannel",
    "ImageChannel",
    "Add",
    "Multiply",
    "Mix",
    "EXPRESSIONS",
    "CHANNEL_TYPES",
    "walk",
    "replace_marbles",
    "Sphere",
    "Plane",
    "Box",
    "Mesh",
    "SHAPE_TYPES",
    "SHAPE_KINDS",
    "ShapeKind",
    "SPACES",
    "Pos",
    "FrozenMap",
    "RGB",
    "Vec3",
    "MarbleFunction",
    "Axis",
    "FIG5_RAMP",
    "MARBLE_FILTERS",
    "MARBLE_FUNCTIONS",
    "AXES",
    "BLOCK_KEYS",
    "STATEMENTS",
    "LIMITS",
    "GRAMMAR_PATH",
]
