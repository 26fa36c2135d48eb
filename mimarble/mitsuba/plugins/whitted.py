"""``whitted``: the paper's ray tracer as a Mitsuba integrator (primary rays only).

For the closest hit p (Mitsuba's ``ray_intersect``, whose surface interaction
is the paper's hit record: it passes the material, hence the channel colours,
back), with two-sided normal n and view direction v = −d::

    L = ka(p)⊙A + Σ_lights V(p,l) · I_l ⊙ ( kd(p)·max(0, n·l) + ks(p)·max(0, n·h)^shininess )

with h = normalize(l + v), point lights of intensity I_l *without* distance
falloff, and V the paper's ``shadowHit``: n·l > 0 and Mitsuba's any-hit
``ray_test`` finds nothing between p + ε·n (ε = 1e-4·(1 + max|p_k|), as the
reference tracer) and the light. On large spheres, where Mitsuba's float32 hit
is off by more than ε, p and n are first refined in float64 and a shadow ray's
false hit on its own sphere is checked again (``sphere_hit.py``). Every other shape
(a plane's ``disk``, a box's ``cube``, a mesh) keeps Mitsuba's hit and is shaded flat,
with its geometric normal ``si.n`` (docs/rendering-model.md, "Planes, boxes and
meshes") — unless ``shading_normals`` is on: then every shape but a refined sphere is
shaded with Mitsuba's shading normal ``si.sh_frame.n`` (a smooth mesh's vertex normals
interpolated, b₀n₀ + b₁n₁ + b₂n₂ normalised), turned to the viewer's side of the
geometric normal with it, while shadow rays still leave along the geometric normal (so
that the shadow test is the flat one's). Every light
contributes (no light is picked at random). A miss returns the background colour, or
with an environment emitter in the scene (``envmap``, ``constant``: Mitsuba's
``scene.environment()``) its radiance in the ray's direction — the scene language's
``environment``, seen as the background; it lights nothing here (no secondary rays; the
ambient term stays the paper's A). The
integrator draws no random numbers: with a non-jittered ``stratified`` sampler
and a ``box`` filter the image is deterministic (docs/rendering-model.md).

What the scene does not need is not computed: the specular half-vector and
power only where some material has a specular channel, no lights at all where no
material has a diffuse or specular one, shadow rays only for lanes that face the
light, no channel evaluation for absent channels.

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Description
   * - ``ambient``
     - rgb (0 0 0)
     - The global ambient colour A.
   * - ``background``
     - rgb (0 0 0)
     - Radiance of rays that hit nothing.
   * - ``shadows``
     - boolean (true)
     - Trace the shadow rays (false: V = [n·l > 0]).
   * - ``shading_normals``
     - boolean (false)
     - Shade with each hit's shading normal ``si.sh_frame.n`` (a mesh loaded with
       ``face_normals`` false: its vertex normals interpolated) rather than the geometric
       ``si.n``. The translator turns it on for scenes with a smooth mesh; off, every
       image of a scene without one stays as it was (a ``cube``'s vertex normals can
       differ from its face normals in the last bit).

Every shape's BSDF must be a ``channel_material``; lights must be point-like
(``point``, ``spot``), an environment (background only), or ``stratified_area`` (an area light as n×n point lights at fixed
stratum centres, area_light.py: the samples a symbolic loop, so that the kernel holds one
light's code whatever their count); other emitters are an error.
"""

from __future__ import annotations

from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import describe, largest_component, numbers, plugin
from mimarble.texture.mapping import (compute_uv_partials_scaled, differentials_from_the_eye,
    footprints_omitted_on_purpose)
from . import sphere_hit
from .area_light import StratifiedArea
from .material import ChannelMaterial

dr, mi = environment.import_drjit_and_mitsuba()


def _colour(props, name):
    value = props.get(name, None)
    if value is None:
        return mi.Color3f(0.0)
    try:
        rgb = [float(value[i]) for i in range(3)]
    except (TypeError, IndexError, ValueError):
        raise ValueError(f"whitted: {name} must be an RGB triple, got {value!r}") from None
    return mi.Color3f(*rgb)


def _no_channels(si):
    zero = dr.zeros(mi.Color3f, dr.width(si.p))
    return zero, zero, zero, mi.Float(1.0)


def _no_channels_and_doubts(si):
    zero = dr.zeros(mi.Color3f, dr.width(si.p))
    return _no_channels(si) + (zero, zero, zero)


#: Mitsuba 3.9's BSDF and emitter plugins by class (each ``src/*/NAME.cpp`` ends with
#: ``MI_EXPORT_PLUGIN(CLASS)``): objects know their class, not the name a scene gave.
#: Making each plugin to ask its class is no way to find out: some abort the process
#: without their parameters (``blendbsdf``).
MITSUBA_PLUGIN_NAMES = {
    "BlendBSDF": "blendbsdf", "BumpMap": "bumpmap", "CircularPolarizer": "circular",
    "SmoothConductor": "conductor", "SmoothDielectric": "dielectric",
    "SmoothDiffuse": "diffuse", "Hair": "hair", "MaskBSDF": "mask", "Measured": "measured",
    "MeasuredPolarized": "measured_polarized", "NormalMap": "normalmap", "Null": "null",
    "SmoothPlastic": "plastic", "LinearPolarizer": "polarizer", "PolarizedPlastic": "pplastic",
    "Principled": "principled", "PrincipledThin": "principledthin",
    "LinearRetarder": "retarder", "RoughConductor": "roughconductor",
    "RoughDielectric": "roughdielectric", "RoughPlastic": "roughplastic",
    "ThinDielectric": "thindielectric", "TwoSidedBRDF": "twosided",
    "AreaLight": "area", "ConstantBackgroundEmitter": "constant",
    "DirectionalEmitter": "directional", "DirectionalArea": "directionalarea",
    "EnvironmentMapEmitter": "envmap", "PointLight": "point", "Projector": "projector",
    "SpotLight": "spot", "SunskyEmitter": "sunsky", "TimedSunskyEmitter": "timed_sunsky",
}


def _class_of(plugin) -> str:
    """The plugin as a scene names it, with its class: "'diffuse' (SmoothDiffuse)"; a
    class not in :data:`MITSUBA_PLUGIN_NAMES` by its class alone (a Python plugin's is
    its Python class)."""
    name = plugin.class_name()
    if name in ("BSDF", "Emitter"):
        return type(plugin).__name__
    return f"'{MITSUBA_PLUGIN_NAMES[name]}' ({name})" if name in MITSUBA_PLUGIN_NAMES else name


def _material_channels(material, si, active):
    if isinstance(material, ChannelMaterial):
        return material.channels(si, active)
    return _no_channels(si)


def _material_channels_and_doubts(material, si, active):
    if isinstance(material, ChannelMaterial):
        return material.channels_and_doubts(si, active)
    return _no_channels_and_doubts(si)


@plugin("integrator", "whitted")
class Whitted:
    """Whitted-style shading of the paper: ambient + diffuse + Phong specular, hard shadows."""

    def __init__(self, props):
        mi.SamplingIntegrator.__init__(self, props)
        problem = environment.whitted_problem(mi.variant())
        if problem:                   # it shades colours (Color3f), not spectra
            raise environment.EnvironmentProblem(problem)
        self.ambient = _colour(props, "ambient")
        self.background = _colour(props, "background")
        self.shadows = bool(props.get("shadows", True))
        self.shading_normals = bool(props.get("shading_normals", False))
        self.parameters_changed()

    def aov_names(self):
        return []

    def traverse(self, cb):
        cb.put("ambient", self.ambient, mi.ParamFlags.Differentiable)
        cb.put("background", self.background, mi.ParamFlags.Differentiable)

    def parameters_changed(self, keys=[]):
        """The colours opaque, as an edit left them: a new value reuses the kernel (and
        a recording of it takes them as inputs)."""
        if dr.is_jit_v(mi.Float):
            dr.make_opaque(self.ambient, self.background)

    def recording(self, scene, placements) -> tuple[tuple, tuple]:
        """(key, inputs) of a recording of :meth:`sample` for ``scene``, from one look-up of
        the sphere table it keeps for it. Key: what decides the traced code besides Dr.Jit's
        variables and the materials' own keys (see ``Marble.recording_key``): the shadow
        switch and the table's structure. Inputs: the Dr.Jit state it reads that the scene
        does not hold (the table, made current). ``placements``: the shapes' ``to_world``
        (``mi.traverse``'s)."""
        table = sphere_hit.SphereTable.of(scene, placements)
        return ("whitted", self.shadows, self.shading_normals, table.structure), (table,)

    def to_string(self):
        return describe("Whitted", {"ambient": numbers(self.ambient).tolist(),
                                    "background": numbers(self.background).tolist(),
                                    "shadows": self.shadows,
                                    "shading_normals": self.shading_normals})

    @staticmethod
    def check_scene(scene) -> None:
        """Every shape's BSDF a ``channel_material`` and every emitter point-like, else a
        ``ValueError`` naming the shape or emitter and its Mitsuba class.

        Mitsuba gives an integrator no look at the scene it is loaded into, so this runs
        where mimarble first holds the scene (``mimarble.render`` of a loaded ``mi.Scene``,
        before anything is traced) and again when :meth:`sample` is traced (under
        ``mi.render`` the sentence is the cause of Dr.Jit's ``drjit.custom`` error)."""
        Whitted.scene_materials(scene)
        Whitted.scene_lights(scene)

    @staticmethod
    def scene_materials(scene):
        """The BSDF of each of ``scene``'s shapes, in order; ValueError unless each is a
        ``channel_material`` (the only material the Whitted sum shades)."""
        materials = [shape.bsdf() for shape in scene.shapes()]
        for shape, material in zip(scene.shapes(), materials):
            if not isinstance(material, ChannelMaterial):
                raise ValueError(f"whitted: shape {shape.id()!r} has BSDF {_class_of(material)}; "
                                 f"the whitted integrator needs 'channel_material' "
                                 f"(or render with Mitsuba's 'path')")
        return materials

    @staticmethod
    def scene_lights(scene):
        """``scene``'s emitters but the environment; ValueError unless each is a point light
        or a ``stratified_area`` (the lights whose sum the Whitted model takes)."""
        # The environment (Mitsuba holds at most one) is the background, not a light.
        lights = [light for light in scene.emitters() if not light.is_environment()]
        for light in lights:
            if not isinstance(light, StratifiedArea) and \
                    not mi.has_flag(light.flags(), mi.EmitterFlags.DeltaPosition):
                raise ValueError(f"whitted: emitter {light.id()!r} is {_class_of(light)}, not "
                                 f"a point light; the whitted integrator shades with point "
                                 f"lights only ('point', 'spot', and 'stratified_area' for "
                                 f"area lights)")
        return lights

    @staticmethod
    def _channels(si, ray, hit, doubts=False):
        """The hit material's channels (and with ``doubts`` their doubts): a symbolic
        call over materials in JIT variants.

        A symbolic call traces *every* live BSDF instance of the variant (other
        scenes' too), so instances that are not channel materials give zeros.
        """
        channels = _material_channels_and_doubts if doubts else _material_channels
        if dr.is_jit_v(mi.Float):
            return dr.dispatch(si.bsdf(ray), channels, si, hit)
        return channels(si.bsdf(ray), si, hit) if hit else \
            (_no_channels_and_doubts if doubts else _no_channels)(si)

    def sample(self, scene, sampler, ray, medium=None, active=True):
        return self.sample_and_shape(scene, sampler, ray, medium, active)[:3]

    def sample_and_shape(self, scene, sampler, ray, medium=None, active=True):
        """``sample``'s (radiance, valid, aovs), and the id of the shape each ray hit
        first (its registry index; 0 for a miss), for edge samples: from the same
        intersection, so finding silhouettes costs no second ray (and nothing at all
        when the id is not used: Dr.Jit traces only what is evaluated)."""
        radiance, shape, _ = self.shade(scene, ray, active)
        return radiance, mi.Bool(True), [], shape

    @staticmethod
    def prepare_doubts(scene) -> None:
        """Every channel material of ``scene`` makes what its marbles' second estimates
        read, before :meth:`shade` with ``doubts`` is traced."""
        for material in Whitted.scene_materials(scene):
            material.prepare_alternates()

    def shade(self, scene, ray, active=True, doubts: bool = False):
        """(radiance, first shape id or None, doubt or None) of each ray: ``sample``'s
        radiance; the shape, as :meth:`sample_and_shape` gives it; with ``doubts`` (JIT
        variants, rays with differentials, after :meth:`prepare_doubts`), the doubt of the
        radiance: an upper bound of |L − L′| per lane (the largest of its three colours),
        L′ the radiance shaded with each channel's second estimate — the marbles' own
        estimate of how wrong a sample of them can be (``Marble.eval_and_alternate``),
        carried through the same lights. 0 for a miss."""
        # Static facts about the scene decide which code is traced at all.
        materials = self.scene_materials(scene)
        any_specular = any(m.has_channel("specular") for m in materials)
        footprints = any(m.needs_differentials() for m in materials)
        lights = self.scene_lights(scene)
        # Lights add kd·(n·l) + ks·(n·h)^s: nothing where no material has either. (Traced
        # anyway, a lone ambient-only material made Dr.Jit 1.5 emit invalid LLVM IR — "does
        # not dominate all uses" — and abort the process.)
        if not any_specular and not any(m.has_channel("diffuse") for m in materials):
            lights = []

        si = scene.ray_intersect(ray, active)
        hit = mi.Bool(active) & si.is_valid()
        # Mitsuba's hit, refined in float64 on the sphere it found (sphere_hit.py).
        spheres = sphere_hit.SphereTable.for_trace(scene)
        p, n, on_sphere = sphere_hit.refine(spheres, ray, si, hit)
        si.p = p
        if footprints or doubts:   # pixel footprints for filtered marbles, from the eye
            from_the_eye = differentials_from_the_eye(ray, scene)
            if sphere_hit.spheres_only(scene):   # as always: Mitsuba's, bit for bit
                si.compute_uv_partials(from_the_eye)
            else:   # a plane's disk, R = 10⁴·extent long, would overflow Mitsuba's solve
                compute_uv_partials_scaled(si, from_the_eye)
        if doubts:
            one, none = (lambda si, on: materials[0].channels_and_doubts(si, on)), \
                _no_channels_and_doubts
        else:
            one, none = (lambda si, on: materials[0].channels(si, on)), _no_channels
        if len({id(m) for m in materials}) == 1 and dr.is_jit_v(mi.Float):
            # One material: no symbolic call, and a symbolic `if` that lets packets of
            # missed rays skip the texture (docs/benchmarks.md, "What made it fast").
            channels = dr.if_stmt((si, hit), hit, one, lambda si, on: none(si))
        elif footprints or doubts:
            channels = self._channels(si, ray, hit, doubts)
        else:   # other scenes' filtered marbles, traced too, are not this scene's concern
            with footprints_omitted_on_purpose():
                channels = self._channels(si, ray, hit)
        ka, kd, ks, shininess = channels[:4]
        dka, dkd, dks = channels[4:] if doubts else (None, None, None)

        v = -mi.Vector3f(ray.d)
        behind = dr.dot(n, v) < 0
        if self.shading_normals:   # a smooth mesh's interpolated normal; refined spheres' own
            shading = dr.select(on_sphere, n, mi.Vector3f(si.sh_frame.n))
            n_offset = dr.select(behind, -n, n)      # shadow rays: the geometric side
            n = dr.select(behind, -shading, shading)
        else:
            n = dr.select(behind, -n, n)            # two-sided
            n_offset = None

        radiance = ka * self.ambient
        doubt = dka * self.ambient if doubts else None
        for light in lights:
            if isinstance(light, StratifiedArea):   # n×n point lights, in a symbolic loop
                shaded = light.shade(scene, spheres, si, p, n, v, on_sphere, hit, kd, ks,
                                     shininess, any_specular, self.shadows,
                                     doubts=(dkd, dks) if doubts else None,
                                     n_offset=n_offset)
                if doubts:
                    radiance, doubt = radiance + shaded[0], doubt + shaded[1]
                else:
                    radiance += shaded
                continue
            ds, weight = light.sample_direction(si, mi.Point2f(0.5, 0.5), hit)
            intensity = weight * dr.square(ds.dist)   # undo the 1/d² falloff
            n_dot_l = dr.dot(n, ds.d)
            lit = hit & (n_dot_l > 0)
            if self.shadows:
                lit &= ~sphere_hit.occluded(scene, spheres, si, p,
                                            n if n_offset is None else n_offset, on_sphere,
                                            ds.p, lit)
            shade = kd * n_dot_l
            if any_specular:
                h = dr.normalize(ds.d + v)
                highlight = dr.power(dr.maximum(dr.dot(n, h), 0.0), shininess)
                shade += ks * highlight
            radiance += dr.select(lit, intensity * shade, 0.0)
            if doubts:
                doubt_shade = dkd * n_dot_l + (dks * highlight if any_specular else 0.0)
                doubt += dr.select(lit, intensity * doubt_shade, 0.0)

        jit = dr.is_jit_v(mi.Float)
        shape = dr.select(hit, dr.reinterpret_array(mi.UInt32, si.shape), 0) if jit else None
        if doubts:
            doubt = dr.select(hit, largest_component(doubt), 0.0)
        return dr.select(hit, radiance, self.background_of(scene, ray, hit)), shape, doubt

    def background_of(self, scene, ray, hit):
        """What a ray that misses sees: the scene's environment emitter's radiance in its
        direction (``eval`` at an interaction whose ``wi`` is −d, as Mitsuba's ``path``
        evaluates it for an escaped ray), else the ``background`` colour."""
        environment = scene.environment()
        if environment is None:
            return self.background
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = -mi.Vector3f(ray.d)
        return environment.eval(si, ~hit if dr.is_jit_v(mi.Float) else not hit)
