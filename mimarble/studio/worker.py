"""The studio's render thread: the newest state only, then progressive refinement.

One thread does every Dr.Jit and Mitsuba call of a studio session, so that a page's
request never waits for a render or a compile. Its contract:

* **Newest state only.** :meth:`RenderThread.submit` replaces the state waiting to be
  rendered (a :class:`Request`); a state that was replaced before the thread took it is
  never rendered, and none is queued. A frame being rendered when edits arrive is
  finished and shown (the page sees the drag move), then the newest state is taken.
* **1 spp while edits come.** A new state is first rendered at 1 sample per pixel (the
  pixel centre in whitted mode): one recorded pass, a few milliseconds warm.
* **Refinement when idle.** Once no edit has come for ``idle_s``, the same state is
  rendered again towards the scene's ``samples``, a run of samples at a time
  (:func:`~mimarble.mitsuba.rendering.passes.trace_samples`: samples 0–3, 4–7, 8–15, …,
  at most :data:`RUN_LANES` lanes a run), their sums **accumulated**: each frame shows all
  the samples so far. Whitted mode's sample k is the render's own (stratum k of n×n, with
  the differentials of the target spp), so the last frame is the render at that spp to
  float64 rounding of the runs' sums (tests/test_studio_engine.py); path mode's runs are
  seeded one by one (run r: seed r + 1), so its frames converge as the render does.
  A new edit stops refinement between runs.
* **Reduced frames while a control moves.** When a state comes less than
  :data:`MOTION_GAP_S` after the one before (a drag, a slider held: a stream of edits)
  and the last whole 1 spp frame took longer than :data:`FRAME_BUDGET_S` (render and
  encode: a loaded machine), the state's first frame is the whole image's pixels of
  every second row and column (every fourth when the last whole frame took over four
  budgets, or the last frame at stride 2 over one)
  — a quarter (a sixteenth) of the lanes, traced by a pass over that pixel list of the
  same loaded scene (``trace_sums``: no new structure, one small recording per size),
  the page scaling it up. Once the edits stop (``idle_s``) the whole 1 spp frame
  follows, then refinement.
* **Compiling.** Before a state whose structure no loaded scene holds, or whose passes
  have no recording, is rendered, ``compiling`` is published as True, then False with
  its frame.
* **Going back compiles nothing.** A recording replays only while Dr.Jit's registry of
  instances holds what it held when it was recorded (``dr.freeze`` flattens every live
  instance of the domains it saw into the recording's key), so loading a new structure
  (octaves 8 → 9) makes every kept structure's recording stale. Right after the new
  structure's first frame, the thread records the passes of the other kept structures
  again — the 1 spp pass and the reduced passes each has shown — the most recently shown
  first (:meth:`RenderThread._record_kept`; a new edit stops it between two), so that
  going back to one (9 → 8) replays: no load, no recording, no kernel compiled, the page
  never says "compiling", and the first reduced frame of a drag there is not slowed by
  a recording. What the thread keeps of each loaded scene for this is one
  :class:`KeptScene`.

Failures of a render (a mode that cannot render the scene, Mitsuba's own errors) are
published as the state's ``error``; the last good frame stays, and the session goes back
to the state it showed (:meth:`StudioSession._render_failed`).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np

from mimarble.runtime import environment
from mimarble.mitsuba.rendering.loaded_scenes import LoadedScenes
from mimarble.mitsuba.rendering.passes import (Target, samples_pass_key, trace_samples,
                                               trace_sums, traced_pass)
from mimarble.mitsuba.rendering.replay import enabled as replay_enabled, scene_facts
from .frames import FRAME_FORMAT, Frame, encode
from .histogram import Histograms

dr, mi = environment.import_drjit_and_mitsuba()

#: Most lanes (pixels × samples) of one refinement run: 2²¹, 8 spp at 512² — the longest an
#: edit waits behind refinement is one such run (docs/benchmarks.md, "Figures moved out of
#: the code").
RUN_LANES = 1 << 21
#: Samples of the first refinement run: the scene's 4 spp (the paper scenes') in one run,
#: a frame at 4, 8, 16, … spp for more (runs of 4, 4, 8, …; docs/benchmarks.md, "Studio").
FIRST_RUN = 4
#: Loaded scenes a session keeps: its structures (octaves 8 and 9, both modes, …), so
#: that going back to one reuses its loaded scene and its recorded passes.
KEPT_SCENES = 6
#: The time a whole 1 spp frame may take (render and encode) before the frames of a drag
#: are reduced: 40 ms leaves 10 ms of the 50 ms a frame has at 20 frames/s (the issue's
#: target) to the socket, the decode and the paint.
FRAME_BUDGET_S = 0.040
#: Edits closer together than this are a control moving (a drag sends one per animation
#: frame, ~16 ms; a held arrow key one per ~33 ms).
MOTION_GAP_S = 0.1


class Request(NamedTuple):
    """A state to render: ``version`` (the session's edit counter), the scene model and
    the mode."""
    version: int
    scene: object
    mode: str


@dataclass
class KeptScene:
    """What the render thread keeps of one loaded scene (one structure) to record its
    passes again after another scene is loaded (module docstring, "Going back compiles
    nothing"): a recording replays only while Dr.Jit's registry of instances is the one it
    was made with, and a load changes it.

    ========  ===========================================================================
    target    the scene as last shown (a ``Target``): its passes are recorded again for it
    facts     its ``scene_facts`` then: the passes' recording key and inputs
    key       its 1 spp pass's recording key then (``samples_pass_key``)
    strides   the strides of the reduced frames it has shown (2, 4)
    current   the passes run since the last load: the 1 spp pass's key, a reduced pass's
              :func:`_reduced_key`; their recordings replay, any other records anew
    ========  ===========================================================================
    """
    target: Target
    facts: object
    key: tuple
    strides: set = field(default_factory=set)
    current: set = field(default_factory=set)


class RenderThread(threading.Thread):
    """The render thread (module docstring). ``publish(kind, payload)`` is called from
    this thread with ``("frame", Frame)``, ``("histograms", dict)`` (a version's
    histograms of t, after its first frame, whose ``histograms`` were None) and
    ``("status", dict)``; ``failed(request, error)`` when a state cannot be rendered.
    ``frame_format``: ``auto``, ``png`` or ``jpeg`` (mimarble/studio/frames.py)."""

    def __init__(self, publish: Callable, failed: Callable, frame_format: str = FRAME_FORMAT,
                 idle_s: float = 0.15):
        super().__init__(name="mimarble-studio-render", daemon=True)
        self.publish, self.failed = publish, failed
        self.frame_format, self.idle_s = frame_format, idle_s
        self.loaded = LoadedScenes(KEPT_SCENES)
        self.histograms = Histograms()
        self._condition = threading.Condition()
        self._pending: Request | None = None
        self._last_submit = 0.0
        self._moving = False         # the pending state came within MOTION_GAP_S
        self.frame_budget_s = FRAME_BUDGET_S
        #: Seconds the last whole 1 spp frame took (render and encode; None: none yet).
        self.last_frame_s: float | None = None
        #: Seconds the last frame at stride 2 took (render and encode).
        self.last_reduced_s: float | None = None
        self._stopping = False
        #: Versions rendered (their first frame), in order: what a test of dropping reads.
        self.rendered: list[int] = []
        #: (structure, mode) → seconds of its first render, for the benchmark.
        self.compile_seconds: dict = {}
        #: Scenes loaded so far (a test's check).
        self.loads = 0
        #: id of a loaded scene → its :class:`KeptScene`, the most recently shown last;
        #: only scenes :attr:`loaded` keeps (each record holds its scene, so no id is reused
        #: while it is here).
        self._kept: dict[int, KeptScene] = {}
        #: Passes recorded again after a load, in order: a 1 spp pass's key, a reduced
        #: pass's :func:`_reduced_key` (a test's check).
        self.recorded_again: list = []
        #: Set while the thread waits for a state or for edits to pause and no state
        #: waits for it (:meth:`submit` clears it): nothing is in progress (a test's check).
        self.resting = threading.Event()

    # -- Called from other threads ---------------------------------------------------

    def submit(self, request: Request) -> None:
        """Make ``request`` the state to render next, replacing any waiting one."""
        with self._condition:
            now = time.monotonic()
            self._pending = request
            self._moving = now - self._last_submit < MOTION_GAP_S
            self._last_submit = now
            self.resting.clear()          # work waits, before the thread has woken to it
            self._condition.notify()

    def stop(self, timeout: float | None = 30.0) -> None:
        """Stop after the run in progress; wait up to ``timeout`` seconds for it."""
        with self._condition:
            self._stopping = True
            self._condition.notify()
        if self.is_alive() and threading.current_thread() is not self:
            self.join(timeout)

    # -- The thread ----------------------------------------------------------------------

    def run(self) -> None:
        while True:
            with self._condition:
                while self._pending is None and not self._stopping:
                    self.resting.set()
                    self._condition.wait()
                self.resting.clear()
                if self._stopping:
                    return
                request, self._pending = self._pending, None
                moving = self._moving
            try:
                self._render(request, moving)
            except Exception as error:       # a state that cannot render: said, not fatal
                self.publish("status", {"compiling": False, "rendering": False})
                self.failed(request, error)

    def _newer(self) -> bool:
        with self._condition:
            return self._pending is not None or self._stopping

    def _wait_idle(self) -> bool:
        """Wait until no edit has come for ``idle_s``; False if a new state (or stop)
        came first."""
        with self._condition:
            try:
                while self._pending is None and not self._stopping:
                    left = self._last_submit + self.idle_s - time.monotonic()
                    if left <= 0:
                        return True
                    self.resting.set()
                    self._condition.wait(left)
                return False
            finally:
                self.resting.clear()

    def stride(self, moving: bool) -> int:
        """1 (the whole image), or the stride of a reduced frame: 2, or 4 when the last
        whole frame took over four frame budgets or the last frame at stride 2 took
        over one (module docstring)."""
        last, budget = self.last_frame_s, self.frame_budget_s
        if not moving or last is None or budget is None or last <= budget:
            return 1
        halved = self.last_reduced_s
        return 4 if last > 4.0 * budget or (halved is not None and halved > budget) else 2

    def _render(self, request: Request, moving: bool = False) -> None:
        scene, mode = request.scene, request.mode
        options = {"mode": mode, "spp": None, "tolerance": None, "filter": None}
        new_structure = not self.loaded.is_loaded(scene, **options)
        if new_structure:
            self.publish("status", {"compiling": True, "rendering": True})
        start = time.perf_counter()
        mitsuba_scene = self.loaded.scene_of(scene, **options)
        target = Target.of(mitsuba_scene, mode, self.loaded.parameters_of(mitsuba_scene))
        facts = scene_facts(target.scene, target.params)
        pixels = target.width * target.height
        first_key = samples_pass_key(facts.key, mode, pixels, 1)
        # A recording is made again when its key is new, or when the loaded scenes have
        # changed since it was made and _record_kept has not made it since (Dr.Jit checks
        # the registry of instances it saw): a load makes every kept pass stale.
        if new_structure:
            self.loads += 1
            self._forget_dropped()
            for kept in self._kept.values():
                kept.current.clear()
        kept = self._kept.get(id(target.scene))
        current = kept.current if kept is not None else set()
        compiling = new_structure or (replay_enabled() and (
            first_key not in traced_pass.frozen or first_key not in current))
        current.add(first_key)
        if compiling and not new_structure:
            self.publish("status", {"compiling": True, "rendering": True})
        stride = 1 if compiling else self.stride(moving)
        first_reduced = False
        if stride > 1:        # a pass that records (not current) is not timed
            reduced_key = _reduced_key(facts, stride, pixels)
            first_reduced = reduced_key not in current
            current.add(reduced_key)
            sums = _reduced(target, stride, facts)
        else:
            # The 1 spp frame: the pixel centre (whitted), or one sample seeded 0 (path).
            sums = trace_samples(target, 1, 0, 1, seed=0, key=facts)
        elapsed = time.perf_counter() - start
        if compiling:
            self.compile_seconds[(facts.key[1:], mode)] = elapsed
        self.rendered.append(request.version)
        histograms = self.histograms.cached(scene)
        target_spp = scene.image.samples
        encode_s = self._show(request, sums, 1, target_spp, elapsed, histograms, stride)
        if stride == 1 and not compiling:
            self.last_frame_s, self.last_reduced_s = elapsed + encode_s, None
        elif stride == 2 and not first_reduced:
            self.last_reduced_s = elapsed + encode_s
        self._keep(target, facts, first_key, stride, current)
        if histograms is None:          # after the frame is out, unless it is stale already
            # Let the threads that wait for the frame (a server's loop) take the GIL now,
            # not after the NumPy below (up to Python's switch interval, 5 ms, later).
            time.sleep(0.001)
            if self._newer():
                return
            histograms = self.histograms.of(scene)
            self.publish("histograms", {"version": request.version,
                                        "histograms": list(histograms)})
        if new_structure:
            self._record_kept()
        if not self._wait_idle():
            return
        self._record_kept()             # any a newer edit cut short, now that edits pause
        if target_spp <= 1 and stride == 1:
            return
        if stride > 1:                  # the control stopped: the whole frame now
            start = time.perf_counter()
            sums = trace_samples(target, 1, 0, 1, seed=0, key=facts)
            elapsed = time.perf_counter() - start
            self.last_frame_s = elapsed + self._show(request, sums, 1, target_spp, elapsed,
                                                     histograms)
            self.last_reduced_s = None   # the next drag tries stride 2 again
            if target_spp <= 1:
                return
        # Refinement: runs of samples, accumulated; the first of FIRST_RUN samples, then
        # each as many as all before it (the frames' spp double), up to RUN_LANES lanes.
        total = np.zeros_like(sums)
        done, run, index = 0, max(1, min(FIRST_RUN, RUN_LANES // pixels)), 0
        start = time.perf_counter()
        while done < target_spp:
            if self._newer():
                return
            count = min(run, target_spp - done)
            total += trace_samples(target, target_spp, done, count, seed=index + 1, key=facts)
            done, index = done + count, index + 1
            self._show(request, total, done, target_spp, time.perf_counter() - start,
                       histograms)
            run = max(1, min(done, RUN_LANES // pixels))

    def _keep(self, target: Target, facts, key: tuple, stride: int, current: set) -> None:
        """Keep the shown scene's :class:`KeptScene` as it is now, the most recently shown.
        One record a loaded scene, for its state now: an in-place edit can change its
        passes' keys (the marble's octaves evaluated, whether it needs noise), and an
        older key, recorded again from the scene as it is now, would hold the wrong
        kernels."""
        kept = self._kept.pop(id(target.scene), None)
        if kept is None:
            kept = KeptScene(target, facts, key, current=current)
        kept.target, kept.facts, kept.key = target, facts, key
        if stride > 1:
            kept.strides.add(stride)
        if len(kept.current) > 1024:   # bounded: stale keys of many in-place edits
            kept.current &= {key, *(_reduced_key(facts, s, target.width * target.height)
                                    for s in kept.strides)}
        self._kept[id(target.scene)] = kept

    def _forget_dropped(self) -> None:
        """Let go of the records of scenes :attr:`loaded` has dropped, before anything is
        recorded: a scene held here would stay in Dr.Jit's registry, in every recording."""
        live = {id(scene) for scene, _, _ in self.loaded.scenes.values()}
        for scene_id in [scene_id for scene_id in self._kept if scene_id not in live]:
            del self._kept[scene_id]

    def _record_kept(self) -> None:
        """Record again the passes of every kept scene whose recording predates the last
        load (module docstring): its 1 spp pass, then the reduced passes it has shown; the
        most recently shown scene first, until a new state comes. Their images are not
        shown."""
        if not replay_enabled():
            return
        for kept in reversed(list(self._kept.values())):
            pixels = kept.target.width * kept.target.height
            passes = [(kept.key, 1)] + [(_reduced_key(kept.facts, stride, pixels), stride)
                                        for stride in sorted(kept.strides)]
            for key, stride in passes:
                if key in kept.current:
                    continue
                if self._newer():
                    return
                if stride == 1:
                    trace_samples(kept.target, 1, 0, 1, seed=0, key=kept.facts)
                else:
                    _reduced(kept.target, stride, kept.facts)
                kept.current.add(key)
                self.recorded_again.append(key)

    def _show(self, request: Request, sums: np.ndarray, spp: int, target_spp: int,
              seconds: float, histograms: tuple | None, stride: int = 1) -> float:
        """Publish the frame of ``sums`` (pixels, 3) over ``spp`` samples (the pixels of
        every ``stride``-th row and column when ``stride`` > 1): JPEG while it is not
        final (``frame_format`` ``auto``), else the format asked for. Returns the
        seconds spent encoding it."""
        scene = request.scene
        height, width = _reduced_size(scene.image.height, scene.image.width, stride)
        pixels = (sums / spp).astype(np.float32).reshape(height, width, 3)
        fmt = self.frame_format
        if fmt == "auto":
            fmt = "png" if spp >= target_spp and stride == 1 else "jpeg"
        image, mime, encode_ms = encode(pixels, fmt)
        self.publish("frame", Frame(request.version, image, mime, width, height, spp,
                                    target_spp, request.mode, seconds * 1e3, encode_ms,
                                    histograms, pixels, stride))
        return encode_ms * 1e-3


def _reduced_key(facts, stride: int, pixels: int) -> tuple:
    """The studio's name of a reduced pass (:func:`_reduced`) of the scene whose
    ``scene_facts`` are ``facts``, at ``stride``, in an image of ``pixels`` pixels."""
    return ("reduced", facts.key, stride, pixels)


def _reduced_size(height: int, width: int, stride: int) -> tuple[int, int]:
    """Rows and columns of a frame of every ``stride``-th row and column (from 0)."""
    return -(-height // stride), -(-width // stride)


def _reduced(target: Target, stride: int, facts) -> np.ndarray:
    """The 1 spp radiance of the pixels of every ``stride``-th row and column of
    ``target``'s image, float64 (pixels, 3), row by row: the same samples the whole
    frame takes there (the pixel centre in whitted mode), traced as a pixel list of the
    loaded scene (``trace_sums``), so no scene is loaded and no structure is new."""
    height, width = _reduced_size(target.height, target.width, stride)
    rows = np.arange(0, target.height, stride, dtype=np.uint32)[:, None]
    columns = np.arange(0, target.width, stride, dtype=np.uint32)[None, :]
    pixels = (rows * np.uint32(target.width) + columns).ravel()
    sums = np.empty((height * width, 3), dtype=np.float64)
    for part in trace_sums(target, 1, mi.UInt32(pixels), len(pixels), with_estimates=False,
                           key=facts):
        sums[part.start:part.start + part.count] = part.sums.numpy().T[:part.count]
    return sums
