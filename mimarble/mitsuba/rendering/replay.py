"""Recorded passes: a pass's kernels traced once, then replayed (Dr.Jit's ``dr.freeze``).

Tracing a pass — the sensor's rays, the integrator, the Python plugins' ``eval`` —
costs Python time on every render, as much again as the kernels themselves for a
500² marble sphere at 1 spp (docs/benchmarks.md, "Whole call against its kernels").
``dr.freeze`` records the kernels a function launches and replays them for inputs of
the same *layout*, with the new inputs' values. Two things keep a replay from ever
being stale:

* **Every Dr.Jit value the trace reads is an input.** The scene is an argument, and
  Dr.Jit traverses it: Mitsuba's C++ plugins, and the Python plugins' ``__dict__``
  (``DRJIT_STRUCT`` on the helper objects they hold: ramp, mapping, filter tables,
  sphere table), including the noise's tables that every marble holds. What a
  plugin holds is opaque, so an edit through ``mi.traverse`` is a new input value,
  not a literal baked into the recording; a variable made before the recording that
  no input reaches makes the recording fail, loudly.
* **Everything else that decides the traced code is the key** (:func:`scene_facts`):
  the Python facts of every mimarble plugin in the scene (``recording_key``: octaves
  evaluated, filter, function, the expression's skipping decisions…), every traversed
  value that is not a Dr.Jit variable, the sphere table's structure, the film size,
  the variant and the scene's identity (:data:`scene_identity`). Each key has its own
  frozen function (:class:`Recorded`), so a new key records again; within it, Dr.Jit adds
  its own checks (types, widths, AD state, the registry of instances).

``MIMARBLE_FREEZE=0`` turns replay off (read at every render); the scalar variant
never records. What Dr.Jit 1.5 cannot record, and what is left, is in
docs/design-decisions.md, "Replaying recorded kernels".
"""

from __future__ import annotations

import gc
from typing import NamedTuple

from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import recording_key

dr, mi = environment.import_drjit_and_mitsuba()

#: Keys whose recordings are kept (least recently used dropped first): a few scenes ×
#: spp × pass widths.
RECORDINGS = 32


class _SceneIdentities:
    """A number for each scene object, never given to another: the key's scene identity.

    ``id(scene)`` alone is not one: a freed scene's id is taken by the next object
    allocated there, and a new scene of the same layout then replayed the old one's
    recording — with the old scene's C++ state that Dr.Jit's traversal does not see (a
    ``bitmap``'s ``wrap_mode`` and ``filter_type``: not traversed, not in its ``repr``; a
    segmentation fault, or the old wrap mode's image). Mitsuba's objects take no weak references and
    no attributes, so each id is held with one object of its scene (the integrator, else
    the first sensor): while it is held no other scene can have it, and a scene whose id
    is known but whose object is another one is a new scene, with a new number. Whatever
    a C++ plugin fixes when it is loaded is then fixed for the whole life of a number."""

    #: Identities kept, least recently used dropped first. Only speed depends on it: a
    #: dropped scene that comes back gets a new number and records again. Few, because a
    #: held object stays in Dr.Jit's registry, which every replay walks.
    KEPT = 8

    def __init__(self):
        self.held = {}                # id(scene) → (an object of that scene, its number)
        self.issued = 0

    def __call__(self, scene) -> int:
        witness = scene.integrator() or next(iter(scene.sensors()), None)
        held, number = self.held.pop(id(scene), (None, None))
        if witness is None or held is not witness:
            self.issued += 1
            number = self.issued
            if len(self.held) >= self.KEPT:
                self.held.pop(next(iter(self.held)))
        if witness is not None:
            self.held[id(scene)] = (witness, number)    # the most recently used last
        return number


scene_identity = _SceneIdentities()


def enabled() -> bool:
    """Whether passes are replayed: a JIT variant, not a spectral one, and
    ``MIMARBLE_FREEZE`` is not ``0``. (Spectral variants trace every pass: Mitsuba's
    colour-matching tables, which its wavelength sampling and ``spectrum_to_srgb`` gather
    from, are Dr.Jit arrays of its own that no input of a recording reaches.)"""
    return dr.is_jit_v(mi.Float) and not mi.is_spectral and environment.replay_wanted()


class SceneFacts(NamedTuple):
    """What a pass over a scene needs besides its Dr.Jit inputs: the recording's ``key``
    and the Dr.Jit state the scene does not hold (``inputs``). See :func:`scene_facts`."""
    key: tuple
    inputs: tuple


def refresh_derived(scene, params=None) -> None:
    """Make current the data a plugin derives from a child that Mitsuba may not have told
    of an edit (``mi.traverse`` tells an edited texture's first parent only):
    marble_medium's albedo grid. Called before every render of the scene, by the pass
    renderer (:func:`scene_facts`) and before Mitsuba's own ``mi.render``."""
    params = mi.traverse(scene) if params is None else params
    for node in params.hierarchy:
        refresh = getattr(node, "refresh_grid", None)
        if refresh is not None:
            refresh()


def scene_facts(scene, params=None) -> SceneFacts:
    """The key and extra inputs of a pass over ``scene`` (module docstring), from its
    ``mi.traverse`` (``params``: one already made, e.g. by the loaded scenes; else made
    here). The key holds: the variant, the scene's identity (:data:`scene_identity`), film
    size, number of lights, the ``recording_key`` of every mimarble plugin anywhere in the
    scene (materials, textures inside Mitsuba's BSDFs, emitters or expressions), and every
    traversed value that is not a Dr.Jit variable (a Python number such as the sensor's
    ``near_clip``, which Mitsuba's C++ plugins read as a constant of the traced code)."""
    params = mi.traverse(scene) if params is None else params
    refresh_derived(scene, params)
    integrator = scene.integrator()
    plugins = tuple(recording_key(node) for node in params.hierarchy
                    if hasattr(node, "recording_key") and node is not integrator)
    constants, placements = [], []
    for name in params.keys():
        value, value_type, node, _ = params.properties[name]
        if value_type is not None:
            value = mi.get_property(value, value_type, node)
        if isinstance(node, mi.Shape) and name.endswith("to_world"):
            placements.append(value)
        elif not dr.detail.collect_indices(value):
            constants.append((name, repr(value)))
    own = getattr(integrator, "recording", None)
    own_key, own_inputs = own(scene, placements) if own is not None else \
        (recording_key(integrator), ())
    film = scene.sensors()[0].film()
    key = (mi.variant(), scene_identity(scene), tuple(film.crop_size()),
           tuple(film.crop_offset()), len(scene.emitters()),
           own_key, plugins, tuple(constants))
    return SceneFacts(key, own_inputs)


def scene_key(scene, params=None) -> tuple:
    """:func:`scene_facts`' key: pass it to your own frozen function as an argument, so that
    a structural change of a mimarble plugin records it again (docs/mitsuba-scene.md)."""
    return scene_facts(scene, params).key


def _own_error(error: RuntimeError) -> BaseException:
    """The error a recording was stopped by, when it is not Dr.Jit's own: the recorder
    wraps it ("record(): error encountered while recording…"), so that a plugin's
    ``ValueError`` (whitted's "shape … needs 'channel_material'") would reach the caller as
    a ``RuntimeError`` whose reason is only in its cause. Else the error itself."""
    cause = error
    while isinstance(cause, RuntimeError) and cause.__cause__ is not None:
        cause = cause.__cause__
    return cause if not isinstance(cause, RuntimeError) else error


def _innermost(error: BaseException) -> BaseException:
    """The first cause of a chain of errors."""
    while error.__cause__ is not None:
        error = error.__cause__
    return error


class Recorded:
    """``function(key, *args)`` replayed from its recordings while :func:`enabled`, else
    called. The function must not read ``key`` (a recording is made with None there).

    The ``key`` (Python values: :func:`scene_facts`' and the pass's) selects the frozen
    function, one ``dr.freeze`` per key, kept least recently used first: which code is
    traced is decided here, in Python, by equality of keys, not left to Dr.Jit's layout
    comparison of Python values inside its inputs (which replayed a recording made under
    another key: a multiply whose constant factor went from 0 to 0.5 under ``path``). Each
    frozen function then records per layout of its Dr.Jit inputs.
    """

    def __init__(self, function):
        self.function = function
        self.frozen = {}                # key → dr.freeze(function)
        self.recorded = 0               # recordings of frozen functions no longer kept
        self.too_deep = set()           # keys whose inputs Dr.Jit's traversal cannot walk

    def __call__(self, key, *args):
        if not enabled() or key in self.too_deep:
            return self.function(key, *args)
        frozen = self.frozen.pop(key, None)
        if frozen is None:
            if len(self.frozen) >= RECORDINGS:
                self.recorded += self.frozen.pop(next(iter(self.frozen))).n_recordings
            # A key records once per layout of its inputs; no warning for a few of them.
            frozen = dr.freeze(self.function, limit=4, warn_after=10 ** 6)
        self.frozen[key] = frozen                     # the most recently used last
        # Python's cycle collector may free unreachable Mitsuba objects (a dropped scene's
        # plugins) at any allocation; during a recording that changes Dr.Jit's registry and
        # variables under the recorder (under --jit-debug: an abort). Not while it runs.
        collecting = gc.isenabled()
        gc.disable()
        try:
            # The key selected the frozen function; inside, it would only be walked and
            # compared at every replay (about 0.05 ms for a scene's key): None instead.
            return frozen(None, *args)
        except RuntimeError as e:
            if _innermost(e).__class__ is RecursionError:
                # Inputs nested deeper than Dr.Jit's traversal goes (a channel expression
                # near the language's depth limit): traced every time instead.
                self.frozen.pop(key, None)
                self.too_deep.add(key)
                return self.function(key, *args)
            raise _own_error(e) from None
        finally:
            if collecting:
                gc.enable()

    @property
    def recordings(self) -> int:
        """How many times it has recorded (a test's and the benchmark's check)."""
        return self.recorded + sum(f.n_recordings for f in self.frozen.values())
