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
so a marble used for both ambient and diffuse is one texture, evaluated once; a
channel that is one of the file's named textures (``Scene.textures``) has its name
as the id (made a valid one: ``white_veins``), the others ``texture_0``, ….
Constant channels are plain ``rgb`` textures: no noise code is generated for them.

Shapes (:func:`shape_dict`): a sphere → ``sphere``, a plane → ``disk`` (the disk it is
rendered as, ``geometry.plane_disk``), a box → ``cube``, a mesh → ``ply``/``obj``, each
under the id ``Scene.shapes()`` gives it. A material whose channels hold a ``space
object`` marble becomes one BSDF per shape, its object-space textures placed by the
shape's object space (``to_world`` = S·M, v = scale·(S·M)⁻¹·p); in path mode planes,
boxes and meshes get their BSDF wrapped in ``twosided`` (docs/rendering-model.md,
"Planes, boxes and meshes"; docs/mitsuba-scene.md).

A material with a ``subsurface`` (:func:`translucent_materials`) is translucent: whitted mode
refuses it (:class:`ModeError`, at its ``subsurface`` keyword); path mode renders it under
``volpath`` (max_depth :data:`VOLPATH_MAX_DEPTH`) as a smooth ``dielectric`` boundary
around a ``marble_medium`` interior on every shape that uses it,
its surface channels unused (docs/rendering-model.md, "Translucent materials").
"""

from __future__ import annotations

import dataclasses
import math
import re
import warnings

from mimarble.texture import error_budget
from mimarble.parameters import checked
from mimarble.contract import FLT_MAX, RENDER_MODES, VOLPATH_MAX_DEPTH
from mimarble.scene import geometry, model
from mimarble.scene.errors import SceneError
from mimarble.scene.image_header import check_image_maps
from mimarble.scene.mesh_files import check_mesh_files
from mimarble.scene.rules import cross, shortened, spp_problem
# Each kind of shape as Mitsuba sees it (shapes.py); the names stay importable from here.
from .shapes import (_EMBREE_LIMIT, _FACE_LIMIT, _FAR_CLIP_MAX, _LIGHT_DISTANCE_LIMIT,  # noqa: F401
                     _NEAREST_HIT_REL, Float32RangeWarning, _box_distance, _facing_out, _largest,
                     _product, _reach_problem, _shape_reach, _transform, _where, clip_planes,
                     cube_to_world, disk_to_world, float32_range_problems, in_object_space,
                     is_two_sided, shape_dict)

MODES = RENDER_MODES
#: The keys ``mi.load_dict`` reads as a dict's own — its plugin type and its id — never as
#: a child (a texture under the key ``id`` became the scene's id: "std::bad_cast"). No
#: top-level entry takes one: a named texture called ``id`` gets the id ``id_2``.
LOAD_DICT_KEYS = ("type", "id")



class ModeError(SceneError, ValueError):
    """A scene that the mode asked cannot render (a translucent material in whitted mode),
    in one sentence at the node's FILE:LINE:COL: a SceneError (the command line prints it,
    exit status 2, no traceback) that is a ValueError to Python."""

    def __reduce__(self):
        return (_mode_error, (self.message, self.filename, self.line, self.column,
                              self.source_line))


def _mode_error(message, filename, line, column, source_line):
    return ModeError(message, filename=filename, line=line, column=column,
                     source_line=source_line)


def texture_dict(channel, tolerance: float | None = None, operand=None) -> dict:
    """The Mitsuba texture of one channel.

    A marble's error budget: ``tolerance`` when given, else the channel's own, else
    the plugin's default (mimarble/texture/error_budget.py). ``operand(channel)`` gives the
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
        volume = material.subsurface.channels() if material.subsurface is not None else {}
        for channel in (*material.channels().values(), *volume.values()):
            total = error_budget.expression_gain(channel)
            for marble in error_budget.marble_gains(channel):
                gains[marble] = max(gains.get(marble, 1.0), total)
    return gains


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
    translucent = translucent_materials(scene)
    if mode == "whitted" and translucent:
        material = translucent[0]
        raise ModeError.in_file(
            scene.source, material.subsurface.pos,
            f"material \"{shortened(material.name)}\" has a subsurface, a "
            f"scattering volume that whitted mode (the paper's surface shading) cannot render: "
            f"render the scene with --mode path (mode=\"path\")")
    check_image_maps(scene)        # the header check of maps the parser never saw
    uv_problems = check_mesh_files(scene)      # and of mesh files, as the parser checks them
    for problem in float32_range_problems(scene) + uv_problems:
        warnings.warn(problem, Float32RangeWarning, stacklevel=2)

    out: dict = {"type": "scene"}
    # (channel value, its shape's object-to-world for a channel with an object-space
    # marble, else None) -> texture id: equal channels are one texture.
    textures: dict = {}
    bases: dict = {}        # channel value -> its texture's id (placed: id_SHAPE)
    # Top-level ids, so that a named texture's id (Scene.textures) takes none of them.
    taken = set(LOAD_DICT_KEYS) | {"integrator", "sensor", "ambient"} \
        | {i for i, _ in scene.shapes()} \
        | {f"light_{k}" for k in range(len(scene.lights))}
    names: dict = {}
    for name, channel in scene.textures.items():
        names.setdefault(channel, name)

    gains = _marble_gains(scene)

    def ref(channel, placement=None):
        """A reference to the channel's texture, declared once for equal channels (an
        expression's operands first, so that they are declared before it). ``placement``:
        ``(shape id, object-to-world)`` of the shape it shades, which places the channel's
        object-space marbles (a channel without one ignores it, and stays shared)."""
        if isinstance(channel, model.ColorChannel):   # a constant: inline, nothing to share
            return texture_dict(channel)
        placement = placement if placement is not None and in_object_space(channel) else None
        named = names.get(channel)
        marble = isinstance(channel, model.MarbleChannel)
        budget = marble_tolerance(scene, channel, tolerance, gains.get(channel, 1.0)) \
            if marble else None
        if marble and filter is not None:
            channel = dataclasses.replace(channel, filter=filter)
        key = (channel, None if placement is None else placement[1])
        if key not in textures:
            texture = texture_dict(channel, budget, operand=lambda inner: ref(inner, placement))
            if placement is not None and marble:
                # v = scale·(S·M)⁻¹·p: the shape's object space S, then the pattern's own M.
                texture["to_world"] = _transform(_product(placement[1], channel.to_world))
            if channel not in bases:      # one name for the channel, placed or not
                bases[channel] = _unused(_texture_id(named) if named is not None
                                         else f"texture_{len(bases)}", taken)
            textures[key] = bases[channel] if placement is None else \
                _unused(f"{bases[channel]}_{placement[0]}", taken)
            out[textures[key]] = texture
        return {"type": "ref", "id": textures[key]}

    if mode == "whitted":
        out["integrator"] = {"type": "whitted", "ambient": list(scene.ambient),
                             "background": list(scene.image.background)}
        sampler = {"type": "stratified", "sample_count": spp, "jitter": False}
    elif translucent:              # light scattered inside media: docs/rendering-model.md
        out["integrator"] = {"type": "volpath", "max_depth": VOLPATH_MAX_DEPTH,
                             "hide_emitters": True}
        sampler = {"type": "independent", "sample_count": spp}
    else:
        out["integrator"] = {"type": "path", "max_depth": 4, "hide_emitters": True}
        sampler = {"type": "independent", "sample_count": spp}
    out["sensor"] = _sensor(scene, sampler)

    bsdfs: dict = {}       # (material name, placement's matrix or None) -> its BSDF

    def bsdf_of(name, placement=None):
        """The material's BSDF: one for every shape that uses it, or with object-space
        marbles one per placement (``placement`` as for ``ref``)."""
        material = scene.materials[name]
        if not any(in_object_space(c) for c in material.channels().values()):
            placement = None
        key = (name, None if placement is None else placement[1])
        if key not in bsdfs:
            if mode == "path" and material.subsurface is not None:
                bsdf = subsurface_boundary(material.subsurface)   # its channels: unused
            elif mode == "whitted":
                bsdf = {"type": "channel_material", "shininess": material.shininess}
                for channel_name, channel in material.channels().items():
                    bsdf[channel_name] = ref(channel, placement)
            else:
                bsdf = _path_bsdf(material, lambda channel: ref(channel, placement))
            bsdfs[key] = bsdf
        return bsdfs[key]

    for name, material in scene.materials.items():   # their textures, in the file's order
        if not any(in_object_space(c) for c in material.channels().values()):
            bsdf_of(name)                 # (object-space ones: per shape, below)

    media: dict = {}       # (material name, placement's matrix or None) -> its medium

    def medium_of(name, placement):
        """The interior of the material's shapes: one medium, or with object-space
        marbles in its subsurface one per placement (``placement`` as for ``ref``)."""
        subsurface = scene.materials[name].subsurface
        if not any(in_object_space(c) for c in subsurface.channels().values()):
            placement = None
        key = (name, None if placement is None else placement[1])
        if key not in media:
            media[key] = medium_dict(scene, subsurface, lambda channel: ref(channel, placement))
        return media[key]

    two_sided: dict = {}       # id of a path BSDF -> the one twosided wrapper of it
    for shape_id, shape in scene.shapes():
        placement = (shape_id, geometry.object_to_world(shape))
        bsdf = bsdf_of(shape.material, placement)
        subsurface = scene.materials[shape.material].subsurface
        if mode == "path" and is_two_sided(shape) and subsurface is None:
            # Mitsuba's BSDFs reflect on the side their normal points to; planes, boxes
            # and meshes are shaded on either side (whitted flips n to the viewer). A
            # dielectric boundary is two-sided itself (and twosided refuses transmission).
            bsdf = two_sided.setdefault(id(bsdf), {"type": "twosided", "bsdf": bsdf})
        # Its medium's textures first: a reference follows what it refers to.
        interior = medium_of(shape.material, placement) \
            if mode == "path" and subsurface is not None else None
        out[shape_id] = shape_dict(scene, shape)
        out[shape_id]["bsdf"] = bsdf
        if interior is not None:
            out[shape_id]["interior"] = interior
            _facing_out(out[shape_id], shape)

    for k, light in enumerate(scene.lights):
        if light.area is not None:
            out[f"light_{k}"] = area_light_dict(light, scene.camera.lookat, mode)
            continue
        out[f"light_{k}"] = point_light_dict(light, scene.camera.lookat, mode)

    if mode == "path" and any(scene.ambient):
        out["ambient"] = {"type": "constant", "radiance": {"type": "rgb", "value": list(scene.ambient)}}
    return out


def _texture_id(name: str) -> str:
    """A named texture's id: its name with every run of characters other than ASCII
    letters, digits and ``_`` made one ``_`` (``"white veins"`` → ``white_veins``), at
    most 64 characters, starting with a letter (else after ``texture_``)."""
    text = re.sub(r"[^A-Za-z0-9_]+", "_", name).strip("_")[:64]
    return text if text[:1].isalpha() else f"texture_{text}".rstrip("_")


def _unused(candidate: str, taken: set) -> str:
    """``candidate``, or ``candidate_2``, ``_3``, … the first not in ``taken`` (then taken)."""
    found, k = candidate, 2
    while found in taken:
        found, k = f"{candidate}_{k}", k + 1
    taken.add(found)
    return found


def point_light_dict(light: model.Light, lookat, mode: str = "whitted") -> dict:
    """A light as Mitsuba's ``point`` emitter at its position: intensity I (whitted mode:
    the paper's unattenuated light), or in path mode I·π·d², d its distance to ``lookat``,
    so that a Lambertian surface there receives kd·I·cos θ, as in whitted mode."""
    intensity = list(light.color)
    if mode == "path":
        d2 = math.dist(light.position, lookat) ** 2
        intensity = [c * math.pi * d2 for c in light.color]
    return {"type": "point", "position": list(light.position),
            "intensity": {"type": "rgb", "value": intensity}}


#: Path mode: a spherical area light whose radius is below this fraction of its distance
#: d to the look-at point is Mitsuba's ``point`` emitter of the same intensity. Mitsuba's
#: ``sphere`` samples the cone it subtends, with the pdf 1/(2π(1 − cos θ_max)) computed in
#: float32, whose relative error is about 2⁻²⁵/sin²θ_max: at 2⁻⁷ of d it is 2⁻¹¹ at the
#: look-at point; below it the light's penumbra is under 1 % of the distance, and a point
#: light (what whitted mode and the reference make of it) is the closer image. Measurements:
#: docs/rendering-model.md, "Tiny area lights in path mode".
AREA_LIGHT_POINT_SIZE = 2.0 ** -7

#: Path mode: a rectangular area light's edges are each at least this times max(d, 1)
#: long (d as above), lengthened along themselves where shorter, its radiance set from the
#: lengthened area (its power kept). Mitsuba's float32 ``rectangle`` lights nothing once the
#: squared cross product of its half-edges leaves float32's normal range, whatever its
#: distance. At 2⁻¹⁶ (even with the least angle between the edges that the language allows,
#: 1e-6 rad) the area is at least 2⁻³²·1e-6 ≈ 2.3e-16, and an edge so lengthened is 1.5e-5
#: of the distance. Measurements: docs/rendering-model.md, "Tiny area lights in path mode".
RECTANGLE_LIGHT_SHORTEST_EDGE = 2.0 ** -16


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

    What Mitsuba's float32 cannot render is translated to what it can, the power kept: a
    sphere of radius below :data:`AREA_LIGHT_POINT_SIZE`·d is the path-mode point light
    (:func:`point_light_dict`); a rectangle's edges are at least
    :data:`RECTANGLE_LIGHT_SHORTEST_EDGE`·max(d, 1) long.
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
    if isinstance(area, model.SphereArea) and area.radius < AREA_LIGHT_POINT_SIZE * math.sqrt(d2):
        return point_light_dict(light, lookat, mode)
    if isinstance(area, model.SphereArea):
        radiance = [c * d2 / area.radius ** 2 for c in light.color]
        return {"type": "sphere", "center": position, "radius": area.radius, "bsdf": black,
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": radiance}}}
    shortest = RECTANGLE_LIGHT_SHORTEST_EDGE * max(math.sqrt(d2), 1.0)
    axis1, axis2 = ([c * max(1.0, shortest / math.hypot(*axis)) for c in axis]
                    for axis in (area.axis1, area.axis2))
    normal = list(cross(axis1, axis2))
    if sum(a * (b - c) for a, b, c in zip(normal, lookat, position)) < 0:
        axis1, axis2 = axis2, axis1          # right-handed, the normal facing the look-at
        normal = [-c for c in normal]
    size = math.hypot(*normal)
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


def translucent_materials(scene: model.Scene) -> tuple:
    """The materials with a subsurface that some shape of ``scene`` uses, in file order:
    a scene with one renders in path mode only, under ``volpath`` (a material no shape
    uses changes no image, and is not asked about)."""
    used = {shape.material for _, shape in scene.shapes()}
    return tuple(m for m in scene.materials.values() if m.subsurface is not None and m.name in used)


def subsurface_boundary(subsurface: model.Subsurface) -> dict:
    """The BSDF of a translucent material's surface: a smooth ``dielectric`` of relative
    index ``ior`` (int_ior = ior, ext_ior = 1; it reflects and refracts by Fresnel's
    equations, and is two-sided) — at ior 1 too, where it bends and reflects nothing: a
    ``null`` BSDF would let point lights in, but volpath would then neither count the
    crossing as a vertex nor show the sky through it to camera rays (hide_emitters), unlike
    every other ior and the reference random walk (docs/rendering-model.md, "Translucent
    materials")."""
    return {"type": "dielectric", "int_ior": subsurface.ior, "ext_ior": 1.0}


def medium_dict(scene: model.Scene, subsurface: model.Subsurface, ref=None) -> dict:
    """The ``marble_medium`` (mimarble/mitsuba/plugins/marble_medium.py) of a subsurface: the
    textures of its albedo and density channels (``ref(channel)``: a texture or a reference
    to one; default: :func:`texture_dict`), ``scale`` = 1/mean_free_path, so that
    σ_t(p) = scale·d(p), and ``density_bound`` ≥ every d(p) (the majorant is
    scale·density_bound): ``error_budget.mean_bound`` of the density channel (d is the mean
    of its components, at least 0), 1 without one (d = 1). Behind the smooth dielectric
    no shadow ray from inside can reach an emitter, so the medium samples none
    (``sample_emitters`` false: the paths that leave find them; unbiased, and up to half the
    render time saved). A majorant past
    float32's range is refused (ModeError at the ``subsurface`` keyword): Mitsuba's
    arithmetic is single precision."""
    ref = texture_dict if ref is None else ref
    density = subsurface.density
    scale = 1.0 / subsurface.mean_free_path
    bound = 1.0 if density is None else max(0.0, error_budget.mean_bound(density))
    if not scale * bound <= FLT_MAX:
        raise ModeError.in_file(
            scene.source, subsurface.pos,
            f"mean_free_path {subsurface.mean_free_path:g} with a density up to {bound:g} is "
            f"an extinction of up to {scale * bound!r} per scene unit, past float32's "
            f"{FLT_MAX!r}, the most Mitsuba's single precision holds")
    out = {"type": "marble_medium", "albedo": ref(subsurface.albedo)}
    if density is not None:
        out["density"] = ref(density)
    out.update(scale=scale, density_bound=bound, sample_emitters=False)
    return out
