"""Scene channels → Mitsuba textures: a constant, an image map, an expression, a marble
with its error budget, and the ids of the textures a scene shares.

Every distinct marble channel becomes one top-level texture referenced by id, so a marble
used for both ambient and diffuse is one texture, evaluated once; a channel that is one of
the file's named textures (``Scene.textures``) has its name as the id (made a valid one:
``white_veins``), the others ``texture_0``, …. Constant channels are plain ``srgb`` textures:
no noise code is generated for them.
"""

from __future__ import annotations

import re

from mimarble.parameters import checked
from mimarble.scene import model
from mimarble.texture import error_budget


def texture_dict(channel, tolerance: float | None = None, operand=None) -> dict:
    """The Mitsuba texture of one channel.

    A marble's error budget: ``tolerance`` when given, else the channel's own, else
    the plugin's default (mimarble/texture/error_budget.py). ``operand(channel)`` gives the
    texture of an expression's operand (default: its own ``texture_dict``, inline;
    ``to_mitsuba`` passes references to shared textures).
    """
    if operand is None:
        def operand(inner):
            return texture_dict(inner, tolerance)
    if isinstance(channel, model.ColorChannel):
        # Mitsuba's reflectance colours must lie in [0, 1] unless "unbounded": the language's
        # colours have no upper bound (and Python's may be negative).
        return {"type": "srgb", "color": list(channel.rgb), "unbounded": True}
    if isinstance(channel, model.ImageChannel):
        # Mitsuba's bitmap defaults, said out loud: sRGB → linear, bilinear, repeat.
        return {"type": "bitmap", "filename": channel.location, "raw": False,
                "filter_type": "bilinear", "wrap_mode": "repeat"}
    if isinstance(channel, model.EXPRESSIONS):
        out = {"type": "channel_expression", "op": type(channel).__name__.lower()}
        sides = (channel.a, channel.b) if isinstance(channel, model.Mix) else channel.operands
        out.update({f"operand_{k}": operand(c) for k, c in enumerate(sides)})
        if isinstance(channel, model.Mix):
            weight = channel.weight
            out["weight"] = weight if isinstance(weight, float) else operand(weight)
        return out
    # The plugin takes properties of the very type (as Mitsuba's do); a model built in
    # Python may hold 8.0 octaves or "true": normalised here by the table's text rule,
    # and refused in its words (ValueError) before Mitsuba sees them.
    out = {"type": "marble"}
    out.update({p.name: p.property_value(checked(p, value, text=True))
                for p, value in channel.items()})
    out["tolerance"] = float(next(t for t in (tolerance, channel.tolerance,
                                              error_budget.DEFAULT_TOLERANCE) if t is not None))
    if getattr(channel, "transform", ()):
        # The pattern's transform (mimarble/scene/transforms.py), composed in double
        # precision and rounded once: the plugin's to_world (v = scale·to_world⁻¹·p).
        import mitsuba as mi   # imported here: the module itself stays importable without it
        out["to_world"] = mi.ScalarTransform4f([list(row) for row in channel.to_world])
    return out


def marble_tolerance(scene: model.Scene, channel: model.MarbleChannel,
                     tolerance: float | None = None, gain: float = 1.0) -> float:
    """A marble's error budget in ``scene``: ``tolerance`` when given, else the channel's
    own, else the scene's default, half an 8-bit sRGB code value through its lighting
    (``error_budget.scene_tolerance``), divided by ``gain``, what the expressions it is
    in can multiply its error by (``error_budget.expression_gain``; 1 alone)."""
    if tolerance is not None:
        return tolerance
    if channel.tolerance is not None:
        return channel.tolerance
    return error_budget.scene_tolerance(scene.ambient, [light.color for light in scene.lights]) \
        / max(gain, 1.0)


def scene_marble_gains(scene: model.Scene) -> dict:
    """Each marble's largest expression gain over the channels it is in."""
    gains: dict = {}
    for material in scene.materials.values():
        volume = material.subsurface.channels() if material.subsurface is not None else {}
        for channel in (*material.channels().values(), *volume.values()):
            total = error_budget.expression_gain(channel)
            for marble in error_budget.marble_gains(channel):
                gains[marble] = max(gains.get(marble, 1.0), total)
    return gains


def named_texture_id(name: str) -> str:
    """A named texture's id: its name with every run of characters other than ASCII
    letters, digits and ``_`` made one ``_`` (``"white veins"`` → ``white_veins``), its
    first 64 characters, starting with a letter (else after ``texture_``)."""
    text = re.sub(r"[^A-Za-z0-9_]+", "_", name).strip("_")[:64]
    return text if text[:1].isalpha() else f"texture_{text}".rstrip("_")


def unused_texture(candidate: str, taken: set) -> str:
    """``candidate``, or ``candidate_2``, ``_3``, … the first not in ``taken`` (then taken)."""
    found, k = candidate, 2
    while found in taken:
        found, k = f"{candidate}_{k}", k + 1
    taken.add(found)
    return found
