"""Recorded passes: a pass's kernels traced once, then replayed (Dr.Jit's ``dr.freeze``).

Tracing a pass — the sensor's rays, the integrator, the Python plugins' ``eval`` —
costs Python time on every render, as much again as the kernels themselves for a
500² marble sphere at 1 spp (docs/benchmarks.md, "Whole call against kernels").
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
* **Everything else that decides the traced code is the key** (:func:`scene_key`):
  the Python facts of each plugin (``recording_key``: octaves evaluated, filter,
  function, the expression's skipping decisions…), the sphere table's structure, the
  film size, and the scene's identity. A new key records again; Dr.Jit adds its own
  checks (types, widths, AD state, the registry of instances).

``MIMARBLE_FREEZE=0`` turns replay off (read at every render); the scalar variant
never records. What Dr.Jit 1.5 cannot record, and what is left, is in
docs/design-decisions.md, "Replaying recorded kernels".
"""

from __future__ import annotations

import gc

from .. import environment
from ..plugins import recording_key

dr, mi = environment.import_drjit_and_mitsuba()

#: Recordings kept (least recently used dropped first): a few scenes × spp × pass widths.
RECORDINGS = 32


def enabled() -> bool:
    """Whether passes are replayed: a JIT variant, and ``MIMARBLE_FREEZE`` is not ``0``."""
    return dr.is_jit_v(mi.Float) and environment.replay_wanted()


def scene_key(scene) -> tuple:
    """What decides the code a pass over ``scene`` traces, besides the Dr.Jit values
    that are its inputs (module docstring)."""
    integrator = scene.integrator()
    own = getattr(integrator, "recording_key", None)
    film = scene.sensors()[0].film()
    return (id(scene), tuple(film.crop_size()), tuple(film.crop_offset()),
            own(scene) if own is not None else recording_key(integrator),
            tuple(_material_key(shape.bsdf()) for shape in scene.shapes()),
            len(scene.emitters()))


def _material_key(bsdf) -> tuple | None:
    """A BSDF's key: a mimarble material's own (it holds its channels' keys); for a
    Mitsuba BSDF (``diffuse`` with a marble reflectance, under ``prb``), its type and the
    keys of the mimarble textures among its parameters' owners."""
    if bsdf is None or hasattr(bsdf, "recording_key"):
        return recording_key(bsdf)
    params = mi.traverse(bsdf)
    owners = {id(node): node for _, _, node, _ in (params.properties[k] for k in params.keys())}
    return (recording_key(bsdf),) + tuple(recording_key(node) for node in owners.values()
                                          if hasattr(node, "recording_key"))


def scene_inputs(scene) -> tuple:
    """The Dr.Jit state a pass over ``scene`` reads that the scene does not hold: the
    integrator's ``recording_inputs`` (whitted: its sphere table)."""
    own = getattr(scene.integrator(), "recording_inputs", None)
    return own(scene) if own is not None else ()


class Recorded:
    """``function`` replayed from its recordings while :func:`enabled`, else called."""

    def __init__(self, function):
        self.function = function
        # A new key records again by design (a structural edit), so no warning for it.
        self.frozen = dr.freeze(function, limit=RECORDINGS, warn_after=10 ** 6)

    def __call__(self, *args):
        if not enabled():
            return self.function(*args)
        # Python's cycle collector may free unreachable Mitsuba objects (a dropped scene's
        # plugins) at any allocation; during a recording that changes Dr.Jit's registry and
        # variables under the recorder (under --jit-debug: an abort). Not while it runs.
        collecting = gc.isenabled()
        gc.disable()
        try:
            return self.frozen(*args)
        finally:
            if collecting:
                gc.enable()

    @property
    def recordings(self) -> int:
        """How many times it has recorded (a test's and the benchmark's check)."""
        return self.frozen.n_recordings
