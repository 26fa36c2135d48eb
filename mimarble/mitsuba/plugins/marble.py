"""The ``marble`` texture: the paper's ChannelMarble as a Mitsuba 3 texture.

    v = scale · to_world⁻¹ · p                          (mimarble/texture/mapping.py)
    F(v) = Σ_{i<K} ω^i N(λ^i v)   (the paper: ω = ½, λ = 2)   (mimarble/texture/noise.py)
    φ = period·v_a + distortion·F(v),   t = t(φ)         (mimarble/texture/stripes.py)
    colour = ramp(t)   (evenly spaced, or at positions)  (mimarble/texture/ramp.py)

filtered over the pixel's footprint as ``filter`` says (mimarble/texture/filters.py), with
the octaves the error budget keeps (mimarble/texture/error_budget.py). The parameters — names,
defaults, ranges, roles — are the table of mimarble/parameters.py, also printed
in ``help(Marble)``. What the texture does not need it does not compute: no noise when
``distortion`` is 0 (and not being differentiated), no transform when ``to_world`` is
not given, a constant when the ramp has one colour.
"""

from __future__ import annotations

import warnings

import numpy as np

from mimarble.runtime import environment
from mimarble.texture import error_budget, filters as pixel_filter, srgb_model
from mimarble.texture.filters import Noise, Octaves, Phase
from mimarble.texture.finite_arithmetic import finite_product
from mimarble.parameters import (AXES, BY_NAME, COLOURS, PARAMETERS, MarbleParameters,
    ParameterError, parameter_table)
from mimarble.texture.fbm import Spectrum, fractal_gradient
from mimarble.texture.perlin import lattice_tables
from mimarble.mitsuba.plugins.registration import (Kept, RGBTexture, describe, first_number,
    plugin)
from mimarble.texture.ramp import Ramp
from mimarble.mitsuba.plugins.marble_values import HeldValues, editable_storage, host_matrix
from mimarble.texture.stripes import STRIPES
from mimarble.texture.mapping import (NoFootprintWarning, TextureMapping, footprints_omitted,
    without_footprint)

dr, mi = environment.import_drjit_and_mitsuba()


@plugin("texture", "marble")
class Marble(HeldValues, RGBTexture):
    __doc__ = ("Marble solid texture (Park & Park 2004): see mimarble/mitsuba/plugins/marble.py.\n\n"
               + parameter_table() + "\n\nAlso ``to_world`` (transform, identity): places the "
               "texture in the world; must be invertible; always in ``mi.traverse``, not "
               "differentiable.")

    def __init__(self, props):
        mi.Texture.__init__(self, props)
        variant_problem = srgb_model.variant_problem("marble")
        if variant_problem:
            raise ParameterError(variant_problem)
        # Spectral variants: the model that turns the colour into a spectrum, held (see
        # RGBTexture.eval and mimarble/texture/srgb_model.py); None elsewhere.
        self.srgb_table = srgb_model.model_table()
        params = MarbleParameters.from_properties(props)
        self.function, self.axis, self.turbulence, self.filter = \
            params.function, params.axis, params.turbulence, params.filter
        self.tolerance = error_budget.DEFAULT_TOLERANCE if params.tolerance is None \
            else params.tolerance
        self.stripe, self.axis_index = STRIPES[self.function], AXES.index(self.axis)
        # What mi.traverse edits in place: the table's traversed rows and to_world.
        # (ramp_positions only when given: having them is structural.)
        self.editable = {p.name: editable_storage(p, getattr(params, p.name))
                         for p in PARAMETERS if p.is_traversed
                         and getattr(params, p.name) is not None}
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

    # -- Mitsuba object protocol -------------------------------------------

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

    def is_spatially_varying(self):
        return self.ramp.size > 1

    def mean(self):
        """The mean luminance where the phase is spread uniformly (mimarble/texture/ramp.py);
        differentiable with respect to the ramp. Spectral variants: ``srgb_model_mean`` (the
        sRGB model's spectrum averaged over 16 wavelengths evenly spaced over 360–830 nm) of
        the one spectrum of that mean colour — what ``srgb`` answers for that colour, but not
        what ``bitmap`` answers (the mean of its texels' spectral means): the model is not
        linear, so a red–blue ramp gives 0.661 where its two colours' spectral means average
        0.544."""
        if mi.is_spectral:
            return srgb_model.mean(self.srgb_table, self.ramp.mean(self.stripe))
        return mi.luminance(self.ramp.mean(self.stripe))

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

    # -- Evaluation ------------------------------------------------------------

    def phase(self, v, F=None):
        """φ = period·v_a + distortion·F (cosine: v_a + distortion·F); F None: no noise."""
        noise = 0.0 if F is None else finite_product(self.distortion, F)
        return self.stripe.phase(v, self.axis_index, self.period, noise)

    def phase_gradient(self, v, noise_gradient=None):
        """∇_v φ, given distortion·∇F (None: no noise)."""
        return self.stripe.phase_gradient(v, self.axis_index, self.period, noise_gradient)

    def eval_3(self, si, active=True):
        """The colour at ``si``; 0 where ``active`` is False, as Mitsuba's ``bitmap``
        gives (every lookup is in bounds by construction, so none needs the mask).
        ``eval`` is this colour, or in spectral variants its spectrum (RGBTexture.eval).
        The formula, in order; the filter decides how a pixel differs from a point."""
        if self.ramp.size == 1:            # a constant: no noise, no ramp interpolation
            return self._kept_attached(dr.select(active, dr.select(
                self._defined(True), self.ramp.constant(dr.width(si.p)), dr.nan), 0.0))
        self._warn_without_footprint(si)
        point = self.mapping.map(si, self.pixel_filter.needs_footprint)  # v = scale·M⁻¹·p
        noise = self.pixel_filter.noise(point, self._octaves())           # F(v)
        phase = self._phase(point.v, noise)                   # φ = period·v_a + distortion·F
        colour = self.pixel_filter.colour(phase, point)       # ramp(t(φ)), or its pixel mean
        return self._shown(colour, point, active)

    def _octaves(self) -> Octaves | None:
        """The octave sum F the filter computes (None: no noise needed)."""
        return Octaves(self.octaves_evaluated, self.turbulence, self.spectrum) \
            if self.needs_noise else None

    def _phase(self, v, noise: Noise) -> Phase:
        """φ from the filter's noise; over the pixel also ∇φ and σ²_φ = distortion²·σ²."""
        value = self.phase(v, noise.value)
        if not noise.over_pixel:
            return Phase(value)
        if noise.value is None:
            return Phase(value, self.phase_gradient(v), 0.0)
        return Phase(value, self.phase_gradient(v, noise.gradient * self.distortion),
                     dr.square(self.distortion) * noise.spread)

    def _shown(self, colour, point, active):
        """The colour as eval returns it: NaN at a NaN or infinite point — decided here once
        rather than left to how each backend's min/max and float→int conversions treat
        NaN (they differ) — or while a value on the device breaks its rule; 0 where
        ``active`` is False."""
        return self._kept_attached(dr.select(active, dr.select(
            self._defined(point.finite), colour, dr.nan), 0.0))

    def _warn_without_footprint(self, si) -> None:
        """Once per texture: a filter that needs a footprint, given none."""
        if self.pixel_filter.needs_footprint and not self._quiet_about_footprints.value \
                and not footprints_omitted():
            self._quiet_about_footprints.value = True
            if without_footprint(si):
                warnings.warn(self._no_footprint_message(), NoFootprintWarning, stacklevel=3)

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

    def prepare_alternate(self) -> None:
        """Make what :meth:`eval_and_alternate` reads (the phase-average tables), before a
        kernel that calls it is traced."""
        if self.ramp.size > 1:
            self.pixel_filter.prepare_alternate()

    def eval_and_alternate(self, si, active=True):
        """(:meth:`eval`'s colour, a second estimate of the pixel's colour): the filter's
        other view of the footprint (mimarble/texture/filters.py) — the prefiltered mean for a
        point sample, the colour at the point for a filtered marble. Their difference is
        the marble's own estimate of how wrong one sample of it can be here, which
        adaptive sampling reads (mimarble/mitsuba/rendering/adaptive.py). Needs the footprint (ray
        differentials) and :meth:`prepare_alternate` first."""
        if self.ramp.size == 1 or self.pixel_filter.average is None:
            # A constant; or a marble not prepared (another scene's, traced by a symbolic
            # call over every live material): one estimate.
            colour = self.eval_3(si, active)          # (kept attached there)
            return colour, colour
        point = self.mapping.map(si, True)
        noise, other = self.pixel_filter.noise_and_alternate(point, self._octaves())
        phase = self._phase(point.v, noise)
        alternate = None if other is None else self._phase(point.v, other)
        colour, alternate = self.pixel_filter.colour_and_alternate(phase, alternate, point)
        return tuple(self._shown(c, point, active) for c in (colour, alternate))

    def _no_footprint_message(self) -> str:
        name = f" {self.id()!r}" if self.id() else ""
        return (f"marble{name}: filter={self.filter!r} has no pixel footprint to filter "
                f"over: the integrator computed no ray differentials (si.duv_dx, si.duv_dy "
                f"are 0), so the marble is its colour at the point, as filter='none'. "
                f"mimarble's 'whitted' provides them; Mitsuba's own integrators ('path', "
                f"'prb', 'direct', ...) do not (docs/mitsuba-scene.md). Said once per "
                f"texture; a symbolic call traces every live instance, so this may be a "
                f"marble of another scene still loaded.")

    def eval_1_grad(self, si, active=True):
        """∂(luminance)/∂(u, v), exact, by the chain rule (what Mitsuba's ``bumpmap`` reads):

            ∇_p lum = lum(ramp′(t)) · t′(φ) · scale · (period·e_a + distortion·∇F(v)),

        mapped to world space by ``to_world``'s inverse transpose, then dotted with
        ∂p/∂u and ∂p/∂v; ∇F with F, in one pass, over every evaluated octave (filters
        act on the colour, not on its derivative).
        """
        if self.ramp.size == 1:
            return dr.zeros(mi.Vector2f, dr.width(si.p))
        v = self.mapping.point(si.p)
        if self.needs_noise:
            F = fractal_gradient(v, self.octaves_evaluated, self.turbulence, self.spectrum)
            phase = self.phase(v, F.value)
            grad_phase = self.phase_gradient(v, F.gradient * self.distortion)
        else:
            phase, grad_phase = self.phase(v), self.phase_gradient(v)
        slope = mi.luminance(self.ramp.slope(self.stripe.t(phase)))
        gradient = self.mapping.gradient_to_world(
            (slope * self.stripe.slope(phase) * self.scale) * grad_phase)
        return dr.select(self._defined(True), mi.Vector2f(dr.dot(gradient, si.dp_du),
                                                         dr.dot(gradient, si.dp_dv)), dr.nan)


