"""Registering mimarble's Python plugins with Mitsuba, for every variant.

A Mitsuba plugin written in Python subclasses a *variant's* class
(``mi.Texture`` of ``llvm_ad_rgb`` is not that of ``scalar_rgb``), and nanobind
types accept a single base. So each plugin is written once as a plain class of
methods, and bound to the current variant's base when registered: at import,
and again whenever the variant changes (a Mitsuba variant callback).
"""

from __future__ import annotations

import numpy as np

from . import environment

dr, mi = environment.import_drjit_and_mitsuba()


def numbers(value) -> np.ndarray:
    """The components of a one-lane (or scalar) Dr.Jit value, as float64 NumPy: what a
    plugin reads back of its own parameters (one lane each) after ``mi.traverse`` edits."""
    if isinstance(value, (int, float)):
        return np.array([float(value)])
    return np.ravel(np.array(dr.detach(value), dtype=np.float64))


def first_number(value) -> float:
    """The single value of a one-lane Dr.Jit array or a number (NaN when empty)."""
    values = numbers(value)
    return float(values[0]) if values.size else float("nan")


def luminance(colour) -> float:
    """Mitsuba's ``luminance`` of a colour (or a number), as a Python float."""
    return first_number(mi.luminance(mi.Color3f(colour)))


def transform_matrix(transform):
    """A Mitsuba transform's 4×4 matrix as float64 NumPy, in every variant (a JIT
    transform holds one matrix as width-1 arrays; a scalar one holds floats)."""
    m = transform.matrix
    return np.array([[first_number(m[i][j]) for j in range(4)] for i in range(4)])


# kind -> (mitsuba base class name, registration function name)
_KINDS = {
    "texture": ("Texture", "register_texture"),
    "bsdf": ("BSDF", "register_bsdf"),
    "integrator": ("SamplingIntegrator", "register_integrator"),
}
_plugins: list[tuple[str, str, type]] = []
_bound: dict[tuple[str, str], type] = {}


def plugin(kind: str, name: str):
    """Class decorator: declare ``cls`` as the Mitsuba plugin ``name`` of ``kind``."""
    def declare(cls):
        _plugins.append((kind, name, cls))
        return cls
    return declare


def bound_class(name: str, variant: str | None = None) -> type:
    """The plugin class ``name`` bound to ``variant``'s Mitsuba base (default: current)."""
    variant = variant or mi.variant()
    if (name, variant) not in _bound:
        kind, _, methods = next(p for p in _plugins if p[1] == name)
        base = getattr(mi, _KINDS[kind][0])
        namespace = {k: v for k, v in vars(methods).items() if k not in ("__dict__", "__weakref__")}
        _bound[(name, variant)] = type(methods.__name__, (base,), namespace)
    return _bound[(name, variant)]


def register_all(variant: str | None = None) -> None:
    """Register every declared plugin for the current variant."""
    for kind, name, _ in _plugins:
        cls = bound_class(name, variant)
        getattr(mi, _KINDS[kind][1])(name, lambda props, cls=cls: cls(props))


def _on_variant_change(old, new):
    if new is not None:
        register_all(new)


def install() -> None:
    """Register now (if a variant is set) and on every later variant change."""
    if mi.variant() is not None:
        register_all()
    mi.detail.add_variant_callback(_on_variant_change)
