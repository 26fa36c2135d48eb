"""Loaded Mitsuba scenes, kept by structure: a scene is loaded once, then edited in place.

``mimarble.render`` of a scene model or file, a sweep's frames, the command line and
the benchmark translate the scene (``to_mitsuba``: microseconds) and ask
:data:`LOADED` for it. A scene dict whose *structure* — the dict with the marbles'
in-place values (``marble_parameters.IN_PLACE``) masked out, plus the size, times and
inode of every image map, mesh and environment file it reads, and the content digest of
every mesh file the parser read (``Mesh.digest``); also masked: the camera's placement and a
point light's position and intensity (:data:`_IN_PLACE_OF`) — matches a loaded one gets that
loaded ``mi.Scene``,
with the in-place values that differ from the ones it holds written through
``mi.traverse`` and told to their marble as values the host holds (``Marble.hold``: the
same decisions, and bits, as a fresh load); anything else is loaded anew (``mi.load_dict``). So repeated renders
of one scene, and frames that differ only in a marble's scale, period or distortion,
re-use the loaded scene, its compiled kernels and its recorded passes (so do an orbit of
the camera that keeps its clip planes, and a point light moved or dimmed)
(mimarble/mitsuba/rendering/replay.py); an edited scene file, image map or mesh file is seen,
because its new text, file facts or digest make another structure (a file rewritten with
its old modification time put back has a new change time).
"""

from __future__ import annotations

import json
import os

from mimarble.runtime import environment
from mimarble.parameters import IN_PLACE, single_precision
from mimarble.mitsuba.plugins.sphere_hit import SphereTable
from mimarble.mitsuba.translate.scene_dict import checked_samples, to_mitsuba

dr, mi = environment.import_drjit_and_mitsuba()

#: Loaded scenes kept (least recently used dropped first). Few: every replay of a
#: recorded pass traverses every live instance of the variant's plugins (Dr.Jit walks its
#: registry for the virtual calls it may record), a cost per kept scene (docs/benchmarks.md,
#: "Whole call against its kernels") — so a scene a render no longer uses should not stay
#: alive.
SCENES = 2


class LoadedScenes:
    """Loaded scenes by structure (module docstring)."""

    def __init__(self, size: int = SCENES):
        self.size, self.scenes = size, {}
        self.translated = {}          # (variant, model, options) → (dict, structure, values)

    def scene_of(self, scene, **options):
        """The loaded scene of a scene model, translated by ``to_mitsuba(scene,
        **options)``. The same model (an immutable value) with the same options is not
        translated again while its image files are unchanged: a warm render skips the
        translation and the structure's JSON too.

        In JIT variants the passes take the spp as their argument and never read the
        sampler's count (whitted: the stratum centres; path: an ``independent`` sampler
        seeded per pass), so the ``spp`` option is checked and the scene loaded at 1 spp:
        renders of one scene at any spp share one loaded scene (the scalar variant renders
        through ``mi.render``, which reads it)."""
        return self._loaded(*self._translated(scene, options)[:3])

    def is_loaded(self, scene, **options) -> bool:
        """Whether :meth:`scene_of` with these arguments would find its structure loaded
        (an edit in place, no ``mi.load_dict``): translated, not loaded."""
        return (mi.variant(), self._translated(scene, options)[1]) in self.scenes

    def _translated(self, scene, options) -> tuple:
        """(scene dict, structure, in-place values, files read) of ``to_mitsuba(scene,
        **options)``, kept for the same model and options (:meth:`scene_of`)."""
        if dr.is_jit_v(mi.Float):
            checked_samples(scene, options.get("mode", "whitted"), options.get("spp"))
            options = {**options, "spp": 1}
        try:
            memo = (mi.variant(), scene, tuple(sorted(options.items())))
            hash(memo)
        except TypeError:            # a model built in Python with unhashable parts
            scene_dict = to_mitsuba(scene, **options)
            return (scene_dict, *_structure(scene_dict))
        kept = self.translated.get(memo)
        if kept is None or _files_read(kept[0]) != kept[3]:
            scene_dict = to_mitsuba(scene, **options)
            if len(self.translated) >= 4 * self.size:
                self.translated.pop(next(iter(self.translated)))
            digests = [mesh.digest for mesh in scene.meshes]
            kept = self.translated[memo] = (scene_dict, *_structure(scene_dict, digests))
        return kept

    def scene_for(self, scene_dict: dict):
        """The loaded scene of ``scene_dict`` (a ``to_mitsuba`` dict): a kept one of the
        same structure with its in-place values set, else a new one."""
        structure, values, _ = _structure(scene_dict)
        return self._loaded(scene_dict, structure, values)

    def _loaded(self, scene_dict: dict, structure: str, values: dict):
        key = (mi.variant(), structure)
        entry = self.scenes.pop(key, None)
        if entry is None:
            if len(self.scenes) >= self.size:
                forget(self.scenes.pop(next(iter(self.scenes)))[0])
            # An OpenEXR file that fails to decode throws from a loader thread, which
            # aborts the process (Mitsuba 3.9.1's parallel load_dict: "terminate called after
            # throwing an instance of 'Iex_2_5::IoExc'"); loaded in this thread, the reader's
            # error is an exception (render.check_images says it at the file's string).
            envmap = any(isinstance(item, dict) and item.get("type") == "envmap"
                         for item in scene_dict.values())
            mitsuba_scene = mi.load_dict(scene_dict, parallel=not envmap)
            entry = (mitsuba_scene, mi.traverse(mitsuba_scene), dict(values))
        else:
            mitsuba_scene, params, held = entry
            changed = {name: value for name, value in values.items()
                       if name not in held or _exact(held[name]) != _exact(value)}
            if changed:            # should this raise, the entry stays out: never half-updated
                try:
                    for name, value in changed.items():
                        params[name] = value
                        _tell(params, name, value)
                    params.update()
                except BaseException:
                    forget(mitsuba_scene)
                    raise
                held.update(changed)
        self.scenes[key] = entry               # the most recently used last
        return entry[0]

    def parameters_of(self, mitsuba_scene):
        """The ``mi.traverse`` of a scene loaded here (None: not one of these): a pass
        reads its replay key from it rather than traversing the scene again."""
        for loaded, params, _ in self.scenes.values():
            if loaded is mitsuba_scene:
                return params
        return None

    def clear(self) -> None:
        for mitsuba_scene, _, _ in self.scenes.values():
            forget(mitsuba_scene)
        self.scenes.clear()
        self.translated.clear()


def _tell(params, name: str, value) -> None:
    """Tell the marble whose in-place value ``name`` was just written the value the host
    holds (``Marble.hold``): its decisions (the error budget's octaves, the noise, gain's
    constants) are then made from the scene dict's own number, as a fresh load makes
    them, not from the float32 the written variable holds nor, for a value that is not a
    literal, the value-independent choice of one on the device."""
    node = params.properties[name][2]
    hold = getattr(node, "hold", None)
    if hold is not None:
        hold(name.rsplit(".", 1)[1], value)


def forget(mitsuba_scene) -> None:
    """Drop what is kept for a scene that is no longer used (its sphere table holds its
    shapes), so that the scene is freed with its last reference."""
    SphereTable.forget(mitsuba_scene)


def _structure(scene_dict, digests=()) -> tuple[str, dict, list]:
    """(the dict with in-place values (:data:`_IN_PLACE_OF`) masked and the facts of the files it reads
    added, and the mesh files' ``digests`` as the parser read them, as JSON; those values
    by traverse key; the files' facts, :func:`_files_read`)."""
    values, masked = {}, {}
    for name, item in scene_dict.items():
        if isinstance(item, dict):
            for key in _IN_PLACE_OF.get(item.get("type"), ()):
                if key in item and (key != "intensity" or _rgb(item[key])):
                    item = dict(item)
                    value = item.pop(key)
                    if key == "intensity":         # {"type": "rgb", "value": […]}
                        item[key] = {"type": "rgb"}
                        key, value = "intensity.value", value["value"]
                    values[f"{name}.{key}"] = value
            if item.get("type") == "perspective" and not _double_precision():
                # The clip planes as the sensor holds them (ScalarFloat: float32): an orbit's
                # eye, rotated in float64, moves them in their 16th digit, not their float32.
                item = {**item, **{k: single_precision(item[k]) for k in _CLIPS if k in item}}
        masked[name] = item
    files = _files_read(scene_dict)
    return json.dumps([masked, files, list(digests)], sort_keys=True, default=_exact), values, \
        files


#: What each plugin type of a scene dict has written in place (its traverse key is its
#: path in the dict): a marble's IN_PLACE values; the camera's placement; a point light's
#: position and (rgb) intensity — Dr.Jit variables of the loaded scene, not constants of
#: the traced code. The sensor's clip planes and fov, a light's kind, are structure.
_IN_PLACE_OF = {"marble": IN_PLACE, "perspective": ("to_world",),
                "point": ("position", "intensity")}


#: The sensor's clip planes: structure (literals of the traced code), compared as it holds them.
_CLIPS = ("near_clip", "far_clip")


def _double_precision() -> bool:
    """Whether the variant holds scalars in double precision (``*_double``)."""
    return "double" in mi.variant()


def _rgb(value) -> bool:
    """Whether ``value`` is an ``rgb`` spectrum dict with a ``value``."""
    return isinstance(value, dict) and value.get("type") == "rgb" and "value" in value \
        and len(value) == 2


def _exact(item):
    """A value JSON cannot write, as the structure holds it: a transform (a camera's, a
    marble's ``to_world``) by every float of its matrix — its ``str`` rounds to 6 digits,
    so two transforms that differ past them would share one loaded scene — anything else
    by its ``str``."""
    matrix = getattr(item, "matrix", None)
    if matrix is not None and "Transform" in type(item).__name__:
        return [type(item).__name__, [[float(matrix[i][j]) for j in range(4)] for i in range(4)]]
    return str(item)


#: The plugins that read a file named by their ``filename``: image maps, meshes and the
#: environment.
_FILE_PLUGINS = ("bitmap", "ply", "obj", "envmap")


def _files_read(item) -> list:
    """(path, size, modification and change times, inode) of every file a ``bitmap``,
    ``ply``, ``obj`` or ``envmap`` of the dict reads, nested. The change time is the kernel's: a
    rewrite that puts the modification time back (``cp -p``, ``rsync -t``, ``touch -r``)
    still changes it."""
    found = []
    if isinstance(item, dict):
        if item.get("type") in _FILE_PLUGINS and isinstance(item.get("filename"), str):
            try:
                facts = os.stat(item["filename"])
                found.append((item["filename"], facts.st_size, facts.st_mtime_ns,
                              facts.st_ctime_ns, facts.st_ino))
            except OSError:
                found.append((item["filename"], None, None, None))   # load_dict will say
        for value in item.values():
            found += _files_read(value)
    return found


#: The loaded scenes of this process (a Dask worker has its own).
LOADED = LoadedScenes()
