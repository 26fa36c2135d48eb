"""A sweep's settings: each varied parameter (``KEY=v1,v2,…`` or ``KEY=start:stop:count``)
and its values, read and checked, and the limits on how many frames they make.

``count`` values of a range go from ``start`` to ``stop``, both included. A key is a key
path of the scene (mimarble/scene/keys.py, ``mimarble sweep --keys SCENE`` lists them):
``marble.K``, ``TEXTURE.K``, ``MATERIAL.K`` or ``MATERIAL.CHANNEL.K`` for K a sweepable
marble parameter (``mimarble.parameters.SWEEPABLE``), ``ramp`` or ``ramp.N``;
``camera.fov|eye|lookat|up``, ``light.N.intensity|color|position``, ``image.samples``.
A whole ramp's values hold commas, so they are separated by ``;``
(``marble.ramp=#ffffff, #000000;#ff0000, #000000``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from mimarble.scene.python_numbers import plain_number
from mimarble.scene.rules import shortened


#: Frames of one sweep at most (the product of the settings' value counts), checked
#: before any frame, or a range's values, is made. A sweep is a figure or a study: every
#: frame's scene is built and checked before the first render (10 000: 0.6 s), the
#: index — an entry a frame — is rewritten whole every INDEX_INTERVAL_S (10 000 entries:
#: ~2.6 MB), and the contact sheet holds every frame (its cells shrink past ~1 700).
#: 10 000 is a 100 × 100 grid, minutes at the README's 160²; more is several sweeps.
MAX_FRAMES = 10_000
#: Settings (``--set`` options) of one sweep at most: each is a value in every index
#: entry and a caption line in every contact-sheet cell; 16 settings of two values
#: each would already be 65 536 frames.
MAX_SETTINGS = 16


class SweepError(ValueError):
    """A sweep that cannot be run as asked (a bad setting, another sweep's folder)."""


@dataclasses.dataclass(frozen=True)
class Setting:
    """One varied parameter: its key and its values, in order."""

    key: str
    values: tuple

    @property
    def name(self) -> str:
        """The last part of the key (``period``; a ramp stop's ``ramp.2``), for labels and
        file names."""
        parts = self.key.rsplit(".", 2)
        return ".".join(parts[-2:]) if parts[-1].isdigit() and len(parts) > 1 else parts[-1]


def parse_setting(text: str) -> Setting:
    """``KEY=v1,v2,…`` or ``KEY=start:stop:count`` → a :class:`Setting`."""
    key, sep, values = text.partition("=")
    key, values = key.strip(), values.strip()
    if not sep or not key or not values:
        raise SweepError(f"--set {text!r}: write KEY=v1,v2,… or KEY=start:stop:count")
    if key.endswith(".ramp"):                # a whole ramp holds commas: ramps split at ';'
        return Setting(key, tuple(v.strip() for v in values.split(";")))
    if ":" in values:
        parts = values.split(":")
        try:
            start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
        except (ValueError, IndexError):
            raise SweepError(f"--set {text!r}: a range is start:stop:count, e.g. 1:8:4") from None
        if len(parts) != 3 or count < 1:
            raise SweepError(f"--set {text!r}: a range is start:stop:count with count ≥ 1")
        if count > MAX_FRAMES:           # before np.linspace allocates them
            raise SweepError(f"--set {text!r}: {count} values; a sweep renders at most "
                             f"{MAX_FRAMES} frames")
        return Setting(key, tuple(float(v) for v in np.linspace(start, stop, count)))
    return Setting(key, tuple(_value(v.strip()) for v in values.split(",")))


def _value(text: str):
    """A number if it is one (int when integral and written so), else the word."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        return text
    return value


#: How a sweep's settings are given, for the sentence that refuses another form.
SETTINGS_FORMS = ("a mapping {key: values} (e.g. {'marble.period': [0.5, 1, 2]}), or "
                  "--set strings ('marble.period=0.5,1,2', one or a list of them)")


def settings_from(spec) -> tuple[Setting, ...]:
    """Settings from ``--set`` strings (one string is one setting), or a mapping
    {key: values} (Python); values are numbers (NumPy's too, as the Python numbers they
    hold: mimarble/scene/python_numbers.py) or words. Any other form is a SweepError."""
    if isinstance(spec, str):
        spec = (spec,)
    if isinstance(spec, dict):
        for key, values in spec.items():
            if not isinstance(key, str):
                raise SweepError(f"setting key {shortened(repr(key), 40)} is not a string: a "
                                 f"key is a key path, e.g. 'marble.period'")
            count = (values.size if isinstance(values, np.ndarray) else
                     len(values) if isinstance(values, (list, tuple, range)) else 1)
            if count > MAX_FRAMES:       # before a range or an array is made into a list
                raise SweepError(f"--set {key}: {count} values; a sweep renders at most "
                                 f"{MAX_FRAMES} frames")
        # NumPy values (np.linspace, np.arange, np.float32(…) in a list) become Python ones:
        # JSON and the checks take them.
        return tuple(Setting(k, tuple(plain_number(x) for x in (
            np.asarray(v, dtype=object).ravel().tolist()
            if isinstance(v, (list, tuple, range, np.ndarray)) else [v])))
            for k, v in spec.items())
    if not isinstance(spec, (list, tuple)):
        raise SweepError(f"settings {shortened(repr(spec), 40)}: give {SETTINGS_FORMS}")
    for item in spec:
        if not isinstance(item, (str, Setting)):
            raise SweepError(f"setting {shortened(repr(item), 40)}: give {SETTINGS_FORMS}")
    return tuple(parse_setting(s) if isinstance(s, str) else s for s in spec)


def frame_count(settings) -> int:
    """How many frames ``settings`` make, refused (SweepError) past :data:`MAX_FRAMES` or
    :data:`MAX_SETTINGS`, with no value or with a key given twice — before any is made."""
    if len(settings) > MAX_SETTINGS:
        raise SweepError(f"{len(settings)} settings; a sweep takes at most {MAX_SETTINGS}")
    keys = [s.key for s in settings]
    for setting in settings:
        if not setting.values:
            raise SweepError(f"--set {setting.key}: no values")
        if keys.count(setting.key) > 1:
            raise SweepError(f"--set {setting.key}: given twice; give it once with every value")
    count = math.prod(len(s.values) for s in settings)
    if count > MAX_FRAMES:
        raise SweepError(f"{count} frames ({' × '.join(str(len(s.values)) for s in settings)} "
                         f"values); a sweep renders at most {MAX_FRAMES}: split it into "
                         f"several sweeps")
    return count
