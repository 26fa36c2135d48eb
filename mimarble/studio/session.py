"""A studio session: one scene file, edited live, rendered by its own thread.

:class:`StudioSession` is the engine under ``mimarble studio`` and the notebook's studio
(the page and the server are mimarble/studio/server…, another module): no HTTP here.
It holds the scene as the file says it (its text and model), the edits made since
(key paths and values, the latest value of each, in order), the view (mode, image size)
and the newest frame, and hands every render to its :class:`RenderThread`
(mimarble/studio/worker.py, which states the threading contract). Every public method may
be called from any thread; none waits for a render.

Decisions (docs/design-decisions.md, "Marble studio engine (issue 41)"):

* An edit is checked by the scene's key registry (``with_value``: the parameter table's
  sentences) before anything changes; a bad value raises ``KeyPathError`` and the state
  keeps its last valid value.
* The mode and the image size are the view, not the file: Save does not write them.
* The file on disk changed (the watcher polls it, :data:`WATCH_SECONDS`): with no unsaved
  edits the session reloads it; with unsaved edits it keeps them, says
  ``disk_changed`` and Save refuses until :meth:`reload` — an editor's save never
  silently throws the studio's edits away, nor the studio's save the editor's. A reload
  that does not parse keeps the last good scene and frame and says the error at
  FILE:LINE:COL.
* A packaged scene (opened by name) is never written: Save refuses, Save as writes a copy.

Save and Save as (the edits written back into the file): mimarble/studio/saving.py.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

from mimarble import scene as scene_language
from mimarble.parameters import ParameterError
from mimarble.runtime import packaged_scenes
from mimarble.scene.edits import KeyPathError, with_image_size, with_value
from mimarble.scene.rewrite import read_scene_text
from .camera import orbited_eye, zoomed_fov
from .compare import Comparison
from .controls import HEIGHT, MODE, WIDTH, controls
from .errors import StudioError, error_dict
from .frames import FRAME_FORMAT, Frame
from .saving import SceneSaving, file_facts
from .worker import RenderThread, Request

#: Seconds between two looks at the scene file's modification time.
WATCH_SECONDS = 0.5
#: The modes the studio renders in (the command line's, less ``preview``): the view's
#: mode control's choices (controls.MODE), declared there once.
MODES = MODE.choices
#: The keys of the view: not in the file, not saved.
VIEW_KEYS = ("mode", "image.width", "image.height")


#: How long a snapshot taken during a drag waits for the whole frame (seconds).
SNAPSHOT_WAIT_S = 10.0


def default_mode(scene) -> str:
    """``path`` when a shape's material is translucent (whitted mode refuses it), else
    ``whitted``, the paper's."""
    used = {shape.material for _, shape in scene.shapes()}
    translucent = any(m.subsurface is not None and m.name in used
                      for m in scene.materials.values())
    return "path" if translucent else "whitted"


class StudioSession(SceneSaving):
    """One scene, edited live (module docstring).

    ============= ======================================================================
    scene         a scene file's path, or a packaged scene's name (``"fig11a"``)
    mode          ``whitted``, ``path`` or None (:func:`default_mode`)
    frame_format  ``png`` or ``jpeg``: how frames are encoded
    watch         poll the file every :data:`WATCH_SECONDS` in a thread (else call
                  :meth:`poll_file`)
    idle_s        seconds without an edit before refinement starts
    ============= ======================================================================

    Raises ``SceneError`` (FILE:LINE:COL) for a file that does not parse, ValueError for
    a mode it does not know.
    """

    def __init__(self, scene, mode: str | None = None, *, frame_format: str = FRAME_FORMAT,
                 watch: bool = True, idle_s: float = 0.15):
        argument = os.fspath(scene)
        path = packaged_scenes.resolve(argument)
        self.packaged = path != argument
        self.path = Path(path)
        self._lock = threading.RLock()
        #: Saves one at a time; the session lock is held only to read and to adopt the
        #: state, not while the text is rewritten and parsed (an edit never waits for that).
        self._save_lock = threading.Lock()
        self._listeners: list = []
        self._closed = False
        self._text, self._stat = self._read()
        self._base = scene_language.parse(self._text, filename=str(self.path),
                                          source=str(self.path))
        if mode is not None and mode not in MODES:
            raise ValueError(f"mode {mode!r:.40} is not one of {', '.join(MODES)}")
        self._mode = mode or default_mode(self._base)
        self._edits: dict = {}            # key → value, since the file was loaded or saved
        self._view: dict = {}             # image.width / image.height given
        self._scene = self._base
        self._shown = (self._base, self._mode)     # the last state a frame showed
        self._version = 0
        self._frame: Frame | None = None
        self._histograms: dict | None = None      # {"version", "histograms"}: the latest
        self._status = {"compiling": False, "rendering": True}
        self._error: dict | None = None
        self._disk_changed = False
        self._frame_ready = threading.Condition(self._lock)
        self._worker = RenderThread(self._publish, self._render_failed, frame_format, idle_s)
        self._worker.start()
        self._compare = None
        self._compare_result = self._compare_note = None
        self._watcher = None
        if watch:
            self._watch_stop = threading.Event()
            self._watcher = threading.Thread(target=self._watch, name="mimarble-studio-watch",
                                             daemon=True)
            self._watcher.start()
        self._submit()

    # -- Listeners -------------------------------------------------------------------------

    def subscribe(self, callback):
        """Call ``callback(kind, payload)`` on every ``frame`` (a Frame), ``histograms``
        (``{"version", "histograms"}``), ``state`` (the :meth:`state` dict), ``compare``
        and ``reload`` (dicts); returns the function that
        unsubscribes it. Called from the session's threads: keep it short."""
        with self._lock:
            self._listeners.append(callback)

        def unsubscribe():
            with self._lock:
                if callback in self._listeners:
                    self._listeners.remove(callback)
        return unsubscribe

    def _emit(self, kind: str, payload) -> None:
        with self._lock:
            listeners = list(self._listeners)
        for callback in listeners:
            try:
                callback(kind, payload)
            except Exception:          # a listener's failure is its own, not the render's
                pass

    def _publish(self, kind: str, payload) -> None:
        """From the render thread: a frame, or a change of its status."""
        if kind == "frame":
            with self._lock:
                if self._frame is None or payload.version >= self._frame.version:
                    self._frame = payload
                if payload.version == self._version:
                    self._shown = (self._scene, self._mode)
                self._status = {"compiling": False, "rendering": not payload.final}
                self._frame_ready.notify_all()
            self._emit("frame", payload)
        elif kind == "histograms":
            with self._lock:
                self._histograms = payload
            self._emit("histograms", payload)
            return
        else:
            with self._lock:
                self._status = dict(payload)
        self._emit("state", self.state())

    def _render_failed(self, request: Request, error: Exception) -> None:
        """A state the render thread could not render: said, and the session goes back
        to the state its last frame showed (when no newer edit has come, and when that
        state is not the one that failed: a first state that cannot render, before any
        frame, stays said, not submitted again and again)."""
        with self._lock:
            self._error = {**error_dict(error), "kind": "render"}
            shown_scene, shown_mode = self._shown
            if request.version == self._version and (
                    request.scene is not shown_scene or request.mode != shown_mode):
                self._scene, self._mode = self._shown
                self._version += 1
                self._worker.submit(Request(self._version, self._scene, self._mode))
        self._emit("state", self.state())

    # -- State -----------------------------------------------------------------------------

    def state(self) -> dict:
        """JSON-able: ``version``, ``compiling``, ``rendering``, ``spp``, ``target_spp``,
        ``mode``, ``width``, ``height``, ``error`` (None or :func:`error_dict`'s, with
        ``kind`` ``parse`` or ``render``), ``dirty`` (unsaved edits), ``disk_changed``,
        ``path``, ``packaged``, ``compare`` (its status)."""
        with self._lock:
            frame = self._frame
            return {"version": self._version, "compiling": self._status["compiling"],
                    "rendering": self._status["rendering"],
                    "spp": frame.spp if frame is not None else 0,
                    "frame_version": frame.version if frame is not None else None,
                    "target_spp": self._scene.image.samples, "mode": self._mode,
                    "width": self._scene.image.width, "height": self._scene.image.height,
                    "error": self._error, "dirty": bool(self._edits),
                    "disk_changed": self._disk_changed, "path": str(self.path),
                    "packaged": self.packaged,
                    "compare": self._compare.status if self._compare is not None else "idle"}

    @property
    def scene(self):
        """The scene model as edited now."""
        with self._lock:
            return self._scene

    @property
    def edits_made(self) -> dict:
        """The edits since the file was loaded or saved: key path → value, in order."""
        with self._lock:
            return dict(self._edits)

    @property
    def text(self) -> str:
        """The file's text as loaded or last saved."""
        with self._lock:
            return self._text

    def latest_frame(self) -> Frame | None:
        with self._lock:
            return self._frame

    def latest_histograms(self) -> dict | None:
        """``{"version", "histograms"}``: the histograms of t computed last (a frame
        whose ``histograms`` is None is followed by these for its version)."""
        with self._lock:
            frame, kept = self._frame, self._histograms
            if frame is not None and frame.histograms is not None and \
                    (kept is None or frame.version >= kept["version"]):
                return {"version": frame.version, "histograms": list(frame.histograms)}
            return kept

    def wait_frame(self, version: int | None = None, final: bool = False,
                   timeout: float = 60.0, whole: bool = False) -> Frame:
        """The first frame of at least ``version`` (default: the current one), at the
        target spp if ``final``, of every pixel (not a drag's reduced frame) if ``whole``;
        TimeoutError after ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        with self._lock:
            version = self._version if version is None else version
            while True:
                frame = self._frame
                if frame is not None and frame.version >= version and \
                        (not final or frame.final) and (not whole or frame.stride == 1):
                    return frame
                left = deadline - time.monotonic()
                if left <= 0 or self._closed:
                    raise TimeoutError(f"no frame of version {version}"
                                       f"{' at its target spp' if final else ''} within "
                                       f"{timeout:g} s")
                self._frame_ready.wait(left)

    # -- Edits -----------------------------------------------------------------------------

    def edit(self, key: str, value) -> int:
        """Set ``key`` (a key path of the scene, or ``mode``, ``image.width``,
        ``image.height``) to ``value``; returns the new version. KeyPathError (a
        ValueError) with the parameter table's sentence, and nothing changed, for a
        value the key cannot take."""
        return self.edits({key: value})

    def edits(self, changes: dict) -> int:
        """Several edits at once: all or none (the first bad one raises), one version."""
        with self._lock:
            scene, mode, view = self._scene, self._mode, dict(self._view)
            kept = dict(self._edits)
            for key, value in changes.items():
                if key == "mode":
                    if not isinstance(value, str) or value not in MODES:
                        raise KeyPathError(f"mode: {value!r:.40} is not one of "
                                           f"{', '.join(MODES)}")
                    mode = value
                elif key in ("image.width", "image.height"):
                    row = WIDTH if key == "image.width" else HEIGHT
                    try:
                        view[key] = row.check(value, text=True)
                    except ParameterError as e:
                        raise KeyPathError(f"{key}: {e}") from None
                    try:
                        scene = with_image_size(scene, width=view.get("image.width"),
                                                height=view.get("image.height"))
                    except (TypeError, ValueError) as e:
                        raise KeyPathError(f"{key}: {e}") from None
                else:
                    scene = with_value(scene, key, value)
                    kept.pop(key, None)                # the latest value last
                    kept[key] = value
            self._scene, self._mode, self._view, self._edits = scene, mode, view, kept
            if self._error is not None and self._error["kind"] == "render":
                self._error = None         # said until the next edit
            return self._submit()

    def _submit(self) -> int:
        """A new version of the state, to the render thread (it drops what it has not
        begun); a compare in progress is cancelled."""
        with self._lock:
            self._version += 1
            self._status = {**self._status, "rendering": True}
            if self._compare is not None:
                self._compare.cancel()
            self._worker.submit(Request(self._version, self._scene, self._mode))
            version = self._version
        self._emit("state", self.state())
        return version

    def orbit(self, dx: float, dy: float) -> int:
        """Turn the eye about the look-at point: ``dx`` degrees about the camera's up
        axis, ``dy`` degrees of elevation (an edit of ``camera.eye``). The loaded scene is
        edited in place while the clip planes stay (the eye at a constant distance from
        a sphere scene's shapes); else the new structure is loaded (and compiled)."""
        with self._lock:
            eye = orbited_eye(self._scene.camera, dx, dy)
        return self.edit("camera.eye", eye)

    def zoom(self, factor: float) -> int:
        """Zoom the lens by ``factor`` (> 1: closer): tan(fov/2) divided by it (an edit
        of ``camera.fov``; the eye stays, mimarble/studio/camera.py says why)."""
        with self._lock:
            fov = zoomed_fov(self._scene.camera, factor)
        return self.edit("camera.fov", fov)

    # -- Files written: snapshot, export ---------------------------------------------------

    def snapshot(self, path) -> Frame:
        """Write the latest frame to ``path`` (.png, .jpg, .jpeg: 8-bit sRGB as ``mimarble
        render`` writes it; .exr: linear float), whole or not at all; returns the frame
        written. StudioError before the first frame."""
        from mimarble.mitsuba.rendering.image_output import write_image
        frame = self.latest_frame()
        if frame is None:
            raise StudioError("snapshot: no frame has been rendered yet")
        if frame.stride > 1:     # a drag's reduced frame: the whole one follows when it stops
            try:
                frame = self.wait_frame(frame.version, timeout=SNAPSHOT_WAIT_S, whole=True)
            except TimeoutError:
                raise StudioError("snapshot: the image is shown reduced while it moves; take "
                                  "the snapshot when it stops (nothing was written)") from None
        try:
            write_image(path, frame.pixels)
        except OSError as e:      # the system's words, not the temporary file's name
            raise StudioError(f"snapshot: {path}: {e.strerror or e}") from None
        return frame

    def export(self, path, python: bool = False) -> str:
        """Write the scene as it is edited now, in the session's mode, as Mitsuba XML (or
        a Python file, ``python``) to ``path`` (``mimarble export``; whole or not at all);
        returns the text written."""
        from mimarble.tools.export import export
        with self._lock:
            scene, mode = self._scene, self._mode
        try:
            return export(scene, path, mode=mode, python=python)
        except OSError as e:      # the system's words, not the temporary file's name
            raise StudioError(f"export: {path}: {e.strerror or e}") from None

    # -- Compare ---------------------------------------------------------------------------

    def compare(self) -> None:
        """Render the float64 reference of the state now in a child process and measure
        the final frame of this version against it (mimarble/studio/compare.py); the
        result comes as a ``compare`` event and from :meth:`compare_result`. The next
        edit cancels it. StudioError in path mode (the reference renders whitted mode)."""
        from mimarble.tools.compare import reference_differs
        with self._lock:
            if self._closed:
                raise StudioError("compare: the studio is closed")
            if self._mode != "whitted":
                raise StudioError("compare: the reference tracer renders whitted mode; "
                                  "switch the mode to whitted to compare")
            if self._compare is not None:
                self._compare.cancel()
            note = ("a marble's pixel filter renders otherwise than the reference's plain "
                    "supersampling: the difference is the filter's, not an error"
                    if reference_differs(self._scene) else None)
            self._compare_result = None
            self._compare_note = note
            self._compare = Comparison(
                self._scene, self._version,
                lambda version: self.wait_frame(version, final=True, timeout=3600),
                self._compared)
        self._emit("state", self.state())

    def _compared(self, result: dict) -> None:
        with self._lock:
            result = {**result, "note": self._compare_note}
            self._compare_result = result
        self._emit("compare", result)
        self._emit("state", self.state())

    def compare_result(self) -> dict | None:
        """The last compare's result: ``status`` (``done`` or ``failed``), ``version``,
        ``psnr``, ``rmse``, ``max_abs``, ``frac_over_1_255``, ``spp``, ``seconds``,
        ``difference_png``, ``reference_png`` (bytes), ``note`` — or ``message`` when it
        failed; None before one finished."""
        with self._lock:
            return self._compare_result

    # -- The file --------------------------------------------------------------------------

    def _read(self) -> tuple[str, tuple]:
        """(the file's text exactly, its facts) — SceneError as the parser says it."""
        scene_language.load(self.path)                   # every reading error in its words
        facts = file_facts(self.path)
        try:
            return read_scene_text(self.path), facts
        except OSError as e:
            raise scene_language.SceneError(f"cannot read scene file: {e}",
                                            filename=str(self.path)) from None

    def controls(self) -> dict:
        """Every control of the scene as edited now, and of the view: JSON-able
        (mimarble/studio/controls.py), made from the key registry and the parameter
        table."""
        with self._lock:
            scene, mode = self._scene, self._mode
        return controls(scene, mode)

    def _watch(self) -> None:
        while not self._watch_stop.wait(WATCH_SECONDS):
            try:
                self.poll_file()
            except Exception:                 # the watcher never dies; the state says it
                pass

    def poll_file(self) -> dict | None:
        """Look at the file: None when it is as loaded; else ``{"reloaded": True}`` after
        reloading it, or ``{"reloaded": False, "error": …}`` (a parse error: the last good
        scene and frame stay) or ``{"reloaded": False, "disk_changed": True}`` (unsaved
        edits kept: :meth:`reload` takes the file's)."""
        with self._lock:
            # Looked at under the lock: a save between the look and the lock would make the
            # file's old facts look like an editor's change (Save then refused, or a reload).
            facts = file_facts(self.path)
            if facts == self._stat or self._closed:
                return None
            if self._edits:
                self._disk_changed = True
                self._stat = facts
                result = {"reloaded": False, "disk_changed": True}
            else:
                result = self._reload()
        self._emit("reload", result)
        self._emit("state", self.state())
        return result

    def reload(self) -> dict:
        """Read the file again, dropping unsaved edits (the view stays)."""
        with self._lock:
            result = self._reload()
        self._emit("reload", result)
        self._emit("state", self.state())
        return result

    def _reload(self) -> dict:
        try:
            text, facts = self._read()
            base = scene_language.parse(text, filename=str(self.path), source=str(self.path))
        except scene_language.SceneError as error:
            self._stat = file_facts(self.path)
            self._error = {**error_dict(error), "kind": "parse"}
            return {"reloaded": False, "error": self._error}
        scene = base
        if self._view:
            scene = with_image_size(base, width=self._view.get("image.width"),
                                    height=self._view.get("image.height"))
        self._text, self._stat, self._base = text, facts, base
        self._scene, self._edits, self._error, self._disk_changed = scene, {}, None, False
        self._submit()
        return {"reloaded": True}

    def close(self) -> None:
        """Stop the render thread, the watcher and a compare; nothing is left running.
        Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            compare, self._compare = self._compare, None
            self._frame_ready.notify_all()
        if compare is not None:
            compare.cancel(wait=True)
        if self._watcher is not None:
            self._watch_stop.set()
            self._watcher.join(5.0)
        self._worker.stop()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

