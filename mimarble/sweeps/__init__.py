"""Sweeps: one scene, some parameters varied, one image per combination.

``mimarble.sweeps.sweep`` (also ``mimarble.sweep``) is :func:`mimarble.sweeps.run.sweep`.
"""

import importlib


def __getattr__(name):
    if name == "sweep":
        return importlib.import_module(f"{__name__}.run").sweep
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
