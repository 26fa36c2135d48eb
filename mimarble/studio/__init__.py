"""The marble studio's engine: a scene edited live, its frames rendered by a thread of its own (issue 41).

:class:`~mimarble.studio.session.StudioSession` (mimarble/studio/session.py) is the API the
page, the server and the notebook use; its render thread is mimarble/studio/worker.py, its
frames mimarble/studio/frames.py, the histograms of t mimarble/studio/histogram.py, the
camera's moves mimarble/studio/camera.py. Nothing here serves HTTP.

The web side: the server mimarble/studio/server.py (its gate guard.py, its messages
messages.py, the page static/), the notebook's view notebook.py. The package itself is
callable: ``mimarble.studio(scene)`` is :func:`mimarble.studio.notebook.studio` (the studio
inline in Jupyter) — a package and a function cannot share the name ``mimarble.studio``
otherwise, as importing a submodule sets the package as that attribute.
"""

from __future__ import annotations

import sys
import types

from .frames import Frame
from .errors import StudioError
from .session import StudioSession

__all__ = ["StudioSession", "Frame", "StudioError"]


class _CallableModule(types.ModuleType):
    """This package's module type: calling it starts the studio in a notebook."""

    def __call__(self, scene, mode=None, **options):
        """``mimarble.studio(scene, mode=None, port=0, height=760)``: see
        :func:`mimarble.studio.notebook.studio`."""
        from .notebook import studio
        return studio(scene, mode, **options)


sys.modules[__name__].__class__ = _CallableModule
