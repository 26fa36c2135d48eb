"""The ``marble`` texture: the paper's ChannelMarble as a Mitsuba 3 texture.

    v = scale · to_world⁻¹ · p                          (mimarble/texture_mapping.py)
    F(v) = Σ_{i<K} ω^i N(λ^i v)   (the paper: ω = ½, λ = 2)   (mimarble/noise.py)
    φ = period·v_a + distortion·F(v),   t = t(φ)         (mimarble/stripes.py)
    colour = ramp(t)   (evenly spaced, or at positions)  (mimarble/ramp.py)

filtered over the pixel's footprint as ``filter`` says (mimarble/pixel_filter.py), with
the octaves the error budget keeps (mimarble/error_budget.py). The parameters — names,
defaults, ranges, roles — are the table of mimarble/marble_parameters.py, also printed
in ``help(Marble)``. What the texture does not need it does not compute: no noise when
``distortion`` is 0 (and not being differentiated), no transform when ``to_world`` is
not given, a constant when the ramp has one colour.
"""

from __future__ import annotations

import warnings

import numpy as np

from . import environment, error_budget, pixel_filter
from .finite_arithmetic import finite_product
from .marble_parameters import (AXES, BY_NAME, COLOURS, INTEGER, PARAMETERS, POSITIONS,
                                MarbleParameters, ParameterError, checked, parameter_table,
                                ramp_count_problem)
from .noise import Spectrum, fractal_sum, lattice_tables
from .plugins import Kept, RGBTexture, describe, first_number, plugin, transform_matrix
from .ramp import Ramp, positions_storage, ramp_storage
from .stripes import STRIPES
from .texture_mapping import (NoFootprintWarning, TextureMapping, footprints_omitted,
                              without_footprint)

dr, mi = environment.import_drjit_and_mitsuba()


@plugin("texture", "marble")
class Marble(RGBTexture):
    __doc__ = ("Marble solid texture (Park & Park 2004): see mimarble/marble.py.\n\n"
               + parameter_table() + "\n\nAlso ``to_world`` (transform, identity): places the "
               "texture in the world; must be invertible; always in ``mi.traverse``, not "
               "differentiable.")

    def __init__(self, props):
        mi.Texture.__init__(self, props)
        if not mi.variant().endswith("_rgb"):
            raise ParameterError(f"marble: variant {mi.variant()} is not supported; use an "
                                 f"RGB variant (llvm_ad_rgb, cuda_ad_rgb, scalar_rgb)")
        params = MarbleParameters.from_properties(props)
        self.function, self.axis, self.turbulence, self.filter = \
            params.function, params.axis, params.turbulence, params.filter
        self.tolerance = error_budget.DEFAULT_TOLERANCE if params.tolerance is None \
            else params.tolerance
        self.stripe, self.axis_index = STRIPES[self.function], AXES.index(self.axis)
        # What mi.traverse edits in place: the table's traversed rows and to_world.
        # (ramp_positions only when given: having them is structural.)
        self.editable = {p.name: _editable(p, getattr(params, p.name))
                         for p in PARAMETERS if p.is_traversed
                         and getattr(params, p.name) is not None}
        self.ramp = Ramp(self.editable["ramp"], self.editable.get("ramp_positions"))
        self.mapping = TextureMapping.from_properties(props)
        self.editable["to_world"] = self.mapping.to_world
        if dr.is_jit_v(mi.Float):        # the noise's tables, held (see lattice_tables)
            self.lattice = lattice_tables(mi.UInt32)
        self.pixel_filter = None
        # The warning of eval, once per texture, and never for one that has been traced
        # with footprints (a whitted scene's marble, traced again by another scene's
        # symbolic call over every live material, is not that scene's concern).
        self._quiet_about_footprints = Kept(False)
        self.parameters_changed()

    # -- Mitsuba object protocol -------------------------------------------

    def traverse(self, cb):
        for name, value in self.editable.items():
            differentiable = name in BY_NAME and BY_NAME[name].in_place
            cb.put(name, value, mi.ParamFlags.Differentiable if differentiable
                   else mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys=[]):
        """Check the values as ``mi.traverse`` left them, with the table's rules; an
        invalid edit raises and puts the last valid values back, so the texture never
        renders with them. Then decide what the kernel evaluates."""
        if dr.is_jit_v(mi.Float):
            # Opaque, first: a new value reuses the compiled kernel, a recording of it
            # (dr.freeze) takes every one as an input, copies too, and reading an
            # evaluated value back launches nothing (a literal's read evaluates a copy).
            dr.make_opaque(*self.editable.values())
        try:
            values = {name: checked(BY_NAME[name], self._read_back(BY_NAME[name]))
                      for name in self.editable if name in BY_NAME}
            problem = ramp_count_problem(values["ramp"], values.get("ramp_positions"))
            if problem:
                raise ParameterError(f"marble: {problem}")
            to_world = transform_matrix(self.mapping.to_world)
            self.mapping.check(to_world)
        except ParameterError:
            for name, value in getattr(self, "_last_valid", Kept({})).value.items():
                # In place: mi.traverse holds these very objects.
                mi.set_property(self.editable[name], value)
            raise
        self._last_valid = Kept({name: type(value)(value) for name, value in self.editable.items()})
        self.ramp.changed()
        if dr.is_jit_v(mi.Float):   # the kernel reads the traversed values themselves
            self.scale, self.period, self.distortion = (
                self.editable[name] for name in ("scale", "period", "distortion"))
        else:                       # the scalar variant computes on Python floats
            self.scale, self.period, self.distortion = (
                values[name] for name in ("scale", "period", "distortion"))
        self.mapping.changed(self.scale, to_world)
        # Structural: a new count traces a new kernel at the next eval. The budget bounds
        # the colour's error, not its derivatives' (every octave's gradient is of the same
        # size, 2^i·2^−i): a parameter being differentiated keeps every octave.
        self.octaves = values["octaves"]
        differentiated = any(dr.grad_enabled(self.editable[p.name]) for p in PARAMETERS
                             if p.in_place and p.name in self.editable)
        self.octaves_evaluated = error_budget.octaves_needed(
            0.0 if differentiated else self.tolerance, self.octaves, values["distortion"],
            values["ramp"], self.function, gain=values["gain"],
            positions=values.get("ramp_positions"))
        # The octaves' gain and lacunarity: the traversed values themselves in JIT variants
        # (opaque, differentiable), Python floats in the scalar one (mimarble/noise.py).
        jit = dr.is_jit_v(mi.Float)
        self.spectrum = Spectrum(values["gain"], values["lacunarity"],
                                 self.editable["gain"] if jit else None,
                                 self.editable["lacunarity"] if jit else None,
                                 opaque=jit, octaves=self.octaves_evaluated)
        # Distortion 0 needs no noise, unless distortion, gain or lacunarity is being
        # differentiated (their derivatives reach the colour through F: F, and 0·∂F).
        self.needs_noise = self.octaves_evaluated > 0 and (
            values["distortion"] != 0.0 or dr.grad_enabled(self.distortion)
            or self.spectrum.differentiated())
        if self.pixel_filter is not None and self._ramp_size == self.ramp.size:
            self.pixel_filter.changed()
        else:                       # a filter's tables are made for a number of colours
            self.pixel_filter = pixel_filter.choose(self, self.filter)
        self._ramp_size = self.ramp.size
        self._max = float(np.max(values["ramp"]))

    def _read_back(self, parameter):
        """A traversed parameter's value as the table holds it (an edit may have left
        anything there: it is checked next)."""
        value = self.editable[parameter.name]
        if parameter.kind == COLOURS:
            return self.ramp.numpy()
        if parameter.kind == POSITIONS:
            return tuple(self.ramp.positions_numpy().tolist())
        number = first_number(value)
        return int(number) if parameter.kind == INTEGER and number.is_integer() else number

    def recording_key(self) -> tuple:
        """Everything outside Dr.Jit's variables that decides the code ``eval`` traces: a
        recording of its kernels (mimarble/mitsuba/replay.py) is replayed only for the
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
            "gain": self.spectrum.gain_value, "lacunarity": self.spectrum.lacunarity_value,
            "turbulence": self.turbulence, "filter": self.filter,
            "ramp": f"{self.ramp.size} colours"
                    + (" at positions" if self.ramp.positioned else ""),
            "to_world": "identity" if self.mapping.to_texture is None else "given"})

    def is_spatially_varying(self):
        return self.ramp.size > 1

    def mean(self):
        """The mean luminance where the phase is spread uniformly (mimarble/ramp.py);
        differentiable with respect to the ramp."""
        return mi.luminance(self.ramp.mean(self.stripe))

    def max(self):
        return self._max

    # -- Evaluation ------------------------------------------------------------

    def phase(self, v, F=None):
        """φ = period·v_a + distortion·F (cosine: v_a + distortion·F); F None: no noise."""
        noise = 0.0 if F is None else finite_product(self.distortion, F)
        return self.stripe.phase(v[self.axis_index], self.period, noise)

    def phase_gradient(self, noise_gradient=None):
        """∇_v φ, given distortion·∇F (None: no noise)."""
        return self.stripe.phase_gradient(self.axis_index, self.period, noise_gradient)

    def eval(self, si, active=True):
        """The colour at ``si``; 0 where ``active`` is False, as Mitsuba's ``bitmap``
        gives (every lookup is in bounds by construction, so none needs the mask)."""
        if self.ramp.size == 1:            # a constant: no noise, no ramp interpolation
            return dr.select(active, self.ramp.constant(dr.width(si.p)), 0.0)
        if self.pixel_filter.needs_footprint and not self._quiet_about_footprints.value \
                and not footprints_omitted():
            self._quiet_about_footprints.value = True
            if without_footprint(si):
                warnings.warn(self._no_footprint_message(), NoFootprintWarning, stacklevel=2)
        point = self.mapping.map(si, self.pixel_filter.needs_footprint)
        # A NaN or infinite point gets a NaN colour, decided here once rather than left to
        # how each backend's min/max and float→int conversions treat NaN (they differ).
        colour = dr.select(point.finite, self.pixel_filter.colour(self, point), dr.nan)
        return dr.select(active, colour, 0.0)

    def prepare_alternate(self) -> None:
        """Make what :meth:`eval_and_alternate` reads (the phase-average tables), before a
        kernel that calls it is traced."""
        if self.ramp.size > 1:
            self.pixel_filter.prepare_alternate()

    def eval_and_alternate(self, si, active=True):
        """(:meth:`eval`'s colour, a second estimate of the pixel's colour): the filter's
        other view of the footprint (mimarble/pixel_filter.py) — the prefiltered mean for a
        point sample, the colour at the point for a filtered marble. Their difference is
        the marble's own estimate of how wrong one sample of it can be here, which
        adaptive sampling reads (mimarble/mitsuba/adaptive.py). Needs the footprint (ray
        differentials) and :meth:`prepare_alternate` first."""
        if self.ramp.size == 1 or self.pixel_filter.average is None:
            # A constant; or a marble not prepared (another scene's, traced by a symbolic
            # call over every live material): one estimate.
            colour = self.eval(si, active)
            return colour, colour
        point = self.mapping.map(si, True)
        colour, alternate = self.pixel_filter.colour_and_alternate(self, point)
        return tuple(dr.select(active, dr.select(point.finite, c, dr.nan), 0.0)
                     for c in (colour, alternate))

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
            F = fractal_sum(v, self.octaves_evaluated, self.turbulence, gradient=True,
                            spectrum=self.spectrum)
            phase, grad_phase = self.phase(v, F.value), self.phase_gradient(F.gradient
                                                                            * self.distortion)
        else:
            phase, grad_phase = self.phase(v), self.phase_gradient()
        slope = mi.luminance(self.ramp.slope(self.stripe.t(phase)))
        gradient = self.mapping.gradient_to_world(
            (slope * self.stripe.slope(phase) * self.scale) * grad_phase)
        return mi.Vector2f(dr.dot(gradient, si.dp_du), dr.dot(gradient, si.dp_dv))


def _editable(parameter, value):
    """A traversed parameter's value in a container Mitsuba can write into in every
    variant: ``mi.Float`` in JIT variants; in scalar_rgb, where mi.Float is a Python
    float, a one-element ``ArrayXf``; the ramp's own (mimarble/ramp.py). An integer is
    held as a float too, so that an edit to 2.5 is seen and refused, not truncated."""
    if parameter.kind == COLOURS:
        return ramp_storage(value)
    if parameter.kind == POSITIONS:
        return positions_storage(value)
    return mi.Float(value) if dr.is_jit_v(mi.Float) else dr.scalar.ArrayXf([value])

