"""``channel_expression``: channels combined arithmetically (the paper's future work, §5).

.. math::

    \\texttt{add}: \\sum_k c_k \\qquad
    \\texttt{multiply}: \\prod_k c_k \\qquad
    \\texttt{mix}: a\\,(1 - w) + b\\,w

componentwise, each operand any Mitsuba texture (``rgb``, ``marble``, ``bitmap``,
another ``channel_expression``…). The float64 twin is :mod:`mimarble.reference.channels`.

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Description
   * - ``op``
     - string
     - ``add``, ``multiply`` or ``mix``.
   * - ``operand_0``, ``operand_1``, …
     - texture (or an ``rgb`` / a float value)
     - Two or more operands, numbered without gaps; ``mix`` takes exactly two, a and b.
       Differentiable through their own parameters (``operand_0.value``, …).
   * - ``weight``
     - texture or float
     - ``mix`` only: w, a texture's colour (componentwise) or a number (not clamped).
       A number is differentiable (key ``weight``).

Operands are read when the expression is evaluated, as Mitsuba's own textures read
theirs, so an edit of an operand shared with another parent (``mi.traverse`` tells only
a node's first parent) is seen. Constant operands (``rgb``, a one-colour ramp, a
constant sub-expression) are combined first, in one constant. What is not needed is not
computed (a new decision compiles a new kernel): a product with a constant 0 evaluates
nothing; a ``mix`` whose weight is the constant 0 or 1 evaluates only ``a`` or only ``b``.
Decided from the values when the texture is loaded; at an update (nothing is read back
there) the decision stays while the constants it was made from are the same Dr.Jit
variables, a number ``weight`` set as a Python number (a literal) is decided again from
it, and any other edit of a constant turns the shortcut off. Those decisions are used
only while no operand has changed since the expression was last told: an edit that
reached only another parent falls back to evaluating everything. Equal operands inside one ``channel_material`` are evaluated once
(:func:`~mimarble.mitsuba.plugins.shared_evaluations.shared_evaluations`); elsewhere Dr.Jit's common-subexpression elimination
merges identical unrolled code.
"""

from __future__ import annotations

import functools
import operator
from typing import NamedTuple

import numpy as np

from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import (Kept, RGBTexture, describe, held_maximum,
    numbers, plugin, recording_key)
from mimarble.parameters import numbered_properties
from .shared_evaluations import evaluate

dr, mi = environment.import_drjit_and_mitsuba()

OPERATIONS = ("add", "multiply", "mix")
#: Step of the central differences of eval_1_grad for products and mixes, relative
#: to |∂p/∂u| (sums add their operands' own gradients).
GRADIENT_STEP = 1e-3


class OperandState(NamedTuple):
    """The operands' values as :meth:`ChannelExpression._operand_state` saw them."""
    fingerprint: int
    held: Kept


class ChannelExpressionError(ValueError):
    """An invalid ``channel_expression``; the message names the parameter."""


# ---------------------------------------------------------------------------

@plugin("texture", "channel_expression")
class ChannelExpression(RGBTexture):
    """Textures added, multiplied or mixed. See the module docstring for parameters."""

    def __init__(self, props):
        mi.Texture.__init__(self, props)
        self.op = props.get("op", None)
        if self.op not in OPERATIONS:
            raise ChannelExpressionError(f"channel_expression: op={self.op!r} must be one of "
                                         f"{', '.join(OPERATIONS)}")
        try:
            numbered = numbered_properties(props, "operand") or []
        except ValueError as e:
            raise ChannelExpressionError(f"channel_expression: operands {e}") from None
        count = len(numbered)
        if count < 2 or (self.op == "mix" and count != 2):
            need = "exactly two operands (a and b)" if self.op == "mix" else "two or more operands"
            raise ChannelExpressionError(f"channel_expression: {self.op} takes {need}, got {count}")
        self.operands = [props.get_texture(key) for key in numbered]
        self.weight, self.weight_value = None, None
        if self.op == "mix":
            if "weight" not in props:
                raise ChannelExpressionError("channel_expression: mix needs a weight (a texture "
                                             "or a number)")
            value = props.get("weight")
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                if not np.isfinite(value):
                    raise ChannelExpressionError(f"channel_expression: weight={value!r} must be "
                                                 f"finite")
                self.weight_value = mi.Float(float(value))
            else:
                self.weight = props.get_texture("weight")
        elif "weight" in props:
            raise ChannelExpressionError(f"channel_expression: weight belongs to mix, not "
                                         f"{self.op}")
        self.parameters_changed([])

    # -- Mitsuba object protocol -------------------------------------------

    def traverse(self, cb):
        flags = mi.ParamFlags.Differentiable
        for k, operand in enumerate(self.operands):
            cb.put(f"operand_{k}", operand, flags)
        if self.weight is not None:
            cb.put("weight", self.weight, flags)
        elif self.weight_value is not None:
            cb.put("weight", self.weight_value, flags)

    def parameters_changed(self, keys=[]):
        """Decide again what can be skipped, from the operands' values as they are now. At
        an update (Mitsuba names ``keys``) nothing is read back — on a GPU a read waits
        for every queued kernel, at every step of an optimisation: the folded constant
        is kept (on the device); the shortcuts that need its value (a product by 0, a mix
        at weight 0 or 1) keep the decision made from values while the constants it was
        made from are the same variables (:meth:`_decided_from`), are decided again where
        the host holds the value — a number ``weight`` set as a Python number, a literal —
        and are off otherwise (docs/design-decisions.md, "The update path")."""
        reading = not keys or not dr.is_jit_v(mi.Float)   # at load, or values on the host
        weight_held = None          # the number weight, where the host holds it
        if self.weight_value is not None:
            if reading or self.weight_value.state == dr.VarState.Literal:
                weight_held = self.weight_value[0] if dr.is_jit_v(mi.Float) \
                    else numbers(self.weight_value)[0]     # a literal's: read without waiting
            dr.make_opaque(self.weight_value)
        self._operand_parameters = None          # traversed again: an operand may be new
        self._state = self._operand_state()
        self.constants = [_constant(t) for t in self.operands]
        self.constant = _opaque(self._combined(self.constants))
        # Structural decisions (a new one traces a new kernel); never while a value is
        # differentiated — the constant's, or any inside the operands: the part left out
        # carries its derivative, 0 by structure there (a factor 0, a weight 0 or 1), and
        # left out it would leave the parameter unattached (prb raises).
        differentiated = self._operands_differentiated()
        decided_from = self._decided_from()
        previous = getattr(self, "_decision", None)
        if not reading and previous is not None \
                and previous[0].fingerprint == decided_from.fingerprint:
            # The constants are the very variables the last decision was made from: their
            # values too (a copy of each is held, so no index was reused).
            zero_product, mix_side = previous[1], previous[2]
        else:
            zero_product = self.op == "multiply" and self.constant is not None and reading \
                and not dr.grad_enabled(self.constant) and not np.any(numbers(self.constant))
            mix_side = None          # "a" or "b" when the weight is the constant 0 or 1
            if self.op == "mix" and (reading or weight_held is not None):
                weight = self.weight_value if self.weight is None else _constant(self.weight)
                if weight is not None and not dr.grad_enabled(weight):
                    w = np.array([weight_held]) if self.weight is None else numbers(weight)
                    mix_side = "a" if np.all(w == 0.0) else "b" if np.all(w == 1.0) else None
        self._decision = (decided_from, zero_product, mix_side)
        self.zero_product = zero_product and not differentiated
        self.mix_side = None if differentiated else mix_side
        self._mean, self._mean_state = None, None

    def _operands_differentiated(self) -> bool:
        """Some value inside the operands (or a weight texture) has its gradient enabled."""
        return any(dr.grad_enabled(params[key]) for params in self._operand_parameters
                   for key in params.keys())

    def _decided_from(self) -> OperandState:
        """A fingerprint of what the skipping decisions are made from: which operands are
        constant, the variables of the constant operands and of the weight (a texture's,
        or the number), copies of them held (see :meth:`_operand_state`)."""
        maps = [params for params, constant in zip(self._operand_parameters, self.constants)
                if constant is not None] + (self._operand_parameters[len(self.operands):])
        items = [tuple(c is None for c in self.constants)]
        values = [params[key] for params in maps for key in params.keys()]
        if self.weight_value is not None:
            values.append(self.weight_value)
        held = []
        for value in values:
            if dr.is_jit_v(mi.Float):
                held.append(type(value)(value))
                items.append(tuple(dr.detail.collect_indices(value)))
            else:
                items.append(repr(value))
        return OperandState(hash(tuple(items)), Kept(held))

    def _operand_state(self):
        """A fingerprint of every value inside the operands (and a weight texture): their
        Dr.Jit variables, or their values in the scalar variant. ``mi.traverse`` edits
        replace the variables, so an edit that reached only another parent shows here;
        the state holds copies of the variables (``held``), so that none of them can be
        freed and its index reused by another value while the state is kept. The operands
        are traversed once (:meth:`parameters_changed`); their values are read again each
        time, through those parameter maps."""
        if getattr(self, "_operand_parameters", None) is None:
            self._operand_parameters = [
                mi.traverse(t) for t in self.operands
                + ([self.weight] if self.weight is not None else [])]
        items, held = [], []
        for params in self._operand_parameters:
            for key in params.keys():
                value = params[key]
                # JIT variants: the variables only (transforms too), never their values,
                # which a recording of the kernels (dr.freeze) cannot read.
                if dr.is_jit_v(mi.Float):
                    held.append(type(value)(value))
                    items.append((key, tuple(dr.detail.collect_indices(value))))
                else:
                    items.append((key, repr(value)))
        return OperandState(hash(tuple(items)), Kept(held))

    def _shortcuts(self) -> bool:
        """The skipping decisions of :meth:`parameters_changed` still hold."""
        return self._state.fingerprint == self._operand_state().fingerprint

    @property
    def varying(self):
        """The operands that change over the surface (read now: a shared operand's ramp
        may have gained colours)."""
        return [t for t in self.operands if t.is_spatially_varying()]

    def recording_key(self) -> tuple:
        """What decides the code ``eval`` traces besides Dr.Jit's variables (see
        ``Marble.recording_key``): the operation, the skipping decisions in force, which
        operands are constant or vary, and the operands' own keys."""
        return ("channel_expression", self.op, self._shortcuts(), self.zero_product,
                self.mix_side, tuple(c is None for c in self.constants),
                tuple(t.is_spatially_varying() for t in self.operands),
                self.weight is None, tuple(recording_key(t) for t in self.operands),
                recording_key(self.weight))

    def to_string(self):
        fields = {"op": self.op}
        fields.update({f"operand_{k}": operand for k, operand in enumerate(self.operands)})
        if self.op == "mix":
            fields["weight"] = self.weight if self.weight is not None else \
                float(numbers(self.weight_value)[0])
        return describe("ChannelExpression", fields)

    def is_spatially_varying(self):
        shortcuts = self._shortcuts()
        if self.op == "multiply" and self.zero_product and shortcuts:
            return False
        if self.op == "mix":
            if self.mix_side is not None and shortcuts:
                side = self.operands[0 if self.mix_side == "a" else 1]
                return side.is_spatially_varying()
            return bool(self.varying) or (self.weight is not None
                                          and self.weight.is_spatially_varying())
        return bool(self.varying)

    def max(self):
        """An upper bound: :meth:`held_maximum`, read back."""
        return float(numbers(self.held_maximum()[0])[0])

    def held_maximum(self) -> tuple:
        """(an upper bound of every component, the host values it was made of:
        plugins.held_maximum): sums and products of the operands' maxima (mix: the larger
        side, for weights in [0, 1]; otherwise |1 − w|·max a + |w|·max b). Made from the
        operands' own held maxima as they are now, in Dr.Jit arithmetic (a kernel may read
        it: ``marble_medium``'s density bound), so an edit of a shared operand shows."""
        parts = [held_maximum(t) for t in self.operands]
        maxima, host = [m for m, _ in parts], tuple(v for _, read in parts for v in read)
        if self.op == "add":
            return functools.reduce(operator.add, maxima), host
        if self.op == "multiply":
            return functools.reduce(operator.mul, maxima), host
        if self.weight is None:
            w = self.weight_value
            return dr.abs(1.0 - w) * maxima[0] + dr.abs(w) * maxima[1], host
        w_max, read = held_maximum(self.weight)
        return dr.select(w_max <= 1.0, dr.maximum(maxima[0], maxima[1]),
                         maxima[0] * (1.0 + w_max) + maxima[1] * w_max), host + read

    def mean(self):
        """The mean luminance, one definition whatever the edits before: the operands'
        means combined as if independent (:func:`_means_combined`) — a sum's exactly, a
        product's constants folded first (exact with at most one varying operand and a
        grey constant), a mix at the weight's mean (exact for a constant grey weight). In
        JIT variants a Dr.Jit value made on the device: no point evaluated, nothing read
        back, at load or after an edit (Mitsuba asks from a BSDF's parameters_changed:
        every step of an optimisation). A marble's mean depends on its ramp only, so a
        BSDF's sampling weight made from it follows no in-place edit of scale, period,
        distortion, gain or lacunarity: an image is the same bits whichever values came
        before. Kept while the operands' variables are the same."""
        state = self._operand_state()
        if self._mean is None or self._mean_state.fingerprint != state.fingerprint:
            self._mean, self._mean_state = _means_combined(self), state
            if dr.is_jit_v(mi.Float):
                # Evaluated (a kernel queued, nothing read): a BSDF's weight made from it
                # then has the same bits whether the BSDF was loaded or updated (a lazy
                # mean would be folded into whichever kernel reads it first).
                dr.make_opaque(self._mean)
        return mi.Float(self._mean)

    # -- Evaluation ------------------------------------------------------------

    def eval(self, si, active=True):
        """The combination of the operands' ``eval``: colours in RGB variants, spectra at
        the lane's wavelengths in spectral ones (a sum, product or mix of spectra)."""
        return self._combine(si, active, rgb=False)

    def eval_3(self, si, active=True):
        """The combination of the operands' colours. Spectral variants: of their
        ``eval_3``, where every operand gives its RGB colour (:func:`gives_rgb`)."""
        if not mi.is_spectral:
            return self.eval(si, active)
        if not gives_rgb(self):
            raise ChannelExpressionError(
                "channel_expression: eval_3 in a spectral variant needs operands that keep "
                "an RGB colour (marble, channel_expression, uniform); Mitsuba's srgb and "
                "bitmap hold spectra there")
        return self._combine(si, active, rgb=True)

    def eval_1(self, si, active=True):
        """The luminance; in spectral variants of the RGB colour where the operands keep
        one, else of the spectrum at the lane's wavelengths (Mitsuba's ``luminance``)."""
        if mi.is_spectral and not gives_rgb(self):
            return mi.luminance(self.eval(si, active), si.wavelengths, active)
        return mi.luminance(self.eval_3(si, active))

    def _combine(self, si, active, rgb: bool):
        """:meth:`eval` (``rgb`` False) or, in spectral variants, :meth:`eval_3` (True)."""
        width = dr.width(si.p) if dr.is_jit_v(mi.Float) else 1
        shortcuts = self._shortcuts()

        def value_of(texture):
            return texture.eval_3(si, active) if rgb else evaluate(texture, si, active)

        if self.op != "mix":
            if self.zero_product and shortcuts:
                return _full(None, width, rgb)
            combine = operator.add if self.op == "add" else operator.mul
            # The constants first, as one constant (folded when the operands last changed
            # through this expression; never in spectral variants), then the rest.
            folded = shortcuts and self.constant is not None
            total = self.constant if folded else None
            for constant in ((False,) if folded else (True, False)):
                for texture in self.operands:
                    if texture.is_spatially_varying() != constant:
                        value = value_of(texture)
                        total = value if total is None else combine(total, value)
            return _full(total, width, rgb)
        mix_side = self.mix_side if shortcuts else None
        a, b = (None if mix_side == "ab"[1 - k] else
                self.constants[k] if shortcuts and self.constants[k] is not None else
                value_of(self.operands[k]) for k in (0, 1))
        if mix_side == "a":
            return _full(a, width, rgb)
        if mix_side == "b":
            return _full(b, width, rgb)
        w = self.weight_value if self.weight is None else value_of(self.weight)
        return _full(a * (1.0 - w) + b * w, width, rgb)

    def eval_1_grad(self, si, active=True):
        """∂(luminance)/∂(u, v): the operands' own gradients for a sum (luminance is
        linear); central differences of :meth:`eval_1` for a product or a mix, moving the
        point along ∂p/∂u, ∂p/∂v and (u, v) together (marble reads the point, an image the
        (u, v)), with a step of GRADIENT_STEP in (u, v)."""
        if self.op == "add":
            gradient = dr.zeros(mi.Vector2f, dr.width(si.p))
            for texture in self.varying:
                gradient += texture.eval_1_grad(si, active)
            return gradient
        h = GRADIENT_STEP
        out = []
        for axis, dp in ((0, si.dp_du), (1, si.dp_dv)):
            values = []
            for sign in (1.0, -1.0):
                moved = mi.SurfaceInteraction3f(si)
                moved.p = si.p + dp * (sign * h)
                step = mi.Vector2f(sign * h if axis == 0 else 0.0, sign * h if axis == 1 else 0.0)
                moved.uv = si.uv + step
                values.append(self.eval_1(moved, active))
            out.append((values[0] - values[1]) / (2.0 * h))
        return mi.Vector2f(out[0], out[1])

    # -- helpers ---------------------------------------------------------------

    def _combined(self, constants):
        """The sum or product of the operands' ``constants`` that are not None (None: there
        are none, or a mix)."""
        values = [c for c in constants if c is not None]
        if self.op == "mix" or not values:
            return None
        combine = operator.add if self.op == "add" else operator.mul
        total = values[0]
        for value in values[1:]:
            total = combine(total, value)
        return total


def _opaque(value):
    """A folded constant as an opaque Color3f: a new value reuses the kernel."""
    if value is not None and dr.is_jit_v(mi.Float) and not dr.grad_enabled(value):
        value = mi.Color3f(value)
        dr.make_opaque(value)
    return value


def _means_combined(texture):
    """The operands' means combined as if independent: a sum of means; a product of the
    folded constant's luminance and the varying operands' means; a mix at the weight's
    mean (a constant weight's luminance; a number as it is). A constant operand is taken
    by its luminance, as marble's and Mitsuba's ``bitmap``'s means are (Mitsuba's ``rgb``
    averages its components instead). JIT variants: in Dr.Jit arithmetic, detached,
    nothing read back; the scalar variant: the same on Python floats."""
    def detached(value):
        return dr.detach(value) if dr.is_jit_v(mi.Float) else value

    def mean_of(operand, constant):
        return detached(mi.Float(operand.mean() if constant is None
                                 else mi.luminance(mi.Color3f(constant))))

    constants = [_constant(t) for t in texture.operands]
    if texture.op == "mix":
        means = [mean_of(t, c) for t, c in zip(texture.operands, constants)]
        w = detached(mi.Float(texture.weight_value)) if texture.weight is None \
            else mean_of(texture.weight, _constant(texture.weight))
        return (1.0 - w) * means[0] + w * means[1]
    combine = operator.add if texture.op == "add" else operator.mul
    parts = [mean_of(t, None) for t, c in zip(texture.operands, constants) if c is None]
    folded = texture._combined(constants)
    if folded is not None:
        parts.append(mean_of(None, folded))
    return functools.reduce(combine, parts)


def _constant(texture):
    """The colour of a texture that is the same everywhere, else None (always None in
    spectral variants: there its value is a spectrum that depends on the wavelengths)."""
    if texture.is_spatially_varying() or mi.is_spectral:
        return None
    si = dr.zeros(mi.SurfaceInteraction3f, 1) if dr.is_jit_v(mi.Float) \
        else dr.zeros(mi.SurfaceInteraction3f)
    return texture.eval(si)


def _full(value, width: int, rgb: bool = True):
    """A Color3f of ``width`` lanes (a folded constant has one); a spectrum (the variant's
    UnpolarizedSpectrum, Color3f in RGB variants) unless ``rgb``."""
    kind = mi.Color3f if rgb else mi.UnpolarizedSpectrum
    if value is None:
        return dr.zeros(kind, width)
    if dr.is_jit_v(mi.Float):
        return kind(value) + dr.zeros(kind, width)
    return kind(value)


def gives_rgb(texture) -> bool:
    """Whether ``texture``'s ``eval_3`` is its RGB colour in a spectral variant: a marble
    (and any texture of mimarble that computes a colour), an expression of such operands,
    Mitsuba's ``uniform``. (``srgb``'s ``eval_3`` there gives its model coefficients,
    ``bitmap``'s raises.)"""
    if isinstance(texture, ChannelExpression):
        return all(gives_rgb(t) for t in texture.operands
                   + ([texture.weight] if texture.weight is not None else []))
    return hasattr(texture, "srgb_table") or texture.class_name() == "UniformSpectrum"
