"""The studio's controls: every key of the scene as a JSON-able control, from the key registry.

Nothing here lists parameters: the keys are the scene's key registry's
(``mimarble.scene.keys.scene_keys``: key paths grouped as the scene names things), each
with its row of the parameter table (``mimarble/parameters.py``: kind, default, bounds,
choices, doc, the slider's span), so a new parameter or key family appears in the page
without a line here. Added: the view (mode, image width and height), which the file
does not hold.

A control (a dict):

============== ===========================================================================
key, label     the key path (what ``StudioSession.edit`` takes; the label shows it, as
               ``mimarble sweep --set`` names it)
group          the key's group (``every marble``, ``material "stone", diffuse``, ``camera``)
name           the parameter's name (``period``): in the control's accessible name
kind           ``number``, ``integer``, ``choice``, ``boolean``, ``colours`` (a whole
               ramp), ``stop`` (a ramp stop), ``vector``, ``colour``
value          the current value, JSON: numbers, strings, booleans; a vector ``[x, y, z]``;
               a colour ``"#rrggbb"``; a ramp ``{"colors": [...], "positions": [...],
               "explicit": bool}``; a stop ``{"position": p, "color": "#rrggbb"}``
text           the current value in the value syntax (exact; ``edit`` takes it back)
default        the table's default (JSON as ``value``), or None
min, max       a number's bounds (None: open), ``exclusive_min``/``exclusive_max``;
               an integer's bounds
slider         ``[lo, hi]`` a slider spans (the row's ``slider``, else its bounds, else
               a span around the value: 0 or its lower bound to 4 × the larger of the
               value and the default, at least 1) — a typed value may lie outside it
step           a slider's step: 1 for integers, else the span / 1000
choices        a choice's words
structural     an edit records new kernels (the page says "compiling")
doc            the row's documentation
stop, count    a ramp stop's N; how many marbles the key sets
============== ===========================================================================

Marble groups that set the same marbles as an earlier group (a material with one
marble channel, ``every marble`` of a scene with one material) are left out: each
marble's controls appear once per distinct selection.
"""

from __future__ import annotations

import math

from mimarble.parameters import (BY_NAME, CHOICE, COLOURS, DIFFERENTIABLE, INTEGER, NUMBER,
                                 Parameter)
from mimarble.ramp_text import hex_of_linear
from mimarble.scene.key_families import MarbleKeys, evenly_spaced
from mimarble.scene.key_values import COLOUR, VECTOR
from mimarble.scene.keys import scene_keys

#: The view's rows: the modes the studio renders in, the image's width and height.
MODE = Parameter("mode", CHOICE, "whitted", choices=("whitted", "path"),
                 doc="whitted: the paper's ray tracer (point lights, no secondary rays); "
                     "path: Mitsuba's path tracer (translucent marble, soft light).")
#: The sizes the view may be set to: a frame's float64 sums are 24 bytes a pixel, so
#: 2048² holds 100 MB (a scene file's own size is rendered as it is; only the view's
#: edits are held to this, checked before anything is allocated).
VIEW_SIZE = (16, 2048)
WIDTH = Parameter("width", INTEGER, None, bounds=VIEW_SIZE, slider=(64, 1024),
                  doc="The image's width in pixels (the view: not saved).")
HEIGHT = Parameter("height", INTEGER, None, bounds=VIEW_SIZE, slider=(64, 1024),
                   doc="The image's height in pixels (the view: not saved).")


def controls(scene, mode: str) -> dict:
    """``{"groups": [{"name", "kind", "controls": [...]}, …]}`` for ``scene`` shown in
    ``mode`` (module docstring): the key registry's groups in its order, then ``view``."""
    groups: dict[str, dict] = {}
    seen_selections = set()
    skipped = set()
    for key in scene_keys(scene).values():
        if key.group in skipped:
            continue
        if key.group not in groups:
            if isinstance(key.family, MarbleKeys):
                selection = tuple(_identity(m) for m in key.family.selected(scene, key.target))
                if selection in seen_selections:
                    skipped.add(key.group)
                    continue
                seen_selections.add(selection)
            groups[key.group] = {"name": key.group, "kind": _group_kind(key),
                                 "controls": []}
        groups[key.group]["controls"].append(control(key.path, key.group, key.parameter,
                                                     key.value, key.text, key.stop,
                                                     key.count))
    view = {"name": "view", "kind": "view", "controls": [
        control("mode", "view", MODE, mode, mode, structural=True),
        control("image.width", "view", WIDTH, scene.image.width, str(scene.image.width),
                structural=True),
        control("image.height", "view", HEIGHT, scene.image.height, str(scene.image.height),
                structural=True)]}
    return {"groups": list(groups.values()) + [view]}


def control(path: str, group: str, row: Parameter, value, text: str, stop: int | None = None,
            count: int = 1, structural: bool | None = None) -> dict:
    """One control (module docstring) of key ``path`` whose row is ``row``."""
    kind = row.kind
    if kind == COLOURS:
        kind = "stop" if stop is not None else "colours"
    out = {"key": path, "label": path, "group": group, "name": row.name, "kind": kind,
           "value": _json(kind, value), "text": text,
           "default": None if row.default is None or kind == "stop" else
           _json(kind, row.default if kind != "colours" else (row.default, None)),
           "doc": row.doc, "stop": stop, "count": count,
           "structural": _structural(row, kind) if structural is None else structural}
    if row.kind in (NUMBER, INTEGER):
        out.update(_range(row, value))
    if row.kind == CHOICE:
        out["choices"] = list(row.choices)
    return out


def _structural(row: Parameter, kind: str) -> bool:
    """Whether an edit makes new kernels: a whole ramp (its size may change) and a marble
    row that is not differentiable (octaves, function, …); not a ramp stop, nor a key of
    the camera, a light or the image (their values are not in the traced code)."""
    if kind in ("colours", "stop"):
        return kind == "colours"
    return BY_NAME.get(row.name) is row and row.role != DIFFERENTIABLE


def _range(row: Parameter, value) -> dict:
    """``min``, ``max``, ``exclusive_min``, ``exclusive_max``, ``slider``, ``step``."""
    if row.kind == INTEGER:
        lo, hi = row.bounds
        low, high = row.slider or (lo, hi)
        return {"min": lo, "max": hi, "exclusive_min": False, "exclusive_max": False,
                "slider": [low, high], "step": 1}
    lo = row.above if row.above is not None else row.at_least
    hi = row.below if row.below is not None else row.at_most
    if row.slider is not None:
        low, high = row.slider
    elif lo is not None and hi is not None:
        low, high = lo, hi
    else:
        scale = max(abs(float(value)) if _finite(value) else 0.0,
                    abs(float(row.default)) if _finite(row.default) else 0.0, 0.25)
        low = lo if lo is not None else 0.0 if not _finite(value) or value >= 0 else -4 * scale
        high = hi if hi is not None else 4 * scale
    return {"min": lo, "max": hi, "exclusive_min": row.above is not None,
            "exclusive_max": row.below is not None, "slider": [low, high],
            "step": (high - low) / 1000}


def _finite(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)


def _json(kind: str, value):
    """A key's value as JSON (module docstring)."""
    if value is None:
        return None
    if kind == "colours":
        colours, positions = value
        return {"colors": [hex_of_linear(c) for c in colours],
                "positions": list(positions if positions is not None
                                  else evenly_spaced(len(colours))),
                "explicit": positions is not None}
    if kind == "stop":
        position, colour = value
        return {"position": position, "color": hex_of_linear(colour)}
    if kind == COLOUR:
        return hex_of_linear(value)
    if kind == VECTOR:
        return [float(x) for x in value]
    return value


def _identity(marble):
    """A marble of the file by its position (the registry's identity of a marble)."""
    return ("pos", marble.pos) if marble.pos is not None else ("id", id(marble))


def _group_kind(key) -> str:
    """``marble``, ``camera``, ``light`` or ``image``: what the page draws for it."""
    if isinstance(key.family, MarbleKeys):
        return "marble"
    return key.path.split(".", 1)[0]
