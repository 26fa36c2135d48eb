"""The studio's compare, the child's side: the float64 reference of one scene, in a process of its own.

``python -m mimarble.studio.reference_process FOLDER``: reads ``FOLDER/scene.pickle``
(a scene model the studio wrote there, in a folder only its user can read), renders it
with the reference tracer (``mimarble.reference.render``, at the scene's samples) and
writes ``FOLDER/reference.npy`` (float64 (H, W, 3)) under a temporary name, renamed
when whole. A process, not a thread: the reference is NumPy (the GIL would slow the
render thread) and the studio cancels it by killing it (mimarble/studio/compare.py).
Imports neither Dr.Jit nor Mitsuba. Errors: the message on stderr, exit status 2.
"""

from __future__ import annotations

import os
import pickle
import sys
from pathlib import Path


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    folder = Path(argv[0])
    try:
        with open(folder / "scene.pickle", "rb") as f:
            scene = pickle.load(f)       # written by this user's studio, in its own folder
        from mimarble.reference.tracer import render
        import numpy as np
        image = render(scene)
        partial = folder / "reference.partial.npy"
        np.save(partial, image)
        os.replace(partial, folder / "reference.npy")
    except Exception as error:           # one sentence for the studio to show
        print(f"{type(error).__name__}: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
