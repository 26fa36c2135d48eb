"""The marble studio's engine: a scene edited live, its frames rendered by a thread of its own (issue 41).

:class:`~mimarble.studio.session.StudioSession` (mimarble/studio/session.py) is the API the
page, the server and the notebook use; its render thread is mimarble/studio/worker.py, its
frames mimarble/studio/frames.py, the histograms of t mimarble/studio/histogram.py, the
camera's moves mimarble/studio/camera.py. Nothing here serves HTTP.
"""

from __future__ import annotations

from .frames import Frame
from .session import StudioError, StudioSession

__all__ = ["StudioSession", "Frame", "StudioError"]
