"""Sphere hits refined in float64, and shadow rays that cannot meet their own sphere.

Mitsuba's ``sphere`` solves the ray's quadratic in float32 in the AD variants and
re-projects the hit as p = c + r·n in float32, so a hit on a large sphere is off
by about ulp(|c| + r): 1e-3 on a "ground sphere" of radius 10⁴ under a unit
sphere. That error is far larger than Mitsuba's spawn offset
((1 + max|p_k|)·RayEpsilon, RayEpsilon = 1500·2⁻²⁴ ≈ 8.9e-5), so shadow rays from
such a floor start inside it and find it again: speckled acne and false shadows
(14 dB against the reference tracer).

The cure keeps Mitsuba's intersection (it decides *which* sphere is hit) and
then, on the sphere it found, in float64:

* solve |o + t·d − c|² = r² by the numerically stable quadratic and take the
  root nearest Mitsuba's t, so p = o + t·d is exact to float64 and then rounded
  once to float32; the normal is (p − c)/r.

Shadow rays follow the rendering model's contract (docs/rendering-model.md,
"Shadows"): from p′ = p + ε·n, ε = EPS_REL·(1 + max|p_k|) with the reference
tracer's EPS_REL = 1e-4 (not Mitsuba's RayEpsilon: the 10 % difference moved
shadow edges by a sample), to the light along the whole segment. When Mitsuba's
float32 test says such a ray meets its *own* sphere first, the answer is
checked again along the same line, from the point where the ray is
δ = SHADOW_OFFSET_ULPS · 2⁻²³ · (max|c_k| + r + max|p_k|) above the surface: δ
bounds the error of Mitsuba's own float32 intersection of that ray with that
sphere (the quadratic is solved from o − c, a projection onto the ray and
|o′|² − r², each rounded at the scale |c| + r, and the origin p′ at |p|), so
past it the sphere is only met where it really is: never on the lit outside of
a convex sphere, across the inside when the hit was seen from within. Staying
on the reference's line (rather than moving the origin δ along the normal) keeps
contact shadows where they are.

Non-sphere shapes keep Mitsuba's hit. The sphere table is indexed by the
shape's registry id, clamped into the table, so the gathers are in bounds by
construction.
"""

from __future__ import annotations

from mimarble.contract import EPS_REL, FLOAT32_EPSILON
from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import transform_matrix

dr, mi = environment.import_drjit_and_mitsuba()

#: Shadow-ray offset in units of 2⁻²³·(max|c_k| + r + max|p_k|) (≈ ulps of that scale).
SHADOW_OFFSET_ULPS = 2.0
_ULP = FLOAT32_EPSILON
# The rendering model's shadow-ray offset ε = EPS_REL·(1 + max|p_k|), shared with the
# reference tracer through mimarble.contract.
#: Shadow rays stop this fraction short of the light. Mitsuba's ``spawn_ray_to`` stops
#: ShadowEpsilon = 8.9e-4 short (meant for area lights' own shapes; point lights have
#: none), which let a light enclosed by a sphere of radius < 8.9e-4 of its distance
#: light everything (16 dB); 2⁻²⁰ is still 4× the float32 error of that hit.
SHADOW_END_REL = 2.0 ** -20
#: Whether shadow rays in scenes with a large sphere check every sphere hit in float64
#: (:func:`_occluded_checking_spheres`): None — on a CUDA GPU only, where Mitsuba's
#: sphere hits are float32; True runs it on the CPU too (its tests).
CHECK_SPHERE_HITS: bool | None = None
#: At most this many spheres are tested in float64 by every shadow ray (each is code in
#: the kernel); a scene with more keeps the CPU's test on a GPU too.
CHECKED_SPHERES_MAX = 64


def spheres_only(scene) -> bool:
    """Whether every shape of the Mitsuba scene is a ``sphere`` (a static fact: what
    code is traced may depend on it)."""
    return all(shape.shape_type() == mi.ShapeType.Sphere for shape in scene.shapes())


def _sphere_geometry(shape):
    """(centre, radius) of a Mitsuba sphere as float64 Python numbers, else None."""
    if shape.shape_type() != mi.ShapeType.Sphere:
        return None
    m = transform_matrix(mi.traverse(shape)["to_world"])
    centre = (float(m[0, 3]), float(m[1, 3]), float(m[2, 3]))
    radius = float((m[0, 0] ** 2 + m[1, 0] ** 2 + m[2, 0] ** 2) ** 0.5)   # as Mitsuba's sphere
    return centre, radius


def _placements(scene) -> list:
    """The spheres' ``to_world`` as ``mi.traverse`` holds them (the variables a table is
    kept for)."""
    return [mi.traverse(s)["to_world"] for s in scene.shapes()
            if s.shape_type() == mi.ShapeType.Sphere]


class SphereTable:
    """Centres and radii of a scene's spheres, looked up per lane by the hit shape.

    A table is built from the shapes' ``to_world`` (a ``mi.traverse`` per sphere), read to
    the host once per build: the values are evaluated, so after the first read no read
    waits for a kernel (docs/design-decisions.md, "Replaying recorded kernels", says why
    it is not built on the device). Its columns are opaque Dr.Jit arrays that the table
    holds (``DRJIT_STRUCT``), so that a recording of the kernels
    (mimarble/mitsuba/rendering/replay.py) takes them as inputs; what decides the traced code,
    :attr:`structure`, is part of the recording's key. Where it comes from
    (:meth:`for_trace`): the table :meth:`of` keeps for the scene, made again only when a
    shape's ``to_world`` is another Dr.Jit variable (an edit; the table holds copies of
    them, so none can be freed and its index reused) — a recorded pass uses the one its
    caller refreshed; the scalar variant, which traces every sample, keeps one while the
    shapes' bounding boxes stay.
    """

    DRJIT_STRUCT = {"columns": list}
    #: Tables by scene, with what they were built for (and, in the scalar variant, its
    #: shapes, to tell a new scene that took a freed one's id), a few kept.
    _tables: dict = {}
    KEPT = 4

    @classmethod
    def of(cls, scene, placements=None) -> "SphereTable":
        """The table of ``scene``: the one built before, unless a shape has moved or
        changed size since, or :data:`CHECK_SPHERE_HITS` was set otherwise — told by ``placements`` (the shapes' ``to_world``, as
        ``mi.traverse`` holds them: the same variables as the table's copies), else by the
        shapes' bounding boxes (the scalar variant)."""
        if placements is not None:
            facts = tuple(tuple(dr.detail.collect_indices(p)) for p in placements)
        else:
            facts = tuple((tuple(s.bbox().min), tuple(s.bbox().max)) for s in scene.shapes())
        # The switch decides checks_hits (the traced code): a table built under the other
        # setting is stale, as one of moved shapes.
        facts = (CHECK_SPHERE_HITS, facts)
        facts_then, table, held = cls._tables.pop(id(scene), (None, None, None))
        # A new scene may take a freed one's id. Its spheres' ``to_world`` are other
        # variables than the held copies (whose indices cannot be reused while held), so
        # the facts tell it; without spheres every table reads radius 0. The scalar
        # variant compares the very shapes, which its table holds.
        if facts_then != facts or (placements is None and any(
                a is not b for a, b in zip(scene.shapes(), table.shapes))):
            if len(cls._tables) >= cls.KEPT:
                cls._tables.pop(next(iter(cls._tables)))
            table = cls(scene)
            # Copies hold the very variables, so none is freed and its index reused.
            held = None if placements is None else [type(p)(p) for p in placements]
        cls._tables[id(scene)] = (facts, table, held)       # the most recently used last
        return table

    @classmethod
    def for_trace(cls, scene) -> "SphereTable":
        """The table a trace of ``scene`` reads (see the class docstring)."""
        if not dr.is_jit_v(mi.Float):
            return cls.of(scene)
        if dr.flag(dr.JitFlag.FreezingScope) and id(scene) in cls._tables:
            return cls._tables[id(scene)][1]
        return cls.of(scene, _placements(scene))

    @classmethod
    def forget(cls, scene) -> None:
        """Drop the table of ``scene`` (and the copies of its spheres' ``to_world`` it holds;
        the scalar variant's holds its shapes alive too)."""
        cls._tables.pop(id(scene), None)

    @property
    def structure(self) -> tuple:
        """What decides the code :func:`refine` and :func:`occluded` trace."""
        return (getattr(self, "size", None), self.large, self.checks_hits,
                self.sphere_ids if self.checks_hits else None, self.spheres_only)

    def __init__(self, scene):
        shapes = list(scene.shapes())
        self.geometry = [_sphere_geometry(s) for s in shapes]
        # Held only where the lookup needs them (the scalar variant): a table of a JIT
        # variant holds no shape, so a dropped scene's shapes leave Dr.Jit's registry, which
        # every recorded pass walks (issue 43: a replay grew slower with each scene held;
        # docs/benchmarks.md, "Figures moved out of the code").
        self.shapes = None if dr.is_jit_v(mi.Float) else shapes
        self.sphere_ids = ()
        self.spheres_only = all(g is not None for g in self.geometry)
        if dr.is_jit_v(mi.Float):
            # Every shape's id sizes the table (a hit's id indexes it, clamped to its end):
            # a plane or mesh whose id is past the last sphere's finds r = 0.
            ids = [int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s))[0]) for s in shapes]
            size = max(ids, default=0) + 1
            columns = [[0.0] * size for _ in range(4)]   # cx, cy, cz, r; r = 0: not a sphere
            for shape_id, geometry in zip(ids, self.geometry):
                if geometry is not None:
                    (cx, cy, cz), r = geometry
                    for column, value in zip(columns, (cx, cy, cz, r)):
                        column[shape_id] = value
            self.size = size
            self.sphere_ids = tuple(i for i, g in zip(ids, self.geometry) if g is not None)
            self.columns = [mi.Float64(c) for c in columns]
            dr.make_opaque(*self.columns)     # evaluated, never a literal: recorded as inputs
        scales = [max(map(abs, g[0])) + g[1] for g in self.geometry if g is not None]
        # Whether Mitsuba's float32 error on some sphere can reach the shadow-ray offset
        # ε ≥ EPS_REL (max|c_k| + r > 419): then refine() works in float64 and occluded()
        # looks for false hits on the own sphere; below it both would change nothing.
        self.large = any(SHADOW_OFFSET_ULPS * _ULP * x > EPS_REL for x in scales)
        # Where Mitsuba's sphere hits are float32 (OptiX): each checked in float64.
        checks = CHECK_SPHERE_HITS if CHECK_SPHERE_HITS is not None else \
            dr.is_jit_v(mi.Float) and dr.backend_v(mi.Float) == dr.JitBackend.CUDA
        self.checks_hits = self.large and checks and \
            len(self.sphere_ids) <= CHECKED_SPHERES_MAX

    def entry(self, shape_id: int):
        """(centre: Point3d, radius: Float64) of the sphere whose shape id is
        ``shape_id`` (JIT variants), read from the table: an input of a recorded pass."""
        index = mi.UInt32(shape_id)
        cx, cy, cz, r = (dr.gather(mi.Float64, c, index) for c in self.columns)
        return mi.Point3d(cx, cy, cz), r

    def lookup(self, shape):
        """(centre: Point3d, radius: Float64) per lane; radius 0 where no sphere was hit."""
        if dr.is_jit_v(mi.Float):
            index = dr.minimum(dr.reinterpret_array(mi.UInt32, shape), self.size - 1)
            cx, cy, cz, r = (dr.gather(mi.Float64, c, index) for c in self.columns)
            return mi.Point3d(cx, cy, cz), r
        for candidate, geometry in zip(self.shapes, self.geometry):
            if geometry is not None and shape is not None and shape == candidate:
                return mi.Point3d(*geometry[0]), geometry[1]
        return mi.Point3d(0.0, 0.0, 0.0), 0.0


def _largest_component(v):
    return dr.maximum(dr.maximum(dr.abs(v.x), dr.abs(v.y)), dr.abs(v.z))


def sphere_roots64(o, d, centre, radius):
    """(discriminant, t0, t1) of |o + t·d − c|² = r² in float64, by the numerically stable
    quadratic: q = −(b + sign(b)·√max(disc, 0)), t0 = q/a, t1 = c/q (t0 where q = 0), with
    |o − c|² − r² as (|o − c| − r)(|o − c| + r), no cancellation of two large squares. A
    negative discriminant (no real root) is returned as it is; the roots are then those
    of the tangent ray."""
    oc = o - centre
    a = dr.squared_norm(d)
    b = dr.dot(oc, d)
    distance = dr.norm(oc)
    c = (distance - radius) * (distance + radius)
    discriminant = b * b - a * c
    q = -(b + dr.copysign(dr.sqrt(dr.maximum(discriminant, 0.0)), b))
    q = dr.select(q == 0.0, -b, q)
    t0 = q / a
    t1 = dr.select(q != 0.0, c / q, t0)
    return discriminant, t0, t1


def refine(table: SphereTable, ray, si, hit):
    """(p, n, on_sphere): the hit point and outward normal, refined in float64 where
    Mitsuba hit a sphere (Mitsuba's own p and n elsewhere).

    Scenes without a large sphere keep Mitsuba's hit as it is: its error is then
    below the shadow-ray offset, and the refinement would cost a noticeable part of a
    render (docs/benchmarks.md, "Figures moved out of the code").
    """
    if not table.large:
        return si.p, mi.Vector3f(si.n), mi.Bool(False) & hit
    centre, radius = table.lookup(si.shape)
    on_sphere = hit & (radius > 0)
    o, d = mi.Point3d(ray.o), mi.Vector3d(ray.d)
    _, t0, t1 = sphere_roots64(o, d, centre, radius)   # a grazing hit Mitsuba found: tangent
    t_mitsuba = mi.Float64(si.t)
    t = dr.select(dr.abs(t0 - t_mitsuba) <= dr.abs(t1 - t_mitsuba), t0, t1)
    p64 = o + d * t
    n64 = (p64 - centre) / dr.select(on_sphere, radius, 1.0)
    p = dr.select(on_sphere, mi.Point3f(p64), si.p)
    n = dr.select(on_sphere, dr.normalize(mi.Vector3f(n64)), mi.Vector3f(si.n))
    return p, n, on_sphere


def _ray_to(origin, target, time, wavelengths):
    to_target = target - origin
    distance = dr.norm(to_target)
    return mi.Ray3f(origin, to_target / distance, distance * (1.0 - SHADOW_END_REL),
                    time, wavelengths)


def occluded(scene, table: SphereTable, si, p, n_facing, on_sphere, target, active):
    """The paper's ``shadowHit``: does anything lie between the hit and ``target``?

    From p′ = p + ε·n_facing, ε = EPS_REL·(1 + max|p_k|), as the reference tracer
    (n_facing faces the light on every lane that asks). In scenes with a sphere
    large enough for Mitsuba's float32 error to matter (:attr:`SphereTable.large`),
    a ray whose first hit is its own sphere is tested again along the same line
    from where it is δ above the surface (module docstring); only those lanes pay
    for the second ray.
    """
    origin = p + n_facing * ((1.0 + _largest_component(p)) * EPS_REL)
    ray = _ray_to(origin, target, si.time, si.wavelengths)
    if not table.large:
        return scene.ray_test(ray, active)
    if table.checks_hits:
        return _occluded_checking_spheres(scene, table, ray, active)
    first = scene.ray_intersect_preliminary(ray, active)
    blocked = mi.Bool(active) & first.is_valid()
    own = blocked & on_sphere & (first.shape == si.shape)
    centre, radius = table.lookup(si.shape)
    scale = _largest_component(centre) + radius + mi.Float64(_largest_component(p))
    delta = mi.Float(scale * (SHADOW_OFFSET_ULPS * _ULP))
    # δ above the surface along a ray that leaves it at cos θ = n·d. Below cos θ = 1e-3
    # the light grazes the surface and n·l (the diffuse term) is < 1e-3 anyway.
    skip = dr.minimum(delta / dr.maximum(dr.dot(n_facing, ray.d), 1e-3), 0.5 * ray.maxt)
    retry = mi.Ray3f(ray(skip), ray.d, ray.maxt - skip, ray.time, ray.wavelengths)
    return (blocked & ~own) | (own & scene.ray_test(retry, own))


#: Hits on spheres, stepped past at most this many times a shadow ray in search of
#: another shape (:func:`_occluded_checking_spheres`).
CUDA_SPHERE_STEPS = 4


def _crosses_sphere(ray, centre, radius):
    """Whether ``ray`` crosses the sphere's surface within (0, maxt), in float64
    (:func:`sphere_roots64`); False where radius is 0."""
    discriminant, t0, t1 = sphere_roots64(mi.Point3d(ray.o), mi.Vector3d(ray.d), centre, radius)
    maxt = mi.Float64(ray.maxt)
    within = ((t0 > 0.0) & (t0 < maxt)) | ((t1 > 0.0) & (t1 < maxt))
    return (radius > 0.0) & (discriminant >= 0.0) & within


def _occluded_checking_spheres(scene, table: SphereTable, ray, active):
    """The shadow test on a GPU, where Mitsuba's sphere is intersected by OptiX in float32
    (mitsuba3 src/shapes/optix/sphere.cuh): its |o − c|² − r² loses ulp(r²), so a ray
    leaving a large sphere, or passing near one, can report a hit on it far past the δ
    the CPU's test allows for. Spheres are tested here instead, every one of the table
    in float64 (:func:`_crosses_sphere`); other shapes as Mitsuba finds them, the ray
    going on past each sphere it reports, up to :data:`CUDA_SPHERE_STEPS` times (an
    occluder behind more sphere hits than that is missed); none in a scene of spheres."""
    blocked = dr.zeros(mi.Bool, dr.width(ray.o))
    for shape_id in table.sphere_ids:
        centre, radius = table.entry(shape_id)
        blocked |= _crosses_sphere(ray, centre, radius)
    blocked &= active
    if table.spheres_only:
        return blocked
    searching = mi.Bool(active) & ~blocked
    start = dr.zeros(mi.Float, dr.width(ray.o))
    for _ in range(CUDA_SPHERE_STEPS):
        part = mi.Ray3f(ray(start), ray.d, ray.maxt - start, ray.time, ray.wavelengths)
        first = scene.ray_intersect_preliminary(part, searching)
        hit = searching & first.is_valid()
        _, radius = table.lookup(first.shape)
        blocked |= hit & (radius <= 0.0)
        searching = hit & (radius > 0.0)
        # Past the reported hit by the shadow-ray offset ε there: from the hit itself the
        # next search would find the same sphere again at t ≈ 0, a step spent for nothing.
        step = first.t + EPS_REL * (1.0 + _largest_component(part(first.t)))
        start = dr.select(searching, start + step, start)
        searching &= start < ray.maxt
    return blocked
