"""The keys of a scene, in one registry: every value a user can tune, by its key path —
what ``mimarble sweep --set KEY=…`` varies, ``mimarble sweep --keys SCENE`` lists, the
studio's controls are named by, and a saved file's edits name (rewrite.py).

    >>> keys = scene_keys(scene)                 # {path: Key}, grouped as the scene names things
    >>> keys["carrara.period"].parameter.above   # its row of the parameter table
    >>> with_value(scene, "marble.ramp.2", "#d0d0d0")

The families (key_families.py): every marble ``marble.K``; a named texture's
``carrara.K``; a material's ``stone.K`` and a channel's ``stone.diffuse.K`` (K a
sweepable marble parameter, ``ramp`` or ``ramp.N``); ``camera.fov|eye|lookat|up``;
``light.N.intensity|color|position``; ``image.samples``; ``environment.intensity|rotate``. The value syntax is
key_values.py's. **A new family** is a :class:`~mimarble.scene.key_families.KeyFamily`
subclass and one entry in :data:`FAMILIES`.
"""

from __future__ import annotations

from .key_families import (CameraKeys, EnvironmentKeys, ImageKeys, Key, KeyFamily, LightKeys,
                           MarbleKeys)
from .key_values import KeyPathError, read

__all__ = ["FAMILIES", "Key", "KeyFamily", "KeyPathError", "scene_keys", "key_of",
           "with_value", "keys_listing"]

#: Every family of keys, in the order they are listed.
FAMILIES: tuple[KeyFamily, ...] = (MarbleKeys(), CameraKeys(), LightKeys(), ImageKeys(),
                                   EnvironmentKeys())


def scene_keys(scene) -> dict[str, Key]:
    """Every key of ``scene`` by its path, family by family, each grouped as the scene
    names things (a path two things would take — a material named ``a.diffuse`` and
    material ``a``'s diffuse channel — is the first's)."""
    keys: dict[str, Key] = {}
    for family in FAMILIES:
        for key in family.keys(scene):
            keys.setdefault(key.path, key)
    return keys


def key_of(scene, path: str) -> Key:
    """The key ``path`` of ``scene``; :class:`KeyPathError` (one sentence: the scene's keys
    in short, grouped, and the closest one) when it has none."""
    if isinstance(path, str):
        for family in FAMILIES:           # the first family's, as scene_keys keeps it
            key = family.find(scene, path)
            if key is not None:
                return key
    keys = scene_keys(scene)
    import difflib
    from .rules import shortened
    shown = shortened(repr(path), 60) if not isinstance(path, str) else shortened(path, 60)
    close = difflib.get_close_matches(path, _candidates(keys, path), n=1) \
        if isinstance(path, str) else []
    said = next((d for d in (f.diagnosis(scene, path) for f in FAMILIES) if d), None) \
        if isinstance(path, str) else None
    said = said or "unknown key" + (f" (did you mean {close[0]}?)" if close else "")
    return _unknown(scene, keys, f"{shown}: {said}")


#: Keys compared with an unknown one for the closest at most (difflib compares each: a scene
#: of 10 000 textures has 200 000 keys).
MAX_CANDIDATES = 5000


def _candidates(keys: dict, path: str) -> list[str]:
    """The keys worth comparing with ``path``: all of a small scene's; of a large one's,
    those that share its first or its last part."""
    if len(keys) <= MAX_CANDIDATES:
        return list(keys)
    first, last = path.split(".", 1)[0], path.rsplit(".", 1)[-1]
    return [k for k in keys if k.startswith(first + ".") or k.endswith("." + last)][
        :MAX_CANDIDATES]


def _unknown(scene, keys: dict, said: str):
    by_family: dict[KeyFamily, list] = {}
    for key in keys.values():
        by_family.setdefault(key.family, []).append(key)
    parts = [entry for family, found in by_family.items() for entry in family.summary(found)]
    raise KeyPathError(f"{said}; this scene's keys: {'; '.join(parts) or 'none'} "
                       f"(mimarble sweep --keys SCENE lists each)")


def with_value(scene, path: str, value):
    """The scene with the value at key path ``path`` set to ``value`` (text in the value
    syntax, key_values.py, or a Python value); :class:`KeyPathError` for a key the scene
    does not have or a value it cannot take there — by the key's row, or by the scene
    model's rule (its constructors check every value by the parser's rules: the sample
    limit, a fov not 0 in single precision, a camera's up not along its view), the
    message starting with the key path."""
    key = key_of(scene, path)
    try:
        return key.family.apply(scene, key, read(path, key.parameter, value, key.stop))
    except KeyPathError:
        raise
    except (TypeError, ValueError) as e:       # the model's rule, in the parser's words
        raise KeyPathError(f"{path}: {e}") from None


def keys_listing(scene) -> str:
    """Every key with its current value and what it takes, grouped: ``mimarble sweep
    --keys``'s output."""
    lines, group = [], None
    keys = list(scene_keys(scene).values())
    width = max((len(k.path) for k in keys), default=0)
    for key in keys:
        if key.group != group:
            group = key.group
            count = f" ({key.count} marbles)" if key.count > 1 else ""
            lines.append(f"{group}{count}")
        p = key.parameter
        what = "a ramp stop: [position] colour" if key.stop is not None else \
            "a ramp: [p] colour, [p] colour, …" if p.kind == "colours" else \
            f"{p.kind}, {p.requirement}"
        lines.append(f"  {key.path:<{width}}  {key.text}  ({what})")
    return "\n".join(lines)
