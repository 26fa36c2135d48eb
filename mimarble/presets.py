"""The marble library: named marbles read from ``presets.toml``, each checked by the parameter table.

A preset is data, not code: a table in mimarble/presets.toml (real stones, and POV-Ray's
``textures.inc`` marbles said in this marble's terms) holding a title, a line on what the
stone is, where its colours come from, and values for rows of the marble's parameter table
(mimarble/parameters.py). Every value is checked by its row when the file is read, so a
broken entry is one :class:`PresetError` that names it (``presets.toml: [carrara]: period
must be a finite number, found 'x'``).

A preset is resolved where it is read — the scene builder (``marble { preset "carrara"
period 1.5 }``) and the ``marble`` plugin's properties (``"preset": "carrara"``) — into
plain parameters: the scene model, the translator and the reference tracer never see the
name. Overrides replace the preset's values; a ramp given replaces the preset's ramp with
its positions.

The standard library only (``tomllib``; ``tomli`` before Python 3.11): the command line
(``mimarble presets``) and the scene package read it before Dr.Jit loads.
"""

from __future__ import annotations

import dataclasses
import functools
import re
from pathlib import Path
from typing import Any

from mimarble.parameters import (BY_NAME, COLOURS, ParameterError, checked,
                                 parse_positioned_ramp, ramp_count_problem)

__all__ = ["PRESETS_PATH", "Preset", "PresetError", "PRESET_ROWS", "read_presets", "presets",
           "preset", "preset_values", "unknown_preset_sentence", "resolved", "block_text"]

#: The library's file, in the package.
PRESETS_PATH = Path(__file__).with_name("presets.toml")
#: The rows of the parameter table a preset may set: all but the rendering choices
#: (``filter``, ``tolerance``), which are the scene's, not the stone's.
PRESET_ROWS: tuple[str, ...] = tuple(name for name in BY_NAME
                                     if name not in ("filter", "tolerance"))
#: A preset's descriptive fields: required, then optional.
_TEXT_FIELDS, _OPTIONAL_TEXT = ("title", "about", "colours"), ("povray",)
#: A preset's name: what the scene language and the plugin write.
_NAME = re.compile(r"[a-z][a-z0-9_]{0,39}")


class PresetError(ParameterError):
    """A preset that does not exist, or an entry of the library that is broken: one
    sentence that names it."""


@dataclasses.dataclass(frozen=True)
class Preset:
    """One named marble.

    ============  ==========================================================
    ``name``      the key (``carrara``): what a scene or a dict writes
    ``title``     the name shown in the gallery (``Carrara (Bianco Carrara)``)
    ``about``     one line on what the stone is
    ``colours``   where the ramp's colours come from
    ``povray``    POV-Ray's name (``White_Marble``), or None for a real stone
    ``values``    the parameter table's rows it sets, checked: name → value as the
                  row holds it (``ramp``: RGB triples; ``ramp_positions`` when the
                  ramp string gives positions)
    ``written``   the same rows as the file writes them (``ramp``: its string)
    ============  ==========================================================
    """

    name: str
    title: str
    about: str
    colours: str
    povray: str | None
    values: dict[str, Any]
    written: dict[str, Any]


def _checked(parameter, value, context: str):
    """``value`` checked by its row of the parameter table, or a :class:`PresetError`."""
    try:
        return checked(parameter, value, context)
    except ParameterError as e:
        raise PresetError(str(e)) from None


def _entry(name: str, table, where: str) -> Preset:
    """One table of the file as a :class:`Preset`, every value checked by its row."""
    context = f"{where}: [{name}]"
    if not _NAME.fullmatch(name):
        raise PresetError(f"{context}: a preset's name is lower-case letters, digits and "
                          f"'_', starting with a letter (at most 40)")
    if not isinstance(table, dict):
        raise PresetError(f"{context}: a preset is a table of values, found {table!r:.40}")
    unknown = sorted(set(table) - set(PRESET_ROWS) - set(_TEXT_FIELDS) - set(_OPTIONAL_TEXT))
    if unknown:
        key = unknown[0]
        why = "a rendering choice, the scene's, not a preset's" if key in BY_NAME else \
            f"not a key of a preset (text: {', '.join(_TEXT_FIELDS + _OPTIONAL_TEXT)}; " \
            f"values: {', '.join(PRESET_ROWS)})"
        raise PresetError(f"{context}: '{key}' is {why}")
    for key in _TEXT_FIELDS + _OPTIONAL_TEXT:
        if key in _TEXT_FIELDS and key not in table:
            raise PresetError(f"{context}: no '{key}' (a preset has {', '.join(_TEXT_FIELDS)})")
        if key in table and not (isinstance(table[key], str) and table[key].strip()):
            raise PresetError(f"{context}: '{key}' must be non-empty text")
    values: dict[str, Any] = {}
    for row in PRESET_ROWS:
        if row not in table:
            continue
        p = BY_NAME[row]
        if p.kind == COLOURS:           # the ramp string: colours, maybe positions
            try:
                colours, positions = parse_positioned_ramp(table[row], row)
            except ParameterError as e:
                raise PresetError(f"{context}: {e}") from None
            values[row] = _checked(p, colours, context)
            if positions is not None:
                if "ramp_positions" in table:
                    raise PresetError(f"{context}: give the ramp's positions in the ramp "
                                      f"string or in ramp_positions, not both")
                values["ramp_positions"] = _checked(BY_NAME["ramp_positions"], positions,
                                                    context)
        elif row == "ramp_positions" and row in values:
            continue
        else:
            values[row] = _checked(p, table[row], context)
    problem = ramp_count_problem(values.get("ramp", BY_NAME["ramp"].default),
                                 values.get("ramp_positions"))
    if problem:
        raise PresetError(f"{context}: {problem}")
    return Preset(name, table["title"].strip(), table["about"].strip(),
                  table["colours"].strip(), table.get("povray"), values,
                  {row: table[row] for row in PRESET_ROWS if row in table})


def read_presets(text: str, where: str = "presets.toml") -> dict[str, Preset]:
    """The presets of a library's ``text`` (TOML), by name, in the file's order; a
    :class:`PresetError` naming ``where`` and the entry at fault."""
    # Imported here, as difflib below: every render imports this module (the plugin's
    # ``preset``), and only a preset used needs the reader.
    try:                                    # Python ≥ 3.11
        import tomllib
    except ModuleNotFoundError:             # pragma: no cover - Python 3.10
        import tomli as tomllib
    try:
        tables = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise PresetError(f"{where}: not valid TOML: {e}") from None
    return {name: _entry(name, table, where) for name, table in tables.items()}


@functools.lru_cache(maxsize=None)
def presets() -> dict[str, Preset]:
    """The package's presets (mimarble/presets.toml), read and checked once a process."""
    return read_presets(PRESETS_PATH.read_text(encoding="utf-8"), PRESETS_PATH.name)


def unknown_preset_sentence(name) -> str:
    """The sentence for a preset that does not exist, naming the closest one (difflib,
    case-insensitive) or, when none is close, pointing at the list."""
    import difflib
    names = list(presets())
    shown = str(name) if len(str(name)) <= 40 else str(name)[:37] + "..."
    close = difflib.get_close_matches(str(name).lower(), names, n=1, cutoff=0.6)
    hint = f"did you mean '{close[0]}'?" if close else f"the presets are {', '.join(names)}"
    return f"no preset '{shown}'; {hint} (`mimarble presets` lists them)"


def preset(name) -> Preset:
    """The preset called ``name``, or a :class:`PresetError` naming the closest one."""
    library = presets()
    if not isinstance(name, str) or name not in library:
        raise PresetError(unknown_preset_sentence(name))
    return library[name]


def preset_values(name) -> dict[str, Any]:
    """The parameter values of preset ``name`` (a copy): rows it does not set are absent."""
    return dict(preset(name).values)


def resolved(name, overrides: dict[str, Any]) -> dict[str, Any]:
    """Preset ``name``'s values with ``overrides`` (checked values, by row) on top: a
    ramp given replaces the preset's ramp and its positions together (its own positions,
    if it has any, come in ``overrides["ramp_positions"]``)."""
    values = preset_values(name)
    if "ramp" in overrides:
        values.pop("ramp_positions", None)
    values.update(overrides)
    return values


def block_text(preset: Preset) -> str:
    """The preset's values in the scene language, as a marble block's keys in the file's
    words (``scale 1.5 period 0.8 … ramp { 0 #7d848b 0.08 #a3a8ad … }``): what to write
    to start from it without the name."""
    words = []
    for row, value in preset.written.items():
        if row == "ramp":
            items = []
            for item in value.split(","):
                tokens = item.split()
                colour = tokens[-1:] if tokens[-1].startswith("#") else \
                    ["<", *tokens[-3:], ">"]
                items.append(" ".join(tokens[:len(tokens) - (1 if tokens[-1].startswith("#")
                                                              else 3)] + colour))
            words.append("ramp { " + "  ".join(items) + " }")
        elif isinstance(value, bool):
            words.append(f"{row} {'true' if value else 'false'}")
        else:
            words.append(f"{row} {value:g}" if isinstance(value, float) else f"{row} {value}")
    return " ".join(words)
