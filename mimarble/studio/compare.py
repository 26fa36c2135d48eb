"""The studio's compare: the float64 reference in a child process, cancelled by the next edit.

:class:`Comparison` starts ``python -m mimarble.studio.reference_process`` on the scene
as it is edited now (pickled into a private temporary folder), waits for it in a thread,
then measures the studio's own frame of that version at the same spp — whitted mode's
final frame, which is ``mimarble render``'s image (tests/test_studio_engine.py) —
against it, as ``mimarble compare`` does (``tools.compare.image_metrics``: RMSE, PSNR,
max error, pixels off by more than 1/255) and draws the error map
(``tools.compare.error_map``, black → white over 1e-6 … 1e-1). :meth:`cancel` kills
the child and waits for it: no process is left behind, nor its folder.
"""

from __future__ import annotations

import pickle
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np


class Comparison:
    """One reference render and its comparison.

    ============ =======================================================================
    scene        the scene model (whitted mode; the reference renders at its samples)
    version      the session's version it belongs to
    frame_of     ``frame_of(version)``: the session's final frame of that version (may
                 wait for it; raises TimeoutError)
    done         ``done(result)``: called once with the result dict (not when cancelled)
    ============ =======================================================================

    ``status``: ``running``, ``done``, ``failed`` or ``cancelled``.
    """

    def __init__(self, scene, version: int, frame_of, done):
        self.version, self.status = version, "running"
        self._frame_of, self._done = frame_of, done
        self._lock = threading.Lock()
        self._folder = Path(tempfile.mkdtemp(prefix="mimarble-compare-"))
        with open(self._folder / "scene.pickle", "wb") as f:
            pickle.dump(scene, f)
        self._start = time.monotonic()
        self.process = subprocess.Popen(
            [sys.executable, "-m", "mimarble.studio.reference_process", str(self._folder)],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        self._thread = threading.Thread(target=self._wait, name="mimarble-studio-compare",
                                        daemon=True)
        self._thread.start()

    def cancel(self, wait: bool = False) -> None:
        """Kill the child (if it runs) and reap it; status ``cancelled`` unless it had
        finished. ``wait``: also wait for the thread that waited for it (which may be
        waiting for a frame: not while holding the session's lock)."""
        with self._lock:
            if self.status == "running":
                self.status = "cancelled"
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()
        if wait and self._thread is not threading.current_thread():
            self._thread.join(30)

    def _wait(self) -> None:
        try:
            _, stderr = self.process.communicate()
            if self.status == "cancelled":
                return
            if self.process.returncode != 0:
                reason = stderr.decode("utf-8", "replace").strip().splitlines()
                self._finish("failed", {"message": (reason[-1] if reason else
                                                    f"the reference exited with status "
                                                    f"{self.process.returncode}")})
                return
            reference = np.load(self._folder / "reference.npy")
            seconds = time.monotonic() - self._start
            frame = self._frame_of(self.version)
            if self.status == "cancelled" or frame.version != self.version:
                return                          # an edit came: this version is gone
            self._finish("done", _measured(frame, reference, seconds))
        except Exception as error:            # said on the page, never raised in a thread
            self._finish("failed", {"message": f"{type(error).__name__}: {error}"})
        finally:
            shutil.rmtree(self._folder, ignore_errors=True)

    def _finish(self, status: str, result: dict) -> None:
        with self._lock:
            if self.status != "running":
                return
            self.status = status
        self._done({"status": status, "version": self.version, **result})


def _measured(frame, reference: np.ndarray, seconds: float) -> dict:
    """The frame against the reference: ``mimarble compare``'s metrics, the error map
    and the reference as PNG bytes."""
    from mimarble.tools.compare import error_map, image_metrics
    from .frames import encode, png_of_rgb8
    metrics = image_metrics(frame.pixels, reference)
    return {"psnr": metrics["psnr"], "rmse": metrics["rmse"], "max_abs": metrics["max_abs"],
            "frac_over_1_255": metrics["frac_over_1_255"], "spp": frame.spp,
            "seconds": round(seconds, 3),
            "difference_png": png_of_rgb8(error_map(frame.pixels, reference)),
            "reference_png": encode(reference.astype(np.float32), "png")[0]}
