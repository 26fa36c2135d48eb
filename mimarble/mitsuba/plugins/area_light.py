"""``stratified_area``: an area light as n×n point lights at stratum centres.

The scene language's ``light { … area { … } }`` in whitted mode (docs/rendering-model.md,
"Area lights"): a rectangle (edges ``axis1``, ``axis2`` centred on ``position``) or a
sphere (``radius`` around it) whose total ``intensity`` is split evenly over ``samples``
= n² sample points, each a point light of the paper's model (no distance falloff, a
shadow ray of its own). No jitter: the pattern is fixed, so the image is deterministic
and the reference tracer (mimarble/reference/tracer.py) computes the same one.

* **rectangle**: sample (a, b), a, b ∈ 0..n−1, lies at
  position + ((a + ½)/n − ½)·axis1 + ((b + ½)/n − ½)·axis2.
* **sphere**: the n×n stratum centres of [−1, 1]² are mapped onto the unit disk by
  Shirley and Chiu's concentric map; seen from a shaded point p, the sphere is that
  disk of radius ``radius`` facing p: position + radius·(x·t + y·b), with w the unit
  vector from the centre to p, t = normalize(f − (f·w)·w), b = w × t, and f a fixed
  unit vector perpendicular to the direction from the centre to ``toward`` (the
  camera's look-at point: the frame turns smoothly over everything seen from there).

The ``whitted`` integrator loops over the samples in a symbolic loop
(:meth:`StratifiedArea.shade`): its kernel holds one light's code whatever the count.
The offsets are opaque Dr.Jit arrays the plugin holds, so that a recording of the pass
(mimarble/mitsuba/rendering/replay.py) takes them, and the edited position, intensity, axes or
radius, as inputs; the shape and the count are its :meth:`recording_key`.

Under Mitsuba's own integrators it is a set of point lights (``sample_direction``
picks one sample point at random); the translator's path mode uses Mitsuba's ``area``
emitters on a ``rectangle`` or ``sphere`` shape instead (translate/lights.py).

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Description
   * - ``position``
     - point (0 0 0)
     - The centre.
   * - ``intensity``
     - rgb (1 1 1)
     - The total intensity; each sample has intensity / samples.
   * - ``shape``
     - string (``rectangle``)
     - ``rectangle`` or ``sphere``.
   * - ``axis1``, ``axis2``
     - vector
     - A rectangle's edges (full lengths), not zero, not parallel.
   * - ``radius``
     - float
     - A sphere's radius, > 0.
   * - ``toward``
     - point (position − (0 0 1))
     - A sphere's frame: where the scene is seen from the light.
   * - ``samples``
     - int (16)
     - n², at most ``LIMITS["max_light_samples"]``.
"""

from __future__ import annotations

import math

import numpy as np

from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import describe, numbers, plugin
from mimarble.scene.model import samples_per_axis
from mimarble.scene.rules import area_axes_problem, area_radius_problem, light_samples_problem
from . import sphere_hit

dr, mi = environment.import_drjit_and_mitsuba()

SHAPES = ("rectangle", "sphere")


def grid_offsets(n: int) -> tuple[list[float], list[float]]:
    """The rectangle's sample offsets (s, t) ∈ (−½, ½)², sample k = b·n + a at
    ((a + ½)/n − ½, (b + ½)/n − ½): in units of axis1 and axis2."""
    s = [(a + 0.5) / n - 0.5 for b in range(n) for a in range(n)]
    t = [(b + 0.5) / n - 0.5 for b in range(n) for a in range(n)]
    return s, t


def disk_offsets(n: int) -> tuple[list[float], list[float]]:
    """The sphere's sample offsets (x, y) on the unit disk: the n×n stratum centres of
    [−1, 1]², sample k = b·n + a at u = 2(a + ½)/n − 1, v = 2(b + ½)/n − 1, through
    Shirley and Chiu's concentric map (r = u, φ = π/4·v/u where |u| > |v|, else r = v,
    φ = π/2 − π/4·u/v; the centre stays (0, 0))."""
    xs, ys = [], []
    for b in range(n):
        for a in range(n):
            u, v = 2.0 * (a + 0.5) / n - 1.0, 2.0 * (b + 0.5) / n - 1.0
            if u == 0.0 and v == 0.0:
                x = y = 0.0
            elif abs(u) > abs(v):
                x, y = u * math.cos(math.pi / 4 * v / u), u * math.sin(math.pi / 4 * v / u)
            else:
                phi = math.pi / 2 - math.pi / 4 * u / v
                x, y = v * math.cos(phi), v * math.sin(phi)
            xs.append(x)
            ys.append(y)
    return xs, ys


def frame_axis(centre, toward) -> tuple[np.ndarray, np.ndarray]:
    """(w0, f) of a sphere light: w0 the unit vector from the centre to ``toward``
    ((0, 0, −1) when they coincide), f the world axis of w0's smallest component (the
    first of equals) made perpendicular to it."""
    w0 = np.asarray(toward, dtype=np.float64) - np.asarray(centre, dtype=np.float64)
    length = float(np.linalg.norm(w0))
    w0 = w0 / length if length > 0 and math.isfinite(length) else np.array([0.0, 0.0, -1.0])
    axis = np.zeros(3)
    axis[int(np.argmin(np.abs(w0)))] = 1.0
    f = axis - np.dot(axis, w0) * w0
    return w0, f / np.linalg.norm(f)


def _property(props, name, default):
    value = props.get(name, None)
    if value is None:
        return default
    try:
        return [float(value[i]) for i in range(3)]
    except (TypeError, IndexError, ValueError):
        raise ValueError(f"stratified_area: {name} must be 3 numbers, got {value!r}") from None


def _jit() -> bool:
    return dr.is_jit_v(mi.Float)


def _inverse_distance(d, dist):
    """1/|d| as Mitsuba's ``point`` light computes it in the JIT variants, bit for bit
    (measured: an rsqrt of the squared norm; Dr.Jit's rcp of the norm differs by an ulp).
    The scalar variant's point light rounds otherwise (its norm is a double here): there
    one sample agrees with the point light to float32 rounding, not bit for bit."""
    return dr.rsqrt(dr.squared_norm(d)) if _jit() else dr.rcp(dist)


@plugin("emitter", "stratified_area")
class StratifiedArea:
    """An area light: n×n point lights at the stratum centres of a rectangle or a sphere."""

    def __init__(self, props):
        mi.Emitter.__init__(self, props)
        self.m_flags = mi.EmitterFlags.DeltaPosition      # a set of points
        shape = props.get("shape", "rectangle")
        if shape not in SHAPES:
            raise ValueError(f"stratified_area: shape must be rectangle or sphere, got {shape!r}")
        self.shape = shape
        samples = props.get("samples", 16)
        problem = light_samples_problem(samples)
        if problem:
            raise ValueError(f"stratified_area: {problem}, found {samples!r}")
        self.samples, self.n = int(samples), samples_per_axis(int(samples))
        position = _property(props, "position", [0.0, 0.0, 0.0])
        self.position = mi.Point3f(*position)
        self.intensity = mi.Color3f(*_property(props, "intensity", [1.0, 1.0, 1.0]))
        if shape == "rectangle":
            axis1, axis2 = (_property(props, k, None) for k in ("axis1", "axis2"))
            if axis1 is None or axis2 is None:
                raise ValueError("stratified_area: a rectangle needs axis1 and axis2")
            problem = area_axes_problem(axis1, axis2)
            if problem:
                raise ValueError(f"stratified_area: {problem}")
            self.axis1, self.axis2 = mi.Vector3f(*axis1), mi.Vector3f(*axis2)
            offsets = grid_offsets(self.n)
        else:
            radius = float(props.get("radius", 1.0))
            problem = area_radius_problem(radius)
            if problem or not math.isfinite(radius):
                raise ValueError(f"stratified_area: radius must be > 0, got {radius!r}")
            self.radius = mi.Float(radius)
            self.toward = _property(props, "toward", [position[0], position[1], position[2] - 1])
            offsets = disk_offsets(self.n)
        if _jit():
            self.offsets = [mi.Float(o) for o in offsets]
        else:                       # scalar_rgb: Python lists, indexed by the sample
            self.offsets = [list(o) for o in offsets]
        self.parameters_changed()

    # -- Mitsuba's interface ----------------------------------------------------

    def _editable(self) -> dict:
        own = {"position": self.position, "intensity": self.intensity}
        if self.shape == "rectangle":
            own.update(axis1=self.axis1, axis2=self.axis2)
        else:
            own.update(radius=self.radius)
        return own

    def traverse(self, cb):
        for name, value in self._editable().items():
            cb.put(name, value, mi.ParamFlags.Differentiable if name == "intensity"
                   else mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys=[]):
        """Opaque values (an edit reuses the kernel; a recording takes them as inputs);
        a sphere's frame vector f from the centre as it is now (docs: ``frame_axis``)."""
        if self.shape == "sphere":
            w0, f = frame_axis(numbers(self.position), self.toward)
            self.w0, self.f = mi.Vector3f(*map(float, w0)), mi.Vector3f(*map(float, f))
        if _jit():
            dr.make_opaque(*self._editable().values(), *self.offsets)
            if self.shape == "sphere":
                dr.make_opaque(self.w0, self.f)

    def recording_key(self) -> tuple:
        """What decides the code :meth:`shade` traces: the shape and the sample count."""
        return ("stratified_area", self.shape, self.samples)

    def to_string(self):
        fields = {"shape": self.shape, "samples": self.samples,
                  "position": numbers(self.position).tolist(),
                  "intensity": numbers(self.intensity).tolist()}
        if self.shape == "rectangle":
            fields.update(axis1=numbers(self.axis1).tolist(), axis2=numbers(self.axis2).tolist())
        else:
            fields.update(radius=float(numbers(self.radius)[0]))
        return describe("StratifiedArea", fields)

    def sample_direction(self, it, sample, active=True):
        """One sample point, picked by ``sample.x``; its weight is intensity / d² (each
        point carries 1/N of the intensity and is picked with probability 1/N)."""
        index = dr.minimum(mi.UInt32(sample.x * self.samples), self.samples - 1)
        edges = self._edges(it.p)
        target = self._point(index, edges)
        ds = dr.zeros(mi.DirectionSample3f)
        ds.p, ds.pdf, ds.delta, ds.time = target, 1.0, True, it.time
        ds.d = target - it.p
        ds.dist = dr.norm(ds.d)
        inv = _inverse_distance(ds.d, ds.dist)
        ds.d *= inv
        ds.emitter = mi.EmitterPtr(self) if _jit() else self
        weight = dr.select(active, self.intensity * dr.square(inv), 0.0)
        return ds, weight

    def eval(self, si, active=True):
        return mi.Color3f(0.0)

    def pdf_direction(self, it, ds, active=True):
        return mi.Float(0.0)

    # -- the pattern -----------------------------------------------------------

    def _edges(self, p):
        """(e1, e2): a sample at offsets (s, t) lies at position + s·e1 + t·e2. A
        rectangle's are its axes; a sphere's the disk's radius·t and radius·b, facing p
        (zero where p is the centre)."""
        if self.shape == "rectangle":
            return self.axis1, self.axis2
        w = dr.normalize(mi.Vector3f(p - self.position))
        t = self.f - dr.dot(self.f, w) * w
        # w ∥ f (90° from the look-at direction): w0 is perpendicular to w there.
        t = dr.select(dr.squared_norm(t) > 1e-12, t, self.w0 - dr.dot(self.w0, w) * w)
        t = dr.normalize(t)
        b = dr.cross(w, t)
        away = dr.squared_norm(p - self.position) > 0
        return (dr.select(away, self.radius * t, 0.0), dr.select(away, self.radius * b, 0.0))

    def _offset(self, k, axis):
        if _jit():
            return dr.gather(mi.Float, self.offsets[axis], k)
        return self.offsets[axis][k]

    def _point(self, k, edges):
        e1, e2 = edges
        return self.position + self._offset(k, 0) * e1 + self._offset(k, 1) * e2

    # -- what the whitted integrator calls ---------------------------------------

    def shade(self, scene, spheres, si, p, n, v, on_sphere, hit, kd, ks, shininess,
              any_specular, shadows, doubts=None, n_offset=None):
        """Σ over the samples of the paper's point-light term (whitted.py's, operation for
        operation, so that one sample renders as a point light at the centre, bit for
        bit), in a symbolic loop: the kernel holds it once. ``doubts``: the channels'
        doubts (dkd, dks), shaded by the same samples beside the radiance (whitted.py's
        ``shade``): then (radiance, doubt). ``n`` shades; shadow rays leave along
        ``n_offset`` (the geometric normal where ``n`` is a smooth mesh's shading normal;
        None: ``n``)."""
        offset = n if n_offset is None else n_offset
        edges = self._edges(p)
        colour = self.intensity * (1.0 / self.samples)

        def body(k, radiance, *doubt):
            target = self._point(k, edges)
            d = target - p                       # Mitsuba's point light, sample_direction
            dist = dr.norm(d)
            inv = _inverse_distance(d, dist)
            d = d * inv
            weight = dr.select(hit, colour * dr.square(inv), 0.0)
            intensity = weight * dr.square(dist)  # undo the 1/d² falloff, as whitted does
            n_dot_l = dr.dot(n, d)
            lit = hit & (n_dot_l > 0)
            if shadows:
                lit &= ~sphere_hit.occluded(scene, spheres, si, p, offset, on_sphere, target,
                                            lit)
            shade = kd * n_dot_l
            if any_specular:
                h = dr.normalize(d + v)
                highlight = dr.power(dr.maximum(dr.dot(n, h), 0.0), shininess)
                shade += ks * highlight
            radiance = radiance + dr.select(lit, intensity * shade, 0.0)
            if not doubt:
                return k + 1, radiance
            dkd, dks = doubts
            doubt_shade = dkd * n_dot_l + (dks * highlight if any_specular else 0.0)
            return k + 1, radiance, doubt[0] + dr.select(lit, intensity * doubt_shade, 0.0)

        zero = dr.zeros(mi.Color3f, dr.width(p))
        state = (zero,) if doubts is None else (zero, zero)
        if not _jit():
            for k in range(self.samples):
                state = body(k, *state)[1:]
        else:
            state = dr.while_loop(state=(mi.UInt32(0),) + state,
                                  cond=lambda k, *rest: k < self.samples, body=body,
                                  labels=("k", "radiance", "doubt")[:1 + len(state)])[1:]
        return state[0] if doubts is None else state
