"""The mimarble scene language: text -> immutable scene model.

    >>> from mimarble import scene
    >>> s = scene.parse('material "red" { diffuse { color < 1 0 0 > } }')
    >>> s.materials["red"].diffuse
    ColorChannel(rgb=(1.0, 0.0, 0.0))

``load(path)`` and ``parse(text)`` raise :class:`SceneError` (``FILE:LINE:COL:
message``, source line, caret) for every user error. This package imports only
the standard library and lark: no mitsuba, drjit or numpy. The language is
described in docs/scene-language.md and, formally, in ``scene.lark``.
"""

from .errors import SceneError
from .model import (
    AXES,
    FIG5_RAMP,
    MARBLE_FILTERS,
    MARBLE_FUNCTIONS,
    RGB,
    Axis,
    Camera,
    Channel,
    ColorChannel,
    FrozenMap,
    Image,
    Light,
    MarbleChannel,
    MarbleFunction,
    Material,
    Pos,
    Scene,
    Sphere,
    Vec3,
)
from .parser import BLOCK_KEYS, GRAMMAR_PATH, LIMITS, STATEMENTS, load, parse

__all__ = [
    "load",
    "parse",
    "SceneError",
    "Scene",
    "Image",
    "Camera",
    "Light",
    "Material",
    "Channel",
    "ColorChannel",
    "MarbleChannel",
    "Sphere",
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
