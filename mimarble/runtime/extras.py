"""Optional extras: the features that need them, and the one sentence when one is missing.

A texture needs neither Dask nor matplotlib, so they are extras of the package
(pyproject.toml's ``[project.optional-dependencies]``; ``./go`` installs them all):

* ``dask`` — ``dask[distributed]``: sweeps with ``--workers`` or ``--scheduler``
  (mimarble/sweeps/cluster.py);
* ``matplotlib`` — ``bench --plot`` (mimarble/bench/plot.py) and the legend under
  ``compare --diff``'s error map (mimarble/tools/compare.py);
* ``studio`` — Starlette, uvicorn and websockets: ``mimarble studio`` and
  ``mimarble.studio(scene)`` (mimarble/studio/server.py).

A feature asks for its extra before it starts (:func:`missing_extra` for a sentence its
own error carries, :func:`require_extra` for :class:`MissingExtra`) and again where it
imports it, so a missing one is a sentence that names it, not a traceback minutes into
a run.
"""

from __future__ import annotations

import importlib

from mimarble.runtime.environment import EnvironmentProblem

#: Each extra: the module whose import says it is installed.
EXTRAS = {
    "dask": "distributed",
    "matplotlib": "matplotlib",
    "studio": "uvicorn",
}
#: Each feature that needs an extra: (the extra, the feature in words, a plural).
FEATURES = {
    "sweep --workers": ("dask", "sweeps with --workers"),
    "sweep --scheduler": ("dask", "sweeps with --scheduler"),
    "bench --plot": ("matplotlib", "benchmark plots (bench --plot)"),
    "compare --diff": ("matplotlib", "error maps' legends (compare --diff)"),
    "studio": ("studio", "the marble studio's pages (mimarble studio, mimarble.studio)"),
}


class MissingExtra(EnvironmentProblem, ImportError):
    """A feature whose optional extra is not installed; the message names the extra and
    how to install it (an ImportError too, for callers that catch that)."""


def missing_extra(feature: str) -> str | None:
    """None if the extra ``feature`` needs (a key of :data:`FEATURES`) is installed, else
    the sentence that says the feature needs it and how to install it."""
    extra, words = FEATURES[feature]
    try:
        importlib.import_module(EXTRAS[extra])
    except ImportError:
        return f"{words} need the '{extra}' extra: pip install 'mimarble[{extra}]'"
    return None


def require_extra(feature: str) -> None:
    """Raise :class:`MissingExtra` (:func:`missing_extra`'s sentence) unless the extra
    ``feature`` needs is installed."""
    problem = missing_extra(feature)
    if problem is not None:
        raise MissingExtra(problem)
