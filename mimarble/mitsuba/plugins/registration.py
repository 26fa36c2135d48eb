"""Registering mimarble's Python plugins with Mitsuba, for every variant.

A Mitsuba plugin written in Python subclasses a *variant's* class
(``mi.Texture`` of ``llvm_ad_rgb`` is not that of ``scalar_rgb``), and nanobind
types accept a single base. So each plugin is written once as a plain class of
methods, and bound to the current variant's base when registered: at import,
and again whenever the variant changes (a Mitsuba variant callback).
"""

from __future__ import annotations

import numpy as np

from mimarble.runtime import environment
from mimarble.texture import srgb_model

dr, mi = environment.import_drjit_and_mitsuba()


def numbers(value) -> np.ndarray:
    """The components of a one-lane (or scalar) Dr.Jit value, as float64 NumPy: what a
    plugin reads back of its own parameters (one lane each) after ``mi.traverse`` edits."""
    if isinstance(value, (int, float)):
        return np.array([float(value)])
    if dr.is_jit_v(type(value)):    # each component's own memory: no kernel packs them
        value = dr.detach(value)
        if dr.depth_v(value) > 1:
            return np.concatenate([numbers(value[k]) for k in range(len(value))])
        return np.asarray(value.numpy(), dtype=np.float64).ravel()
    return np.ravel(np.array(dr.detach(value), dtype=np.float64))


def first_number(value) -> float:
    """The single value of a one-lane Dr.Jit array or a number (NaN when empty)."""
    values = numbers(value)
    return float(values[0]) if values.size else float("nan")


def luminance(colour) -> float:
    """Mitsuba's ``luminance`` of a colour (or a number), as a Python float."""
    return first_number(mi.luminance(mi.Color3f(colour)))


def largest_component(colour):
    """The largest of a colour's three components, per lane (what the adaptive estimates
    compare against their threshold: the worst colour)."""
    return dr.maximum(dr.maximum(colour[0], colour[1]), colour[2])


def describe(class_name: str, fields: dict) -> str:
    """A plugin's ``to_string`` in Mitsuba's form: ``Name[`` then one ``key = value`` a
    line, indented (a nested object's own lines indented with it), then ``]``."""
    if not fields:
        return f"{class_name}[]"
    lines = []
    for key, value in fields.items():
        text = str(value).replace("\n", "\n  ")
        lines.append(f"  {key} = {text}")
    return f"{class_name}[\n" + ",\n".join(lines) + "\n]"


def transform_matrix(transform):
    """A Mitsuba transform's 4×4 matrix as float64 NumPy, in every variant (a JIT
    transform holds one matrix as width-1 arrays; a scalar one holds floats)."""
    m = transform.matrix
    return np.array([[first_number(m[i][j]) for j in range(4)] for i in range(4)])


class Kept:
    """A holder Dr.Jit's traversal does not enter (it knows no such type): what a plugin
    keeps for itself rather than for its kernels — the last valid values it restores after
    a refused edit — so that a recording's inputs (mimarble/mitsuba/rendering/replay.py) do not
    carry it, and every replay does not traverse it."""

    __slots__ = ("value",)

    def __init__(self, value):
        self.value = value


def recording_key(plugin) -> tuple | None:
    """What decides the code a plugin traces besides its Dr.Jit variables: a mimarble
    plugin's ``recording_key()``; a Mitsuba plugin's type (its structure is fixed when
    it is loaded); None for none. A recording of kernels (mimarble/mitsuba/rendering/replay.py) is
    replayed only for the same keys."""
    if plugin is None:
        return None
    own = getattr(plugin, "recording_key", None)
    return own() if own is not None else (type(plugin).__name__, plugin.class_name()
                                          if hasattr(plugin, "class_name") else None)


def held_maximum(texture) -> tuple:
    """(an upper bound of every component of ``texture``'s colour, the host values it was
    made of). A mimarble texture's ``held_maximum()``: a Dr.Jit value computed from what
    the texture holds (no read back), which a kernel reads as it is now — after an edit
    that Mitsuba told only another parent of (``mi.traverse`` tells a node's first
    parent). Any other texture's ``max()``, a Python float read now, and also the second
    item: what a recording's key must hold, since a kernel traced with it holds it as a
    constant. ``max()`` itself may raise (not implemented: ``checkerboard``).

    A recording (``dr.freeze``) may not read a value back, and ``srgb``'s and ``uniform``'s
    ``max()`` read theirs: inside one, the value read last outside it is used — the one
    the recording's key holds, read by that key's :func:`recording_key` just before."""
    own = getattr(texture, "held_maximum", None)
    if own is not None:
        return own()
    value = None
    if dr.is_jit_v(mi.Float) and dr.flag(dr.JitFlag.FreezingScope):
        value = _maxima_read.get(id(texture))
    if value is None:
        value = float(texture.max())
        if len(_maxima_read) >= 256:
            _maxima_read.pop(next(iter(_maxima_read)))
        _maxima_read[id(texture)] = value
    return value, (value,)


#: Mitsuba textures' ``max()`` as :func:`held_maximum` last read them outside a recording.
_maxima_read: dict[int, float] = {}


# kind -> (mitsuba base class name, registration function name)
_KINDS = {
    "texture": ("Texture", "register_texture"),
    "bsdf": ("BSDF", "register_bsdf"),
    "integrator": ("SamplingIntegrator", "register_integrator"),
    "emitter": ("Emitter", "register_emitter"),
    "medium": ("Medium", "register_medium"),
    "phase": ("PhaseFunction", "register_phase"),
}
#: (kind, name, class) of every plugin declared with :func:`plugin`, in declaration order.
declared_plugins: list[tuple[str, str, type]] = []
_bound: dict[tuple[str, str], type] = {}


class PluginClass(type):
    """What a declared plugin's class is: it stands for the plugin in every variant.

    ``Marble(props)`` makes one in the current variant (``Marble()``: with no
    properties), and ``isinstance(x, Marble)`` holds for a marble of any variant — what
    ``mi.load_dict`` returns — as it does for Mitsuba's own classes."""

    def __call__(cls, props=None):
        return bound_class(cls.plugin_name)(mi.Properties() if props is None else props)

    def __instancecheck__(cls, instance):
        return any(isinstance(instance, bound) for (name, _), bound in _bound.items()
                   if name == cls.plugin_name)


def plugin(kind: str, name: str):
    """Class decorator: declare ``cls`` as the Mitsuba plugin ``name`` of ``kind``."""
    def declare(cls):
        namespace = {k: v for k, v in vars(cls).items() if k not in ("__dict__", "__weakref__")}
        declared = PluginClass(cls.__name__, cls.__bases__, {**namespace, "plugin_name": name})
        declared_plugins.append((kind, name, declared))
        return declared
    return declare


def bound_class(name: str, variant: str | None = None) -> type:
    """The plugin class ``name`` bound to ``variant``'s Mitsuba base (default: current):
    its methods, and those of the plain classes it derives from, on that base."""
    variant = variant or mi.variant()
    if (name, variant) not in _bound:
        kind, _, methods = next(p for p in declared_plugins if p[1] == name)
        base = getattr(mi, _KINDS[kind][0])
        namespace = {}
        for klass in reversed(methods.__mro__[:-1]):          # object's own: not copied
            namespace.update({k: v for k, v in vars(klass).items()
                              if k not in ("__dict__", "__weakref__")})
        _bound[(name, variant)] = type(methods.__name__, (base,), namespace)
    return _bound[(name, variant)]


class RGBTexture:
    """The parts of Mitsuba's Texture interface that a texture of RGB colours answers
    alike, as Mitsuba's ``bitmap`` and ``srgb`` do: the texture computes its colour in
    ``eval_3``; ``eval`` is that colour in RGB variants and, in spectral ones, its smooth
    spectrum at the lane's wavelengths (mimarble/texture/srgb_model.py, Mitsuba's sRGB model, from
    the table the texture holds as ``srgb_table``). ``eval_1`` is the colour's luminance
    in every variant (``bitmap`` refuses it in spectral variants; a marble still has one)."""

    def eval(self, si, active=True):
        colour = self.eval_3(si, active)
        if not mi.is_spectral:
            return colour
        return srgb_model.spectrum(self.srgb_table, colour, si.wavelengths)

    def eval_1(self, si, active=True):
        return mi.luminance(self.eval_3(si, active))

    def sample_spectrum(self, si, sample, active=True):
        """RGB variants sample no wavelengths: (no wavelengths, the colour). Spectral ones:
        wavelengths uniform over Mitsuba's CIE range, weighted by the spectrum over their
        density (:meth:`pdf_spectrum`), as ``srgb`` and ``bitmap`` sample in Mitsuba 3.9.1."""
        if not mi.is_spectral:
            return dr.zeros(type(si.wavelengths)), self.eval(si, active)
        moved = mi.SurfaceInteraction3f(si)
        moved.wavelengths = mi.MI_CIE_MIN + (mi.MI_CIE_MAX - mi.MI_CIE_MIN) * sample
        return moved.wavelengths, self.eval(moved, active) * (mi.MI_CIE_MAX - mi.MI_CIE_MIN)

    def pdf_spectrum(self, si, active=True):
        """The density :meth:`sample_spectrum` draws ``si.wavelengths`` with: in spectral
        variants 1/(MAX − MIN) per nm inside Mitsuba's CIE range, 0 outside (so weight × pdf
        = ``eval``); 0 in RGB variants, which sample no wavelengths. (Mitsuba 3.9.1's ``srgb``
        and ``bitmap`` sample the same way and leave ``pdf_spectrum`` unimplemented.)"""
        wavelengths = si.wavelengths
        if not mi.is_spectral:
            return dr.zeros(type(wavelengths))
        inside = (wavelengths >= mi.MI_CIE_MIN) & (wavelengths <= mi.MI_CIE_MAX) & active
        return type(wavelengths)(dr.select(inside, 1.0 / (mi.MI_CIE_MAX - mi.MI_CIE_MIN), 0.0))

    def spectral_resolution(self):
        return 0.0


def register_all(variant: str | None = None) -> None:
    """Register every declared plugin for the current variant."""
    for kind, name, _ in declared_plugins:
        cls = bound_class(name, variant)
        getattr(mi, _KINDS[kind][1])(name, lambda props, cls=cls: cls(props))


def _on_variant_change(old, new):
    if new is not None:
        register_all(new)


def install() -> None:
    """Register now (if a variant is set) and on every later variant change.

    Mitsuba 3.9 offers no public hook for a variant change; ``mi.detail`` has the one it
    uses itself. Without it (another Mitsuba), the plugins are registered for the variant
    set now, and :func:`register_all` registers them for another."""
    if mi.variant() is not None:
        register_all()
    add_callback = getattr(getattr(mi, "detail", None), "add_variant_callback", None)
    if add_callback is not None:
        add_callback(_on_variant_change)
