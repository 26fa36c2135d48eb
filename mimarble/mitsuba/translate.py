"""Scene model → Mitsuba scene dict, in two modes.

``whitted``: the paper's model exactly — ``channel_material`` BSDFs, ``point``
lights, the ``whitted`` integrator, a non-jittered ``stratified`` sampler and a
``box`` filter, so every pixel is the mean of its n×n stratum centres.

``path``: physically based — the marble drives Mitsuba's own BSDFs under the
``path`` integrator. The paper's quantities map as follows (docs/rendering-model.md):

* diffuse channel kd → ``diffuse`` reflectance; with a specular channel,
  ``roughplastic`` (diffuse_reflectance kd, specular_reflectance ks, Beckmann
  α = √(2/(shininess+2)), the usual Phong-exponent match, interior IOR 1.6 of
  calcite): a physical polished marble, whose highlight is a few percent of the
  light — far dimmer than the paper's Phong highlight (measured side by side in
  docs/rendering-model.md);
* a light of colour I → ``point`` intensity I·π·d², d its distance to the
  camera's look-at point: a Lambertian surface there then receives
  kd·I·cosθ, as in whitted mode, and the 1/d² falloff is physical elsewhere;
  an area light → a ``rectangle`` or ``sphere`` shape with an ``area`` emitter of the
  same radiant intensity towards the look-at point (:func:`area_light_dict`); in
  whitted mode a ``stratified_area`` emitter;
* the global ambient A → a hidden ``constant`` environment of radiance A
  (a Lambertian surface open to the sky reflects kd⊙A: the ambient term with
  kd in place of ka);
* the background colour is not rendered in path mode (misses are black).

Every distinct marble channel becomes one top-level texture referenced by id,
so a marble used for both ambient and diffuse is one texture, evaluated once.
Constant channels are plain ``rgb`` textures: no noise code is generated for them.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

from .. import error_budget
from ..marble_parameters import checked
from ..scene import model
from ..scene.image_header import check_image_maps
from ..scene.rules import cross, spp_problem

MODES = ("whitted", "path")


def texture_dict(channel, tolerance: float | None = None, operand=None) -> dict:
    """The Mitsuba texture of one channel.

    A marble's error budget: ``tolerance`` when given, else the channel's own, else
    the plugin's default (mimarble/error_budget.py). ``operand(channel)`` gives the
    texture of an expression's operand (default: its own ``texture_dict``, inline;
    ``to_mitsuba`` passes references to shared textures).
    """
    if operand is None:
        def operand(inner):
            return texture_dict(inner, tolerance)
    if isinstance(channel, model.ColorChannel):
        # Mitsuba's reflectance colours must lie in [0, 1] unless "unbounded": the language's
        # colours have no upper bound (and Python's may be negative).
        return {"type": "srgb", "color": list(channel.rgb), "unbounded": True}
    if isinstance(channel, model.ImageChannel):
        # Mitsuba's bitmap defaults, said out loud: sRGB → linear, bilinear, repeat.
        return {"type": "bitmap", "filename": channel.location, "raw": False,
                "filter_type": "bilinear", "wrap_mode": "repeat"}
    if isinstance(channel, model.EXPRESSIONS):
        out = {"type": "channel_expression", "op": type(channel).__name__.lower()}
        sides = (channel.a, channel.b) if isinstance(channel, model.Mix) else channel.operands
        out.update({f"operand_{k}": operand(c) for k, c in enumerate(sides)})
        if isinstance(channel, model.Mix):
            weight = channel.weight
            out["weight"] = weight if isinstance(weight, float) else operand(weight)
        return out
    # The plugin takes properties of the very type (as Mitsuba's do); a model built in
    # Python may hold 8.0 octaves or "true": normalised here by the table's text rule,
    # and refused in its words (ValueError) before Mitsuba sees them.
    out = {"type": "marble"}
    out.update({p.name: p.property_value(checked(p, value, text=True))
                for p, value in channel.items()})
    out["tolerance"] = float(next(t for t in (tolerance, channel.tolerance,
                                              error_budget.DEFAULT_TOLERANCE) if t is not None))
    if getattr(channel, "transform", ()):
        # The pattern's transform (mimarble/scene/transforms.py), composed in double
        # precision and rounded once: the plugin's to_world (v = scale·to_world⁻¹·p).
        import mitsuba as mi   # imported here: the module itself stays importable without it
        out["to_world"] = mi.ScalarTransform4f([list(row) for row in channel.to_world])
    return out


def marble_tolerance(scene: model.Scene, channel: model.MarbleChannel,
                     tolerance: float | None = None, gain: float = 1.0) -> float:
    """A marble's error budget in ``scene``: ``tolerance`` when given, else the channel's
    own, else the scene's default, half an 8-bit sRGB code value through its lighting
    (``error_budget.scene_tolerance``), divided by ``gain``, what the expressions it is
    in can multiply its error by (``error_budget.expression_gain``; 1 alone)."""
    if tolerance is not None:
        return tolerance
    if channel.tolerance is not None:
        return channel.tolerance
    return error_budget.scene_tolerance(scene.ambient, [light.color for light in scene.lights]) \
        / max(gain, 1.0)


def _marble_gains(scene: model.Scene) -> dict:
    """Each marble's largest expression gain over the channels it is in."""
    gains: dict = {}
    for material in scene.materials.values():
        for channel in material.channels().values():
            total = error_budget.expression_gain(channel)
            for marble in error_budget.marble_gains(channel):
                gains[marble] = max(gains.get(marble, 1.0), total)
    return gains


# The reference tracer accepts hits from t = 1e-6·(1 + max|eye_k|) on (T_MIN_REL).
_NEAREST_HIT_REL = 1e-6


def clip_planes(scene: model.Scene) -> tuple[float, float]:
    """(near_clip, far_clip) that keep every sphere in view.

    Mitsuba's defaults (0.01, 10 000) drop geometry the scene language allows.
    A sphere of centre c and radius r lies between ||c − e| − r| and |c − e| + r
    of the eye e (inside it too), so: far just past the farthest of these, near
    half the nearest — never below the reference tracer's smallest hit distance,
    so an eye on a surface still sees what the reference sees.

    How ``perspective`` uses them (src/sensors/perspective.cpp): a ray starts on
    the near plane, o = e + d·near/d_z, with maxt = (far − near)/d_z, and its
    direction comes from the inverse projection, which Mitsuba writes down in
    closed form (``Transform::perspective``): a film point maps to
    (x·tan·near, y·tan·near, near), then normalised, so the ratio far/near costs
    no precision however large it is. What float32 does not tolerate is an
    infinite far (> 3.4e38): the inverse's term (near − far)/(far·near) becomes
    inf/inf = NaN and so does every ray. So far is capped at 2¹²⁵ (4.3e37); only
    a sphere beyond Embree's ±1.8e18 (warned about below) gets near it. Near is
    at least 1e-6, far at least 2·near, both normal float32 numbers.
    """
    eye = scene.camera.eye
    if not scene.spheres:
        return 0.01, 1e4   # Mitsuba's defaults: nothing to see either way
    distances = [math.dist(s.center, eye) for s in scene.spheres]
    farthest = max(d + s.radius for d, s in zip(distances, scene.spheres))
    nearest = min(abs(d - s.radius) for d, s in zip(distances, scene.spheres))
    near = max(0.5 * nearest, _NEAREST_HIT_REL * (1.0 + max(map(abs, eye))))
    far = min(max(farthest * (1.0 + 1e-3), 2.0 * near), _FAR_CLIP_MAX)
    return near, far


#: The largest far_clip (see clip_planes): finite in float32 with room to spare.
_FAR_CLIP_MAX = 2.0 ** 125


class Float32RangeWarning(UserWarning):
    """A sphere, eye or light beyond what Mitsuba's float32 (and Embree's) arithmetic reaches."""


# float32's unit roundoff·2: the scale of Mitsuba's intersection error on a sphere is
# 2⁻²³·(max|c_k| + r). Measured (docs/rendering-model.md, "Large spheres"): a ground sphere
# agrees with the reference while that error is up to 1.6× the eye's distance to the
# surface, and fails from 3.2× on; the warning comes from 1×.
_FLOAT32_ERROR_SCALE = 2.0 ** -23

# Embree, Mitsuba's ray tracer in the scalar and LLVM variants, takes coordinates only in
# ±1.844e18 (its FLT_LARGE): a sphere whose bounding box reaches past it is dropped, and a
# ray from beyond it meets nothing (measured: radius 1.8e18 at the origin is hit, 1.85e18
# is not). Warned from 1.8e18.
_EMBREE_LIMIT = 1.8e18

# A point light's weight I/d² is a float32 below 2⁻¹²⁶ (flushed to zero) once d ≥ 2⁶³
# ≈ 9.2e18: the light then lights nothing (measured: 6.1e18 right, 9.8e18 dark). Warned
# from 2⁶² (a light's distance to the farthest point of any sphere).
_LIGHT_DISTANCE_LIMIT = 2.0 ** 62


def _where(scene: model.Scene, node) -> str:
    return f"{scene.source or '<scene>'}:{node.pos or '?'}"


def float32_range_problems(scene: model.Scene) -> list[str]:
    """One message per sphere, eye or light that Mitsuba cannot place precisely enough.

    A sphere whose float32 intersection error reaches the eye's distance to it, or
    which reaches past Embree's coordinate range; an eye past that range; a light so
    far from the spheres that its float32 1/d² underflows.
    """
    problems = []
    eye = scene.camera.eye
    if max(map(abs, eye)) > _EMBREE_LIMIT:
        problems.append(
            f"{_where(scene, scene.camera)}: the eye at {max(map(abs, eye)):g} from the origin is "
            f"beyond ±{_EMBREE_LIMIT:g}, the coordinates Mitsuba's CPU ray tracer (Embree) "
            f"accepts: its rays meet nothing there (docs/rendering-model.md)")
    for sphere in scene.spheres:
        extent = max(map(abs, sphere.center)) + sphere.radius
        error = _FLOAT32_ERROR_SCALE * extent
        distance = abs(math.dist(sphere.center, eye) - sphere.radius)
        if extent > _EMBREE_LIMIT:
            problems.append(
                f"{_where(scene, sphere)}: sphere of radius {sphere.radius:g} reaches "
                f"{extent:g} from the origin, beyond ±{_EMBREE_LIMIT:g}, the coordinates "
                f"Mitsuba's CPU ray tracer (Embree) accepts: Mitsuba drops it "
                f"(docs/rendering-model.md)")
        elif error > distance:
            problems.append(
                f"{_where(scene, sphere)}: sphere of radius {sphere.radius:g} at "
                f"{max(map(abs, sphere.center)):g} from the origin is beyond float32's reach from "
                f"this eye: Mitsuba's intersection error (~{error:.3g}) exceeds the eye's distance "
                f"to its surface ({distance:.3g}), so the Mitsuba image may be wrong there (the "
                f"reference tracer is float64; docs/rendering-model.md)")
    for light in scene.lights:
        farthest = max((math.dist(light.position, s.center) + s.radius for s in scene.spheres),
                       default=0.0)
        if farthest >= _LIGHT_DISTANCE_LIMIT:
            problems.append(
                f"{_where(scene, light)}: light {farthest:.3g} from the farthest sphere point it "
                f"may light: from {2 * _LIGHT_DISTANCE_LIMIT:.3g} on, Mitsuba's float32 point "
                f"light (intensity/distance²) underflows to zero, so it may light nothing there "
                f"(docs/rendering-model.md)")
    return problems


def _sensor(scene: model.Scene, sampler: dict) -> dict:
    import mitsuba as mi   # imported here: the module itself stays importable without it
    cam, img = scene.camera, scene.image
    near, far = clip_planes(scene)
    return {
        "type": "perspective",
        "fov": cam.fov,
        "fov_axis": "y",
        "near_clip": near,
        "far_clip": far,
        "to_world": mi.ScalarTransform4f().look_at(origin=list(cam.eye), target=list(cam.lookat),
                                                   up=list(cam.up)),
        "film": {"type": "hdrfilm", "width": img.width, "height": img.height,
                 "pixel_format": "rgb", "rfilter": {"type": "box"}},
        "sampler": sampler,
    }


def checked_samples(scene: model.Scene, mode: str, spp: int | None) -> int:
    """``spp`` (None: the scene's own) if the image may take it — within the sample limit,
    and n² in whitted mode — else ValueError."""
    spp = scene.image.samples if spp is None else spp
    problem = spp_problem(spp, scene.image.width, scene.image.height)
    if problem:
        raise ValueError(problem)
    if mode == "whitted":
        model.samples_per_axis(spp)
    return spp


def to_mitsuba(scene: model.Scene, mode: str = "whitted", spp: int | None = None,
               tolerance: float | None = None, filter: str | None = None) -> dict:
    """A Mitsuba scene dict for ``scene`` (``mi.load_dict`` it to render).

    ``spp`` overrides the scene's samples per pixel; in whitted mode it must be
    a perfect square (an n×n grid of stratum centres). ``tolerance`` overrides
    every marble's error budget; without it a marble keeps its own, or gets the
    scene's default: half an 8-bit sRGB code value through the scene's lighting
    (``error_budget.scene_tolerance``). ``filter`` overrides every marble's pixel
    filter (``none``, ``bandlimit``, ``prefilter``).
    """
    if not isinstance(scene, model.Scene):
        raise TypeError(f"to_mitsuba: {scene!r:.80} is not a scene model (mimarble.scene.Scene)")
    if tolerance is not None and (isinstance(tolerance, bool)
                                  or not isinstance(tolerance, (int, float))
                                  or not 0 <= tolerance < math.inf):
        raise ValueError(f"tolerance={tolerance!r:.40} must be a finite number ≥ 0")
    if filter is not None and filter not in model.MARBLE_FILTERS:
        raise ValueError(f"filter={filter!r:.40} must be one of {', '.join(model.MARBLE_FILTERS)}")
    if mode not in MODES:
        raise ValueError(f"mode={mode!r:.40} must be one of {', '.join(MODES)}")
    spp = checked_samples(scene, mode, spp)
    check_image_maps(scene)        # the header check of maps the parser never saw
    for problem in float32_range_problems(scene):
        warnings.warn(problem, Float32RangeWarning, stacklevel=2)

    out: dict = {"type": "scene"}
    textures: dict = {}            # channel value -> texture id (dedupes equal channels)

    gains = _marble_gains(scene)

    def ref(channel):
        """A reference to the channel's texture, declared once for equal channels (an
        expression's operands first, so that they are declared before it)."""
        if isinstance(channel, model.ColorChannel):   # a constant: inline, nothing to share
            return texture_dict(channel)
        marble = isinstance(channel, model.MarbleChannel)
        budget = marble_tolerance(scene, channel, tolerance, gains.get(channel, 1.0)) \
            if marble else None
        if marble and filter is not None:
            channel = dataclasses.replace(channel, filter=filter)
        if channel not in textures:
            texture = texture_dict(channel, budget, operand=ref)
            textures[channel] = f"texture_{len(textures)}"
            out[textures[channel]] = texture
        return {"type": "ref", "id": textures[channel]}

    if mode == "whitted":
        out["integrator"] = {"type": "whitted", "ambient": list(scene.ambient),
                             "background": list(scene.image.background)}
        sampler = {"type": "stratified", "sample_count": spp, "jitter": False}
    else:
        out["integrator"] = {"type": "path", "max_depth": 4, "hide_emitters": True}
        sampler = {"type": "independent", "sample_count": spp}
    out["sensor"] = _sensor(scene, sampler)

    materials = {}
    for name, material in scene.materials.items():
        if mode == "whitted":
            bsdf = {"type": "channel_material", "shininess": material.shininess}
            for channel_name, channel in material.channels().items():
                bsdf[channel_name] = ref(channel)
        else:
            bsdf = _path_bsdf(material, ref)
        materials[name] = bsdf

    for k, sphere in enumerate(scene.spheres):
        out[f"sphere_{k}"] = {"type": "sphere", "center": list(sphere.center),
                              "radius": sphere.radius, "bsdf": materials[sphere.material]}

    for k, light in enumerate(scene.lights):
        if light.area is not None:
            out[f"light_{k}"] = area_light_dict(light, scene.camera.lookat, mode)
            continue
        intensity = list(light.color)
        if mode == "path":
            d2 = math.dist(light.position, scene.camera.lookat) ** 2
            intensity = [c * math.pi * d2 for c in light.color]
        out[f"light_{k}"] = {"type": "point", "position": list(light.position),
                             "intensity": {"type": "rgb", "value": intensity}}

    if mode == "path" and any(scene.ambient):
        out["ambient"] = {"type": "constant", "radiance": {"type": "rgb", "value": list(scene.ambient)}}
    return out


def area_light_dict(light: model.Light, lookat, mode: str = "whitted") -> dict:
    """An area light (``light.area``) in Mitsuba's terms.

    ``whitted``: a ``stratified_area`` emitter (area_light.py), its n×n point samples the
    rendering model's (docs/rendering-model.md, "Area lights"); a sphere's disks are
    oriented from the direction to ``lookat``.

    ``path``: Mitsuba's own: a ``rectangle`` (or ``sphere``) shape with an ``area`` emitter
    and a black ``diffuse`` BSDF. Its radiance L is set so that its radiant intensity
    towards the look-at point equals the path-mode point light's, I·π·d² (d the distance
    from the light's centre to ``lookat``), so that there, as for a point light, a
    Lambertian surface receives what whitted mode gives it:

    * sphere of radius R: intensity π·R²·L in every direction, L = I·d²/R²; its total
      power, 4π·(π·R²·L), is the point light's;
    * rectangle of area A = |axis1 × axis2|, one-sided, its normal ±(axis1 × axis2) the
      one facing ``lookat``: intensity A·L·cos θ at θ from its normal, so L = I·π·d²/(A·cos θ₀),
      θ₀ the look-at point's angle (cos θ₀ = 1 when the look-at point lies in its plane). Its
      power, π·A·L, is 1/(4·cos θ₀) of the point light's: it lights one half-space, with a
      cosine.
    """
    area, position = light.area, list(light.position)
    if mode == "whitted":
        out = {"type": "stratified_area", "position": position, "intensity": list(light.color),
               "samples": area.samples}
        if isinstance(area, model.SphereArea):
            out.update(shape="sphere", radius=area.radius, toward=list(lookat))
        else:
            out.update(shape="rectangle", axis1=list(area.axis1), axis2=list(area.axis2))
        return out
    import mitsuba as mi   # imported here: the module itself stays importable without it
    d2 = math.dist(light.position, lookat) ** 2
    black = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}
    if isinstance(area, model.SphereArea):
        radiance = [c * d2 / area.radius ** 2 for c in light.color]
        return {"type": "sphere", "center": position, "radius": area.radius, "bsdf": black,
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": radiance}}}
    axis1, axis2 = list(area.axis1), list(area.axis2)
    normal = list(cross(axis1, axis2))
    if sum(a * (b - c) for a, b, c in zip(normal, lookat, position)) < 0:
        axis1, axis2 = axis2, axis1          # right-handed, the normal facing the look-at
        normal = [-c for c in normal]
    size = math.sqrt(sum(c * c for c in normal))
    facing = sum(a * (b - c) for a, b, c in zip(normal, lookat, position)) / (size * math.sqrt(d2)) \
        if d2 > 0 else 1.0
    facing = facing if facing > 0 else 1.0
    radiance = [c * math.pi * d2 / (size * facing) for c in light.color]
    matrix = [[axis1[i] / 2, axis2[i] / 2, normal[i] / size, position[i]] for i in range(3)]
    return {"type": "rectangle", "to_world": mi.ScalarTransform4f(matrix + [[0, 0, 0, 1]]),
            "bsdf": black,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": radiance}}}


#: Marble is calcite: refractive index 1.49–1.66, so a polished face reflects ~5 % at normal
#: incidence. Path mode renders the specular channel as that dielectric coating
#: (docs/rendering-model.md, "Path mode"), not as the paper's Phong lobe.
CALCITE_IOR = 1.6


def _path_bsdf(material: model.Material, ref) -> dict:
    diffuse = ref(material.diffuse) if material.diffuse is not None else \
        {"type": "rgb", "value": [0.0, 0.0, 0.0]}
    if material.specular is None:
        return {"type": "diffuse", "reflectance": diffuse}
    return {"type": "roughplastic", "distribution": "beckmann",
            "alpha": math.sqrt(2.0 / (material.shininess + 2.0)), "int_ior": CALCITE_IOR,
            "diffuse_reflectance": diffuse, "specular_reflectance": ref(material.specular),
            "nonlinear": True}
