"""The distribution of t over the visible marble: one histogram per marble in view.

A marble's colour is its ramp at t (mimarble/parameters.py; paper §3.2); where t falls
decides which of the ramp's colours show — a serpentine whose t stays within 0.8–0.97
shows only its last colours, and nothing in the image says why. So the studio draws,
under the ramp editor, the histogram of t at the first-hit points of the camera's rays,
beside the ramp's stops.

t comes from the reference tracer's float64 NumPy marble (``reference.marble.stripe``:
the formula before the ramp), at the first hits of a grid of at most :data:`GRID` pixel
centres on the long side, found by the reference's own intersection — no Dr.Jit
kernel to compile for it, and independent of the render it is drawn beside. The hits
depend only on the camera, the shapes and the image's shape, so they are kept
(:class:`Histograms`) while marble edits only re-evaluate t there: about 8 ms for
fig11a's 12 octaves at the default grid (96 across; 4 ms at 64, 12 ms at 128; AMD EPYC),
so the render thread computes them after a frame is out, not before
(mimarble/studio/worker.py).

Only the marble's own t: a marble inside an expression (``mix``, ``add``) has its own
histogram, the expression's colour has none. A marble evaluated per shape in object
space (``space object``) is evaluated at each hit's object-space point.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mimarble.ramp_text import hex_of_linear
from mimarble.reference import intersection, preparation
from mimarble.reference.marble import stripe
from mimarble.scene import MarbleChannel, walk
from mimarble.scene.key_families import MarbleKeys, material_channels

#: Pixel centres across the long side of the grid t is sampled on.
GRID = 96
#: Bins over t ∈ [0, 1].
BINS = 64


class Histograms:
    """The hits of the last camera and shapes, and the histograms of t there."""

    def __init__(self, grid: int = GRID, bins: int = BINS):
        self.grid, self.bins = grid, bins
        self._geometry = None        # (key, hit points, object-space points, material names)
        self._last = None            # (scene, its histograms)

    def cached(self, scene) -> tuple | None:
        """:meth:`of` ``scene`` if it was the last scene asked for, else None."""
        return self._last[1] if self._last is not None and self._last[0] == scene else None

    def of(self, scene) -> tuple:
        """One dict per distinct marble in view (see :func:`histogram`), in the order
        the materials name them; empty when no ray hits a marble."""
        kept = self.cached(scene)
        if kept is not None:
            return kept
        self._last = (scene, self._of(scene))
        return self._last[1]

    def _of(self, scene) -> tuple:
        points, local, names = self._hits(scene)
        prefixes = {selection[1:]: prefix for _, prefix, selection in MarbleKeys().groups(scene)
                    if selection[0] == "channel"}
        found = {}                   # marble channel → (labels, mask of the hits using it)
        for index, name in enumerate(names):
            on_material = None
            for place, channel in material_channels(scene.materials[name]).items():
                for marble in walk(channel):
                    if not isinstance(marble, MarbleChannel):
                        continue
                    if on_material is None:
                        on_material = local[2] == index
                    labels, mask = found.get(marble, ([], np.zeros(len(points), dtype=bool)))
                    label = prefixes.get((name, place), f"{name}.{place}")
                    if label not in labels:
                        labels.append(label)
                    found[marble] = (labels, mask | on_material)
        out, said = [], {}
        for marble, (labels, mask) in found.items():
            if not mask.any():
                continue
            said[tuple(labels)] = said.get(tuple(labels), 0) + 1
            if said[tuple(labels)] > 1:      # two marbles of one channel (an expression's)
                labels = [f"{label} ({said[tuple(labels)]})" for label in labels]
            at = local[0][mask] if marble.space == "object" else points[mask]
            out.append(histogram(stripe(at, marble), marble, labels, self.bins))
        return tuple(out)

    def _hits(self, scene):
        """(world points, (object-space points, …, material index per hit), material names)
        of the grid's first hits, kept while the camera, shapes and image shape stay."""
        key = (scene.camera, scene.image.width, scene.image.height,
               tuple(shape for _, shape in scene.shapes()),
               tuple((n, m.subsurface is None) for n, m in scene.materials.items()))
        if self._geometry is not None and self._geometry[0] == key:
            return self._geometry[1:]
        width, height = scene.image.width, scene.image.height
        scale = self.grid / max(width, height)
        w, h = max(int(round(width * scale)), 1), max(int(round(height * scale)), 1)
        x, y = np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
        geometry = _without_subsurfaces(scene)
        prepared = preparation.prepare(geometry)
        eye, directions = preparation.camera_rays(geometry, x.ravel(), y.ravel())
        record = intersection.closest_hit(prepared, eye, directions)
        local = intersection.object_points(prepared, record) if prepared.from_world is not None \
            else record.p
        names = list(scene.materials)
        self._geometry = (key, record.p, (local, None, record.material), names)
        return self._geometry[1:]


def histogram(t: np.ndarray, marble, labels, bins: int = BINS) -> dict:
    """The JSON-able histogram of ``t`` for ``marble`` (a MarbleChannel): ``label`` (its
    places as key-path prefixes, ``stone.diffuse``, joined), ``keys`` (those prefixes),
    ``bins``, ``counts`` over [0, 1] (t is in [0, 1] by its formula; clipped against
    rounding), ``stops`` (where the ramp's colours sit on t: its positions, else
    k/(K−1)), ``colors`` (the stops' colours as ``#rrggbb``, sRGB-encoded), ``samples``
    (points counted) and ``range`` (t's least and largest value)."""
    t = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)
    counts = np.histogram(t, bins=bins, range=(0.0, 1.0))[0]
    ramp = tuple(marble.ramp)
    positions = marble.ramp_positions
    if positions is None:
        positions = tuple(k / (len(ramp) - 1) for k in range(len(ramp))) if len(ramp) > 1 \
            else (0.0,)
    return {"label": ", ".join(labels), "keys": list(labels), "bins": bins,
            "counts": counts.tolist(), "stops": [float(p) for p in positions],
            "colors": [hex_of_linear(c) for c in ramp], "samples": int(t.size),
            "range": [float(t.min()), float(t.max())] if t.size else None}


def _without_subsurfaces(scene):
    """The scene with no material's subsurface: the reference's whitted preparation
    refuses them, and only the shapes' surfaces matter here."""
    if all(m.subsurface is None for m in scene.materials.values()):
        return scene
    from mimarble.scene import FrozenMap
    materials = {n: dataclasses.replace(m, subsurface=None) for n, m in scene.materials.items()}
    return dataclasses.replace(scene, materials=FrozenMap(materials))
