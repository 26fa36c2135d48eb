"""The marble's parameters, declared once: name, type, default, range, and role.

Everything that reads or writes a marble parameter is made from :data:`PARAMETERS`:
the scene language's grammar and its checks (``mimarble/scene/builder.py``), the
scene model's :class:`~mimarble.scene.model.MarbleChannel`, the ``marble`` plugin's
reading, validation and ``mi.traverse`` keys (:meth:`MarbleParameters.from_properties`,
``mimarble/mitsuba/plugins/marble.py``), the translator's texture dict, the sweep keys and the values a
sweep changes in place (``mimarble/sweeps/run.py``) and the command line's choices. A new
parameter is one row here plus the code that uses it.

Roles:

* ``differentiable``: an opaque Dr.Jit value the plugin exposes to ``mi.traverse`` as
  differentiable; a new value (a sweep's, an optimiser's) reuses the compiled kernel.
* ``structural``: a Python value that shapes the traced kernel; a new value traces a
  new one. ``traversed`` ones are also in ``mi.traverse`` (not differentiable).

How colours and ramps are written as text (``#rrggbb``, ``"[p] r g b, …"``) is
mimarble/ramp_text.py; its names are re-exported here. This module imports neither Lark
nor Dr.Jit: the command line reads it before either is loaded.
"""

from __future__ import annotations

import dataclasses
import re
import math
import struct
from typing import Any

from mimarble.contract import FLT_MAX, FLT_MIN_NORMAL, MAX_OCTAVES
# Colours and ramps as text (the form of the colours and positions rows), re-exported.
from mimarble.ramp_text import (HEX_FORM, MAX_RAMP_COLOURS, ParameterError, hex_colour,
    hex_colour_problem, parse_positioned_ramp, parse_positions, parse_ramp, positions_problem,
    positions_text, ramp_count_problem, ramp_text, srgb_to_linear)

__all__ = ["Parameter", "ParameterError", "MarbleParameters", "PARAMETERS", "BY_NAME",
           "SWEEPABLE", "IN_PLACE", "RENAMED", "FUNCTIONS", "AXES", "FILTERS", "FIG5_RAMP",
           "MAX_OCTAVES", "MAX_RAMP_COLOURS", "parse_ramp", "parse_positioned_ramp",
           "ramp_text", "positions_text", "positions_problem", "parameter_table",
           "single_precision", "HEX_FORM", "hex_colour", "hex_colour_problem", "srgb_to_linear",
           "MAX_LACUNARITY", "POSITIONS", "KEYWORD_PARAMETERS", "parse_positions",
           "ramp_count_problem"]

#: The stripe functions (mimarble/texture/stripes.py), in the order of the documentation: the
#: paper's three, then POV-Ray's triangle and ramp (sawtooth) waves.
FUNCTIONS: tuple[str, ...] = ("abs_sine", "sine", "cosine", "triangle", "sawtooth")
#: The coordinate axes a marble may run along.
AXES: tuple[str, ...] = ("x", "y", "z")
#: How a marble filters the pixel's footprint in Mitsuba (mimarble/texture/filters.py).
FILTERS: tuple[str, ...] = ("none", "bandlimit", "prefilter")
#: The paper's Fig. 5 ramp: 8 colours from red <1 0 0> to orange <1 0.875 0>.
FIG5_RAMP: tuple[tuple[float, float, float], ...] = tuple((1.0, k / 8.0, 0.0) for k in range(8))
# MAX_OCTAVES (mimarble.contract): the largest octave count accepted (octaves past 25
# cost nothing: mimarble/texture/noise.py); MAX_RAMP_COLOURS (mimarble.ramp_text): the
# most colours a ramp may hold.
#: The largest lacunarity: the finest of 64 octaves, at frequency λ^63, keeps every point
#: the noise sees (|v| < 2^24 after its wrap, mimarble/texture/noise.py) within float32's range:
#: 3^63·2^24 < 2^124, where 3.2^63 would overflow to infinity.
MAX_LACUNARITY = 3.0

NUMBER, INTEGER, CHOICE, BOOLEAN, COLOURS = "number", "integer", "choice", "boolean", "colours"
#: Numbers in [0, 1], non-decreasing, one for each ramp colour: where the colours sit.
POSITIONS = "positions"
DIFFERENTIABLE, STRUCTURAL = "differentiable", "structural"


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One marble parameter. ``kind`` is number, integer, choice, boolean, colours or
    positions. ``keyword``: a key of its own in the scene language; ``ramp_positions`` is
    not, its values are written inside the ``ramp`` block (and the plugin's ramp string)."""

    name: str
    kind: str
    default: Any
    doc: str
    role: str = STRUCTURAL
    traversed: bool = False
    above: float | None = None          # number: > above
    at_least: float | None = None       # number: ≥ at_least
    below: float | None = None          # number: < below
    at_most: float | None = None        # number: ≤ at_most
    bounds: tuple[int, int] | None = None   # integer: lo..hi; colours: count lo..hi
    choices: tuple[str, ...] = ()       # choice
    keyword: bool = True
    #: number, integer: the span a slider covers (the studio's controls), where the range
    #: is open or wider than a user tunes in; a value outside it is typed. None: the range.
    slider: tuple[float, float] | None = None

    @property
    def in_place(self) -> bool:
        """Changed through ``mi.traverse`` without a new kernel."""
        return self.role == DIFFERENTIABLE

    @property
    def is_traversed(self) -> bool:
        return self.in_place or self.traversed

    @property
    def requirement(self) -> str:
        """What a value must be, in words (``must be > 0``)."""
        if self.kind == NUMBER:
            lower = f"> {self.above:g}" if self.above is not None else \
                f"≥ {self.at_least:g}" if self.at_least is not None else None
            upper = f"< {self.below:g}" if self.below is not None else \
                f"≤ {self.at_most:g}" if self.at_most is not None else None
            if lower or upper:
                return "must be " + " and ".join(b for b in (lower, upper) if b)
            return "must be a finite number"
        if self.kind == INTEGER:
            return f"must be an integer in {self.bounds[0]}..{self.bounds[1]}"
        if self.kind == CHOICE:
            return f"must be one of {_listed(self.choices)}"
        if self.kind == BOOLEAN:
            return "must be true or false"
        if self.kind == POSITIONS:
            return "must be numbers in [0, 1], non-decreasing, one for each ramp colour"
        return f"must hold {self.bounds[0]}..{self.bounds[1]} finite colours"

    def check(self, value, text: bool = False):
        """``value`` as this parameter holds it (float, int, str, bool or a tuple of RGB
        tuples), or :class:`ParameterError`. Strings and sequences are taken for colours
        (:func:`parse_ramp`). A value read from text (``text``: the scene language, a
        sweep's ``--set``) may also be a word for a boolean (``true``) and a number with
        no fraction for an integer; a plugin's properties must have the type itself, as
        Mitsuba's own plugins require. A number's problem names the bound it misses."""
        if self.kind == COLOURS:
            colours = parse_ramp(value, self.name)
            lo, hi = self.bounds
            if not lo <= len(colours) <= hi:
                raise ParameterError(f"{self.name} has {len(colours)} colours; it holds "
                                     f"{lo}..{hi}")
            return colours
        if self.kind == POSITIONS:
            positions = parse_positions(value, self.name)
            problem = positions_problem(positions, self.name)
            if problem:
                raise ParameterError(problem[1])
            return positions
        if self.kind == CHOICE:
            if value not in self.choices:
                raise ParameterError(f"{self.name} {self.requirement}")
            return str(value)
        if self.kind == BOOLEAN:
            if not (isinstance(value, bool) or text and value in ("true", "false")):
                raise ParameterError(f"{self.name} {self.requirement}")
            return value in (True, "true")
        if self.kind == INTEGER and not text and not (isinstance(value, int)
                                                      and not isinstance(value, bool)):
            raise ParameterError(f"{self.name} {self.requirement}")
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value):
            raise ParameterError(f"{self.name} must be a finite number")
        if self.kind == INTEGER:
            if not float(value).is_integer():
                raise ParameterError(f"{self.name} must be an integer")
            lo, hi = self.bounds
            if not lo <= value <= hi:
                raise ParameterError(f"{self.name} must be in {lo}..{hi}")
            return int(value)
        # The bound holds for the value and for the float32 the Mitsuba path holds it in
        # (scale 1e-40 is > 0, but 0 in single precision: a renderer would divide by it).
        for held, how in ((value, ""), (single_precision(value), " in single precision "
                                                                 "(the renderer's)")):
            if (self.above is not None and not held > self.above) or \
                    (self.at_least is not None and not held >= self.at_least) or \
                    (self.below is not None and not held < self.below) or \
                    (self.at_most is not None and not held <= self.at_most):
                raise ParameterError(f"{self.name} {self.requirement}{how}")
        return float(value)

    def property_value(self, value):
        """The value as a Mitsuba property (``mi.load_dict``): colours as ``"r g b, …"``,
        positions as ``"p, p, …"``."""
        if self.kind == COLOURS:
            return ramp_text(value)
        return positions_text(value) if self.kind == POSITIONS else value


# Subnormal values read back from the renderer's float32 as zero (measured: the plugin
# read ``scale 1e-40`` back as 0).
_FLT_MIN_NORMAL = FLT_MIN_NORMAL
_FLT_MAX = FLT_MAX


def single_precision(value: float) -> float:
    """``value`` as the renderer's float32 holds it: rounded to the nearest float32, a
    subnormal one flushed to (signed) zero as the JIT's arithmetic does; past float32's
    range, the value itself (its sign and size are what a bound compares)."""
    if not abs(value) <= _FLT_MAX:
        return float(value)
    rounded = struct.unpack("f", struct.pack("f", value))[0]
    return math.copysign(0.0, rounded) if abs(rounded) < _FLT_MIN_NORMAL else rounded


def _listed(words) -> str:
    return ", ".join(words[:-1]) + " or " + words[-1] if len(words) > 1 else "".join(words)


PARAMETERS: tuple[Parameter, ...] = (
    Parameter("scale", NUMBER, 1.0, above=0.0, role=DIFFERENTIABLE, slider=(0.05, 8.0),
              doc="Texture-space scale applied to the point before anything else: "
                  "larger is finer."),
    Parameter("period", NUMBER, 1.0, role=DIFFERENTIABLE, slider=(0.0, 8.0),
              doc="Stripe frequency along ``axis`` (unused by ``cosine``, whose paper "
                  "formula has none)."),
    Parameter("distortion", NUMBER, 1.0, role=DIFFERENTIABLE, slider=(0.0, 12.0),
              doc="Weight of the fractal noise in the phase."),
    Parameter("octaves", INTEGER, 8, bounds=(0, MAX_OCTAVES), traversed=True, slider=(0, 25),
              doc="Number of noise octaves K. Octaves below float32 resolution are not "
                  "evaluated: from 25 on at the paper's gain 0.5 (at gain ω, from the "
                  "first k with ω^k/(1−ω) ≤ 2^−24; all 64 from ω ≈ 0.755 on)."),
    Parameter("gain", NUMBER, 0.5, above=0.0, below=1.0, role=DIFFERENTIABLE,
              doc="Amplitude ratio ω of successive octaves, F = Σ_{i<K} ω^i N(λ^i v) "
                  "(POV-Ray's ``omega``; the paper's 0.5). Below 1, so that the octaves' "
                  "tail, at most 1.0364·ω^k/(1−ω), is bounded: the error budget and the "
                  "octaves float32 can add are made from it. A new value reuses the "
                  "kernel unless it changes the number of octaves evaluated."),
    Parameter("lacunarity", NUMBER, 2.0, above=1.0, at_most=MAX_LACUNARITY,
              role=DIFFERENTIABLE,
              doc="Frequency ratio λ of successive octaves (POV-Ray's ``lambda``; the "
                  "paper's 2). Above 1, each octave finer than the last; at most 3, so "
                  "that the 64th octave's frequency λ^63 times any point stays within "
                  "float32's range. The filters' octave cut-offs are at λ^i."),
    Parameter("function", CHOICE, "abs_sine", choices=FUNCTIONS,
              doc="``abs_sine`` (paper §3.2), ``sine`` (Fig. 1), ``cosine`` (Fig. 2), "
                  "``triangle`` (POV-Ray's marble wave, ``triangle_wave``: 2·frac φ "
                  "rising, 2(1 − frac φ) falling), ``sawtooth`` (POV-Ray's "
                  "``ramp_wave``: frac φ); the last two with the phase of ``abs_sine``, "
                  "φ = period·v_a + distortion·F."),
    Parameter("axis", CHOICE, "x", choices=AXES,
              doc="The coordinate the stripes run along."),
    Parameter("turbulence", BOOLEAN, False,
              doc="Sum |N| instead of N (Perlin's turbulence)."),
    Parameter("filter", CHOICE, "none", choices=FILTERS,
              doc="How a pixel's footprint (from the integrator's ray differentials; "
                  "``whitted`` has them) filters the marble: ``none``, the colour at the "
                  "point; ``bandlimit``, octaves finer than the footprint left out "
                  "(pbrt-v4's FBm clamp); ``prefilter``, the colour averaged over the "
                  "pixel's interval of phase, exactly (mimarble/texture/filters.py). Without "
                  "differentials every filter is ``none``."),
    Parameter("tolerance", NUMBER, None, at_least=0.0, slider=(0.0, 0.05),
              doc="Colour error allowed for leaving out fine octaves (a proven bound, "
                  "mimarble/texture/error_budget.py); 0 evaluates every octave. Default: the "
                  "scene's, half an 8-bit sRGB code value through its lighting; the plugin "
                  "alone, half a code value (error_budget.DEFAULT_TOLERANCE)."),
    Parameter("ramp", COLOURS, FIG5_RAMP, bounds=(1, MAX_RAMP_COLOURS), role=DIFFERENTIABLE,
              doc="Colours at evenly spaced keys k/(K−1), or at ``ramp_positions``, "
                  "interpolated linearly (one "
                  "colour: a constant). In a texture dict ``\"r g b, r g b, …\"`` "
                  "(``mimarble.parameters.ramp_text`` writes it from triples: "
                  "Mitsuba's properties hold no lists), one ``rgb``, or ``ramp_0``, "
                  "``ramp_1``, … (also in XML, which cannot repeat a name). ``r g b`` is "
                  "linear RGB, as Mitsuba's ``rgb``; an item ``#rrggbb`` is sRGB-encoded, "
                  "as on the web and in paint programs, and decoded with the exact sRGB "
                  "curve (IEC 61966-2-1): ``#808080`` is 0.2159 (``hex_colour``), as in "
                  "the scene language. Each item may start with its position: "
                  "``\"0 1 1 1, 0.5 0.5 0.4 0.3, 1 #202020\"`` (every item or none; "
                  "``ramp_positions``)."),
    Parameter("ramp_positions", POSITIONS, None, bounds=(1, MAX_RAMP_COLOURS),
              role=DIFFERENTIABLE, keyword=False,
              doc="Where each ramp colour sits on t (POV-Ray's ``color_map``, Blender's "
                  "ColorRamp): numbers in [0, 1], non-decreasing, one for each colour; "
                  "below the first and above the last the end colours hold; two equal "
                  "positions are a hard step (the upper colour from the position on). "
                  "Default (None): evenly spaced k/(K−1), the paper's ramp. Written in the "
                  "``ramp`` string (each item's leading number) or here as "
                  "``\"p, p, …\"`` (for ``ramp_0``, ``ramp_1``, …); in the scene language "
                  "inside the ``ramp`` block, ``ramp { 0 < 1 1 1 > 1 #202020 }``. "
                  "Differentiable (through ``filter`` ``prefilter`` the colours only: its "
                  "tables follow the positions' values). Having positions or not is "
                  "structural."),
)

BY_NAME: dict[str, Parameter] = {p.name: p for p in PARAMETERS}
#: The rows that are keys of their own in the scene language (its grammar, its keywords):
#: all but ``ramp_positions``, whose values the ``ramp`` block holds.
KEYWORD_PARAMETERS: tuple[Parameter, ...] = tuple(p for p in PARAMETERS if p.keyword)
#: What a sweep can vary (one value a frame): not the lists (ramp, its positions).
SWEEPABLE: tuple[str, ...] = tuple(p.name for p in PARAMETERS
                                   if p.kind not in (COLOURS, POSITIONS))
#: What a sweep changes in place, through ``mi.traverse`` (no new kernel).
IN_PLACE: tuple[str, ...] = tuple(p.name for p in PARAMETERS if p.in_place
                                  and p.kind not in (COLOURS, POSITIONS))
#: Keys that were renamed: the old name, and the parameter that replaced it.
RENAMED: dict[str, str] = {"bandlimit": "filter"}


class _Values:
    """The methods of :class:`MarbleParameters` (its fields come from the table)."""

    def __post_init__(self) -> None:
        if isinstance(self.ramp, str):         # "r g b, #rrggbb, …": its colours, as the plugin reads it
            colours, positions = parse_positioned_ramp(self.ramp)
            object.__setattr__(self, "ramp", colours)
            if positions is not None:          # "p r g b, …": the positions too
                if self.ramp_positions is not None:
                    raise ParameterError("give the ramp's positions in the ramp string or "
                                         "in ramp_positions, not both")
                object.__setattr__(self, "ramp_positions", positions)
        elif not isinstance(self.ramp, tuple):   # lists from Python: stored immutably
            object.__setattr__(self, "ramp", tuple(tuple(c) for c in self.ramp))
        if isinstance(self.ramp_positions, str):
            object.__setattr__(self, "ramp_positions", parse_positions(self.ramp_positions))
        elif self.ramp_positions is not None and not isinstance(self.ramp_positions, tuple):
            object.__setattr__(self, "ramp_positions", tuple(self.ramp_positions))

    @classmethod
    def from_properties(cls, props, context: str = "marble", defaults=None):
        """Every parameter read from a mapping (a Mitsuba ``Properties``, a dict) and
        checked; missing ones take their defaults: the table's, or ``defaults``' (checked
        values by row: a preset's, mimarble/presets.py), whose ramp positions are left
        out when ``props`` gives a ramp. ``ParameterError`` names ``context``, the
        parameter and the value."""
        defaults = {} if defaults is None else dict(defaults)
        if _ramp_given(props):              # a ramp given replaces its positions too
            defaults.pop("ramp_positions", None)
        for old, new in RENAMED.items():
            if old in props:
                others = [c for c in BY_NAME[new].choices if c != old]
                raise ParameterError(f"{context}: {old} was replaced by {new}; write "
                                     f"{new}=\"{old}\" (or {_listed(others)})")
        values, inline = {}, None
        for p in PARAMETERS:
            try:
                default = defaults.get(p.name, p.default)
                if p.kind == COLOURS:       # "p r g b, …": the positions come with it
                    value, inline = parse_positioned_ramp(ramp_property(props, default),
                                                          p.name)
                elif p.kind == POSITIONS and inline is not None:
                    if props.get(p.name, None) is not None:
                        raise ParameterError("give the ramp's positions in the ramp string "
                                             "or in ramp_positions, not both")
                    value = inline
                else:
                    value = props.get(p.name, default)
            except ParameterError as e:
                raise ParameterError(f"{context}: {e}") from None
            values[p.name] = checked(p, value, context)
        problem = ramp_count_problem(values["ramp"], values["ramp_positions"])
        if problem:
            raise ParameterError(f"{context}: {problem}")
        return cls(**values)

    def items(self):
        """(parameter, value) for every row that holds a value: None (decided elsewhere,
        as ``tolerance``, or not given, as ``ramp_positions``) is left out."""
        return ((p, getattr(self, p.name)) for p in PARAMETERS
                if getattr(self, p.name) is not None)


#: Values for every row of :data:`PARAMETERS`, as the rows hold them: a frozen dataclass
#: whose fields are the rows, in order, with their defaults. Built by
#: :meth:`from_properties` (checked) or directly (not checked; the scene language's
#: ``MarbleChannel`` adds its source position).
MarbleParameters = dataclasses.make_dataclass(
    "MarbleParameters", [(p.name, Any, dataclasses.field(default=p.default)) for p in PARAMETERS],
    bases=(_Values,), frozen=True)
MarbleParameters.__module__ = __name__


def checked(parameter: Parameter, value, context: str = "marble", text: bool = False):
    """``parameter.check(value, text)``, with ``context`` and the value in the message;
    None (a default of None, "decided elsewhere") passes."""
    if value is None and parameter.default is None:
        return None
    try:
        return parameter.check(value, text)
    except ParameterError as e:
        if parameter.kind in (COLOURS, POSITIONS):   # its messages quote the item at fault
            raise ParameterError(f"{context}: {e}") from None
        shown = repr(value)
        shown = shown if len(shown) <= 60 else shown[:57] + "..."
        raise ParameterError(f"{context}: {e}, found {shown}") from None


# ---------------------------------------------------------------------------
# The ramp as Mitsuba properties

def numbered_properties(props, name: str) -> list[str] | None:
    """The keys ``NAME_0``, ``NAME_1``, … of ``props`` in order; None when there are none;
    ValueError when they have gaps."""
    pattern = re.compile(rf"{re.escape(name)}_(\d+)$")
    numbered = sorted((int(m.group(1)), key) for key in props.keys() if (m := pattern.match(key)))
    if not numbered:
        return None
    if [k for k, _ in numbered] != list(range(len(numbered))):
        raise ValueError(f"{name}_0, {name}_1, … must be numbered without gaps, got "
                         f"{', '.join(key for _, key in numbered)}")
    return [key for _, key in numbered]


def _ramp_given(props) -> bool:
    """Whether ``props`` gives a ramp: ``ramp``, or ``ramp_0``, ``ramp_1``, …"""
    return "ramp" in props or any(key.startswith("ramp_") and key[5:].isdigit()
                                  for key in props.keys())


def ramp_property(props, default=BY_NAME["ramp"].default):
    """The ramp as given: ``ramp`` (a string, a list, or one ``rgb``), or ``ramp_0``,
    ``ramp_1``, … (one ``<rgb>`` each); ``default`` when neither is there."""
    try:
        keys = numbered_properties(props, "ramp")
    except ValueError as e:
        raise ParameterError(str(e)) from None
    if keys is None:
        return props.get("ramp", default)
    if "ramp" in props:
        raise ParameterError("give either ramp or ramp_0, ramp_1, …, not both")
    return [props[key] for key in keys]


def parameter_table() -> str:
    """The parameters as a reStructuredText list-table (the plugin's docstring)."""
    rows = []
    for p in PARAMETERS:
        default = "the Fig. 5 ramp" if p.kind == COLOURS else \
            "None: evenly spaced" if p.kind == POSITIONS else repr(p.default)
        role = "differentiable" if p.in_place else \
            "structural, in ``mi.traverse``" if p.traversed else "structural"
        rows.append(f"   * - ``{p.name}``\n     - {p.kind} ({default}; {role})\n"
                    f"     - {p.requirement[0].upper() + p.requirement[1:]}. {p.doc}")
    return ".. list-table::\n   :header-rows: 1\n\n   * - Parameter\n     - Type\n" \
           "     - Description\n" + "\n".join(rows)
