"""Equal operands evaluated once per shading point: the ``channel_material``'s context.

Within :func:`shared_evaluations` (one per shading call) :func:`evaluate` evaluates each
texture object once, so that a texture shared by several channels, or inside expressions of
several, costs one evaluation; with ``alternates`` a marble's second estimate is kept
beside its colour and an expression's is combined from its operands'
(:func:`evaluate_alternate`, adaptive sampling's). The ``channel_expression`` plugin
(mimarble/mitsuba/plugins/channel_expression.py) evaluates its operands through it; plain
Python, no Dr.Jit.
"""

from __future__ import annotations

import contextlib
import threading

__all__ = ["shared_evaluations", "evaluate", "evaluate_primary", "evaluate_alternate",
           "textures_within"]

#: The evaluations of the current shading call, per thread: Mitsuba's scalar variant
#: shades samples on several threads at once, each in its own call.
_shading = threading.local()


@contextlib.contextmanager
def shared_evaluations(alternates: bool = False):
    """Within this context :func:`evaluate` evaluates each texture object once (the
    ``channel_material`` opens one per shading call: its channels share a point).
    ``alternates``: marbles also give their second estimate (``Marble.eval_and_alternate``),
    which :func:`evaluate_alternate` then combines."""
    outer = (getattr(_shading, "evaluations", None), getattr(_shading, "alternates", None),
             getattr(_shading, "alternate_walk", False))
    _shading.evaluations, _shading.alternates = {}, ({} if alternates else None)
    _shading.alternate_walk = False
    try:
        yield
    finally:
        _shading.evaluations, _shading.alternates, _shading.alternate_walk = outer


def evaluate(texture, si, active=True):
    """``texture.eval(si, active)``, once per texture within :func:`shared_evaluations`
    (inside :func:`evaluate_alternate`: the texture's second estimate)."""
    evaluations = getattr(_shading, "evaluations", None)
    if evaluations is None:
        return texture.eval(si, active)
    key = id(texture)
    alternates = _shading.alternates
    if _shading.alternate_walk:
        if key not in alternates:
            # An expression again, from its operands' second estimates; a marble's was
            # kept with its colour; any other texture (rgb, bitmap) has one estimate only.
            if hasattr(texture, "operands"):         # a channel_expression
                alternates[key] = texture.eval(si, active)
            else:
                alternates.setdefault(key, evaluate_primary(texture, si, active))
        return alternates[key]
    return evaluate_primary(texture, si, active)


def evaluate_primary(texture, si, active=True):
    """The texture's colour, once within :func:`shared_evaluations`; a marble's second
    estimate kept beside it when alternates are asked for."""
    evaluations, alternates = _shading.evaluations, _shading.alternates
    key = id(texture)
    if key not in evaluations:
        if alternates is not None and hasattr(texture, "eval_and_alternate"):
            evaluations[key], alternates[key] = texture.eval_and_alternate(si, active)
        else:
            evaluations[key] = texture.eval(si, active)
    return evaluations[key]


def evaluate_alternate(texture, si, active=True):
    """Within ``shared_evaluations(alternates=True)``, after :func:`evaluate` of the same
    texture: its second estimate — a marble's own, an expression's combined from its
    operands' (the same arithmetic), any other texture's colour."""
    _shading.alternate_walk = True
    try:
        return evaluate(texture, si, active)
    finally:
        _shading.alternate_walk = False


def textures_within(texture):
    """The texture and, for an expression, every texture inside it (None: nothing)."""
    if texture is None:
        return
    yield texture
    for inner in list(getattr(texture, "operands", ())) + [getattr(texture, "weight", None)]:
        yield from textures_within(inner)
