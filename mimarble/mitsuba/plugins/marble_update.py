"""The marble's update path: its traversed values, read from its properties and edited
through ``mi.traverse``, and what an edit decides — the octaves the error budget keeps,
whether the noise is needed, the filter's tables, the ramp's maximum — made on the host
without waiting for the device (docs/design-decisions.md, "The update path").
:class:`MarbleUpdates` is the base of the texture (mimarble/mitsuba/plugins/marble.py),
whose own code is the formula.
"""

from __future__ import annotations

import numpy as np

from mimarble.runtime import environment
from mimarble.texture import error_budget, filters as pixel_filter
from mimarble import presets
from mimarble.parameters import AXES, BY_NAME, COLOURS, PARAMETERS, MarbleParameters, ParameterError
from mimarble.texture.fbm import Spectrum
from mimarble.texture.perlin import lattice_tables
from mimarble.mitsuba.plugins.registration import Kept, describe, first_number
from mimarble.texture.ramp import Ramp
from mimarble.mitsuba.plugins.marble_values import HeldValues, editable_storage, host_matrix
from mimarble.texture.stripes import STRIPES
from mimarble.texture.mapping import TextureMapping

dr, mi = environment.import_drjit_and_mitsuba()


class MarbleUpdates(HeldValues):
    """A marble's values and the decisions made from them (see the module)."""

    def _read_properties(self, props) -> None:
        """The texture's values from its properties (``MarbleParameters``: the table's
        rules), then every decision made from them."""
        # "preset": a named marble (mimarble/presets.toml) whose values are the defaults.
        try:
            defaults = presets.preset_values(props["preset"]) if "preset" in props else None
        except ParameterError as e:
            raise ParameterError(f"marble: {e}") from None
        params = MarbleParameters.from_properties(props, defaults=defaults)
        self.function, self.axis, self.turbulence, self.filter = \
            params.function, params.axis, params.turbulence, params.filter
        self.tolerance = error_budget.DEFAULT_TOLERANCE if params.tolerance is None \
            else params.tolerance
        self.stripe, self.axis_index = STRIPES[self.function], AXES.index(self.axis)
        # What mi.traverse edits in place: the table's traversed rows and to_world.
        # (ramp_positions only when given: having them is structural.)
        self._editable = Kept({p.name: editable_storage(p, getattr(params, p.name))
                               for p in PARAMETERS if p.is_traversed
                               and getattr(params, p.name) is not None})
        self.ramp = Ramp(self.editable["ramp"], self.editable.get("ramp_positions"))
        self.mapping = TextureMapping.from_properties(props)
        self.editable["to_world"] = self.mapping.to_world
        if dr.is_jit_v(mi.Float):        # the noise's tables, held (see lattice_tables)
            self.lattice = lattice_tables(mi.UInt32)
            self._zero = dr.opaque(mi.Float, 0.0)   # see _kept_attached
        self.pixel_filter = None
        # The warning of eval, once per texture, and never for one that has been traced
        # with footprints (a whitted scene's marble, traced again by another scene's
        # symbolic call over every live material, is not that scene's concern).
        self._quiet_about_footprints = Kept(False)
        # What the host holds of each traversed value (None: held on the device only, an
        # edit the host never saw; see parameters_changed): the properties' values, and
        # to_world's matrix (literals, read without waiting).
        self._held = Kept({name: getattr(params, name) for name in self.editable
                           if name in BY_NAME})
        self._held.value["to_world"] = host_matrix(self.mapping.to_world)
        # The host's values told of (hold), and those the host read or was given, by the
        # Dr.Jit variable they are the value of (see _host_value).
        self._told, self._pending = Kept({}), Kept({})
        self._changed(set())

    @property
    def editable(self) -> dict:
        """What ``mi.traverse`` edits in place (name → its Dr.Jit value), held in a
        :class:`Kept`: every value the kernel reads is held where it reads it as well
        (``scale``, ``ramp``, ``mapping``, ``spectrum``, …), so a recorded pass, which walks
        the texture's attributes at each replay, walks them there once and not again here
        (docs/design-decisions.md, "Adaptive samples: the pass's fixed cost")."""
        return self._editable.value

    def traverse(self, cb):
        for name, value in self.editable.items():
            differentiable = name in BY_NAME and BY_NAME[name].in_place
            cb.put(name, value, mi.ParamFlags.Differentiable if differentiable
                   else mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys=[]):
        """Check the values as ``mi.traverse`` left them, and decide what the kernel
        evaluates, without reading back a value the host does not hold (no wait for the
        device: an optimisation step stays asynchronous).

        ``keys``: the names Mitsuba says were edited (none: every one may have been). An
        edited value the host holds — a Python number set through ``mi.traverse`` is a
        Dr.Jit literal, read without waiting — and a structural one (``octaves``, which
        decides the kernel) are checked here with the table's rules: an invalid edit
        raises and puts the last valid values back. Any other edited value (computed on
        the device: an optimiser's, a ramp array) is checked in the kernel instead: while
        one breaks its rule, the texture is NaN everywhere (:meth:`check_values` says
        which rule, reading them). Decisions made from values (the octaves the error
        budget keeps, whether the noise is needed) take the value-independent choice for
        a value on the device (docs/design-decisions.md, "The update path")."""
        self._changed(set(keys) if keys else set(self.editable))

    def _changed(self, keys: set) -> None:
        jit = dr.is_jit_v(mi.Float)
        values = self._take_edit(keys)
        on_device = {name for name, value in values.items() if value is None}
        self.ramp.changed()
        if jit:                     # the kernel reads the traversed values themselves
            self.scale, self.period, self.distortion = (
                self.editable[name] for name in ("scale", "period", "distortion"))
        else:                       # the scalar variant computes on Python floats
            self.scale, self.period, self.distortion = (
                values[name] for name in ("scale", "period", "distortion"))
        self.mapping.changed(self.scale, values["to_world"])
        # Structural: a new count traces a new kernel at the next eval. The budget bounds
        # the colour's error, not its derivatives' (every octave's gradient is of the same
        # size, 2^i·2^−i): a parameter being differentiated keeps every octave; so does a
        # value the budget reads that is on the device (the budget is made on the host).
        self.octaves = values["octaves"]
        differentiated = any(dr.grad_enabled(self.editable[p.name]) for p in PARAMETERS
                             if p.in_place and p.name in self.editable)
        budget_unknown = bool(on_device & {"distortion", "ramp", "ramp_positions", "gain"})
        self.octaves_evaluated = self.octaves if values["gain"] is None else \
            error_budget.octaves_needed(
                0.0 if differentiated or budget_unknown else self.tolerance, self.octaves,
                values["distortion"], values["ramp"], self.function, gain=values["gain"],
                positions=values.get("ramp_positions"))
        # The octaves' gain and lacunarity: the traversed values themselves in JIT variants
        # (opaque, differentiable), Python floats in the scalar one (mimarble/texture/noise.py);
        # None for a value on the device, whose derived constants the device computes.
        self.spectrum = Spectrum(values["gain"], values["lacunarity"],
                                 self.editable["gain"] if jit else None,
                                 self.editable["lacunarity"] if jit else None,
                                 opaque=jit, octaves=self.octaves_evaluated)
        # Distortion 0 needs no noise, unless distortion, gain or lacunarity is being
        # differentiated (their derivatives reach the colour through F: F, and 0·∂F).
        self.needs_noise = self.octaves_evaluated > 0 and (
            values["distortion"] is None or values["distortion"] != 0.0
            or dr.grad_enabled(self.distortion) or self.spectrum.differentiated())
        if self.pixel_filter is not None and self._ramp_size == self.ramp.size:
            self.pixel_filter.changed()
        else:                       # a filter's tables are made for a number of colours
            self.pixel_filter = pixel_filter.choose(self.filter, self.stripe, self.ramp)
        self._ramp_size = self.ramp.size
        # The largest ramp component: what the host holds, else read when max() asks; in
        # JIT variants also on the device (a reduction, no read back) for the kernels that
        # read it (held_maximum).
        self._max = None if values["ramp"] is None else float(np.max(values["ramp"]))
        if jit:
            c = dr.detach(self.editable["ramp"])
            self._held_max = dr.max(dr.maximum(dr.maximum(c[0], c[1]), c[2]))
            dr.make_opaque(self._held_max)
        self.valid = self._kernel_check(on_device) if jit else None

    def recording_key(self) -> tuple:
        """Everything outside Dr.Jit's variables that decides the code ``eval`` traces: a
        recording of its kernels (mimarble/mitsuba/rendering/replay.py) is replayed only for the
        same key; the values themselves are the recording's inputs."""
        return ("marble", self.function, self.axis, self.turbulence,
                type(self.pixel_filter).__name__, self.octaves_evaluated, self.needs_noise,
                self.ramp.size, self.ramp.positioned, self.mapping.to_texture is None)

    def max(self):
        """The largest ramp component (read back, once, after an edit on the device)."""
        if self._max is None:
            self._max = first_number(self._held_max)
        return self._max

    def held_maximum(self) -> tuple:
        """(:meth:`max` as the texture holds it — JIT variants: a one-lane Dr.Jit value
        made from the ramp without a read back, current after every edit of it, which a
        kernel reads (``marble_medium``'s density bound) —, no host values:
        plugins.held_maximum)."""
        return (self._held_max if dr.is_jit_v(mi.Float) else self._max), ()

    def _kept_attached(self, colour):
        """``colour``, plus 0·p for each in-place parameter p being differentiated: where
        the colour does not depend on p by structure — a one-colour ramp (scale, period,
        distortion, gain, lacunarity, positions), one octave (gain: ω⁰ = 1; lacunarity:
        λ⁰ = 1) — its derivative is then 0, and Mitsuba's ``prb`` finds the contribution
        attached to the AD graph rather than raising. The 0 is an opaque value the texture
        holds: Dr.Jit's AD drops a product with a literal 0 (and its edge). Nothing is added
        while nothing is differentiated (the images are untouched)."""
        if not dr.is_jit_v(mi.Float):
            return colour
        for p in PARAMETERS:
            value = self.editable.get(p.name) if p.in_place else None
            if value is not None and dr.grad_enabled(value):
                first = dr.gather(type(value), value, mi.UInt32(0)) if dr.width(value) > 1 \
                    else value
                colour = colour + self._zero * (first if p.kind != COLOURS else first[0])
        return colour

    def _defined(self, finite):
        """Where the colour is defined: at finite points (``finite``), and only while every
        value on the device keeps its rule (:meth:`_kernel_check`); elsewhere NaN. (The
        scalar variant holds every value on the host.)"""
        return finite if self.valid is None else finite & self.valid

    def to_string(self):
        return describe("Marble", {
            "function": self.function, "axis": self.axis,
            "scale": first_number(self.scale), "period": first_number(self.period),
            "distortion": first_number(self.distortion),
            "octaves": f"{self.octaves} ({self.octaves_evaluated} within tolerance "
                       f"{self.tolerance:g})",
            "gain": first_number(self.spectrum.gain),
            "lacunarity": first_number(self.spectrum.lacunarity),
            "turbulence": self.turbulence, "filter": self.filter,
            "ramp": f"{self.ramp.size} colours"
                    + (" at positions" if self.ramp.positioned else ""),
            "to_world": "identity" if self.mapping.to_texture is None else "given"})
