"""The scene language's keywords: its statements, and the keys each kind of block takes.

Read by the builder (which keys a block may hold), by the syntax-error wording (which
keywords to list, in what order) and by whoever documents or tests the language. The
marble block's keys are the rows of the marble's parameter table
(mimarble/parameters.py), as its grammar rules are (grammar.py), then the
language's own keys (grammar.LANGUAGE_MARBLE_KEYS: ``transform``, the pattern's
translate / rotate / scale, and ``space``).
"""

from __future__ import annotations

# The rows with a key of their own (ramp_positions is written inside the ramp block).
from mimarble.parameters import KEYWORD_PARAMETERS as PARAMETERS
from .grammar import LANGUAGE_MARBLE_KEYS
from .shapes import SHAPE_KINDS

__all__ = ["STATEMENTS", "CHANNEL_KEYWORDS", "CHANNEL_BLOCKS", "BARE_CHANNEL_KEYS", "BLOCK_KEYS"]

#: Top-level statements, in documentation order.
STATEMENTS: tuple[str, ...] = ("image", "camera", "ambient", "light", "environment", "material",
                               "texture", *(kind.keyword for kind in SHAPE_KINDS))

#: The keywords that start a channel (``texture "NAME"``: a named texture's channel).
CHANNEL_KEYWORDS: tuple[str, ...] = ("color", "marble", "image", "add", "multiply", "mix",
                                     "texture")
#: The blocks whose contents are channels (``texture``: the top-level ``texture "NAME" {
#: CHANNEL }``, which holds one).
CHANNEL_BLOCKS: tuple[str, ...] = ("ambient", "diffuse", "specular", "add", "multiply", "mix",
                                   "texture")
#: The keys followed by one channel written bare, without braces (a subsurface's:
#: ``albedo marble { … }``, ``reflectance color < 0.9 0.9 0.9 >``, ``density texture "veins"``).
BARE_CHANNEL_KEYS: tuple[str, ...] = ("albedo", "reflectance", "density")

#: The keywords allowed in each kind of block (keyed by the block's rule name: an image
#: map is ``image_map``, written ``image { file "…" }`` like the image statement).
BLOCK_KEYS: dict[str, tuple[str, ...]] = {
    "image": ("width", "height", "samples", "background"),
    "camera": ("eye", "lookat", "up", "fov"),
    "light": ("position", "color", "area"),
    "area": ("axis1", "axis2", "radius", "samples"),
    "environment": ("file", "color", "intensity", "rotate"),
    "material": ("ambient", "diffuse", "specular", "shininess", "subsurface"),
    "subsurface": ("albedo", "reflectance", "mean_free_path", "density", "ior", "grid"),  # BARE_CHANNEL_KEYS: a channel
    "ambient": CHANNEL_KEYWORDS,
    "diffuse": CHANNEL_KEYWORDS,
    "specular": CHANNEL_KEYWORDS,
    "add": CHANNEL_KEYWORDS,
    "multiply": CHANNEL_KEYWORDS,
    "mix": CHANNEL_KEYWORDS + ("weight",),
    "image_map": ("file",),
    "texture": CHANNEL_KEYWORDS,                     # texture "NAME" { CHANNEL }
    "marble": tuple(p.name for p in PARAMETERS) + LANGUAGE_MARBLE_KEYS,
    "transform": ("translate", "rotate", "scale"),   # marble, box, mesh: transforms.STEPS
    **{kind.keyword: tuple(key.name for key in kind.keys) + ("material",)
       for kind in SHAPE_KINDS},
}

#: Keys whose value is the word true or false (a mesh's smooth, a subsurface's grid).
SWITCH_KEYS = ("smooth", "grid")
