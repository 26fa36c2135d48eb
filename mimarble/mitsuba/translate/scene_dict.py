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
import os
import re
import warnings

import numpy as np

from mimarble.texture import error_budget
from mimarble.parameters import checked
from mimarble.contract import FLOAT32_EPSILON, FLT_MAX, RENDER_MODES, T_MIN_REL, VOLPATH_MAX_DEPTH
from mimarble.scene import geometry, model
from mimarble.scene.errors import SceneError
from mimarble.scene.image_header import check_image_maps
from mimarble.scene.mesh_files import check_mesh_files
from mimarble.scene.rules import cross, shortened, spp_problem

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


# The reference tracer accepts hits from t = T_MIN_REL·(1 + max|eye_k|) on.
_NEAREST_HIT_REL = T_MIN_REL


def _box_distance(point, corners) -> float:
    """The distance from ``point`` to the axis-aligned box around ``corners`` (0 inside)."""
    gaps = [max(min(c[i] for c in corners) - point[i], 0.0, point[i] - max(c[i] for c in corners))
            for i in range(3)]
    return math.sqrt(math.fsum(g * g for g in gaps))


def _shape_reach(scene: model.Scene) -> tuple[list[float], list[float]]:
    """(nearest, farthest): for every shape but the meshes, how near to the eye its surface
    may come and how far from it it reaches (``clip_planes``)."""
    eye = scene.camera.eye
    distances = [math.dist(s.center, eye) for s in scene.spheres]
    nearest = [abs(d - s.radius) for d, s in zip(distances, scene.spheres)]
    farthest = [d + s.radius for d, s in zip(distances, scene.spheres)]
    for plane in scene.planes:
        centre, radius = geometry.plane_disk(scene, plane)
        height = math.dist(centre, eye)       # the disk's centre is the eye's foot on it
        nearest.append(height)
        farthest.append(math.hypot(height, radius))     # its rim
    for box in scene.boxes:
        corners = geometry.box_corners(box)
        nearest.append(_box_distance(eye, corners))
        farthest.append(max(math.dist(c, eye) for c in corners))
    return nearest, farthest


def clip_planes(scene: model.Scene) -> tuple[float, float]:
    """(near_clip, far_clip) that keep every shape in view.

    Mitsuba's defaults (0.01, 10 000) drop geometry the scene language allows.
    A sphere of centre c and radius r lies between ||c − e| − r| and |c − e| + r
    of the eye e (inside it too); a plane, rendered as a disk of radius R around the
    eye's foot on it (``geometry.plane_disk``), between the eye's height h above it and
    √(h² + R²), its rim; a box between the eye's distance to its world bounding box (0
    inside) and its farthest corner. So: far just past the farthest of these, near half
    the nearest — never below the reference tracer's smallest hit distance, so an eye on
    a surface still sees what the reference sees. A mesh's vertices are in its file, not
    known before Mitsuba loads it: a scene with meshes gets that floor as its near and
    the cap below as its far (which costs nothing, see next).

    How ``perspective`` uses them (src/sensors/perspective.cpp): a ray starts on
    the near plane, o = e + d·near/d_z, with maxt = (far − near)/d_z, and its
    direction comes from the inverse projection, which Mitsuba writes down in
    closed form (``Transform::perspective``): a film point maps to
    (x·tan·near, y·tan·near, near), then normalised, so the ratio far/near costs
    no precision however large it is. What float32 does not tolerate is an
    infinite far (> 3.4e38): the inverse's term (near − far)/(far·near) becomes
    inf/inf = NaN and so does every ray. So far is capped at 2¹²⁵ (4.3e37); only
    a shape beyond Embree's ±1.8e18 (warned about below) gets near it. Near is
    at least 1e-6, far at least 2·near, both normal float32 numbers.
    """
    eye = scene.camera.eye
    if not scene.shapes():
        return 0.01, 1e4   # Mitsuba's defaults: nothing to see either way
    floor = _NEAREST_HIT_REL * (1.0 + max(map(abs, eye)))
    if scene.meshes:
        return floor, _FAR_CLIP_MAX
    nearest, farthest = _shape_reach(scene)
    near = max(0.5 * min(nearest), floor)
    far = min(max(max(farthest) * (1.0 + 1e-3), 2.0 * near), _FAR_CLIP_MAX)
    return near, far


#: The largest far_clip (see clip_planes): finite in float32 with room to spare.
_FAR_CLIP_MAX = 2.0 ** 125


class Float32RangeWarning(UserWarning):
    """A shape, eye or light beyond what Mitsuba's float32 (and Embree's) arithmetic reaches."""


# float32's unit roundoff·2: the scale of Mitsuba's intersection error on a sphere is
# 2⁻²³·(max|c_k| + r). Measured (docs/rendering-model.md, "Large spheres"): a ground sphere
# agrees with the reference while that error is up to 1.6× the eye's distance to the
# surface, and fails from 3.2× on; the warning comes from 1×.
_FLOAT32_ERROR_SCALE = FLOAT32_EPSILON

# Embree, Mitsuba's ray tracer in the scalar and LLVM variants, takes coordinates only in
# ±1.844e18 (its FLT_LARGE): a sphere whose bounding box reaches past it is dropped, and a
# ray from beyond it meets nothing (measured: radius 1.8e18 at the origin is hit, 1.85e18
# is not). Warned from 1.8e18.
_EMBREE_LIMIT = 1.8e18

# A point light's weight I/d² is a float32 below 2⁻¹²⁶ (flushed to zero) once d ≥ 2⁶³
# ≈ 9.2e18: the light then lights nothing (measured: 6.1e18 right, 9.8e18 dark). Warned
# from 2⁶² (a light's distance to the farthest point of any sphere).
_LIGHT_DISTANCE_LIMIT = 2.0 ** 62


# A triangle's normal is normalize(e₁ × e₂) in float32: its squared length overflows once
# |e₁ × e₂| (twice the triangle's area) reaches √FLT_MAX ≈ 1.8e19, and the normal is 0.
_FACE_LIMIT = 2.0 ** 64


def _where(scene: model.Scene, node) -> str:
    return f"{scene.source or '<scene>'}:{node.pos or '?'}"


def _reach_problem(where: str, what: str, extent: float, placed: float, error: float,
                   distance: float | None) -> str | None:
    """The message of one shape (``what``) reaching ``extent`` from the origin (its
    coordinates' largest magnitude ``placed``), whose float32 placement error ``error``
    may reach the eye's distance to it (None: not checked): Embree's range first."""
    if extent > _EMBREE_LIMIT:
        return (f"{where}: {what} reaches {extent:g} from the origin, beyond ±{_EMBREE_LIMIT:g}, "
                f"the coordinates Mitsuba's CPU ray tracer (Embree) accepts: Mitsuba drops it "
                f"(docs/rendering-model.md)")
    if distance is not None and error > distance:
        return (f"{where}: {what} at {placed:g} from the origin is beyond float32's reach from "
                f"this eye: Mitsuba's intersection error (~{error:.3g}) exceeds the eye's distance "
                f"to its surface ({distance:.3g}), so the Mitsuba image may be wrong there (the "
                f"reference tracer is float64; docs/rendering-model.md)")
    return None


def _largest(v) -> float:
    return max(map(abs, v))


def float32_range_problems(scene: model.Scene) -> list[str]:
    """One message per shape, eye or light that Mitsuba cannot place precisely enough.

    A shape which reaches past Embree's coordinate range — a sphere, a plane's disk
    (``geometry.plane_disk``), a box's corners, a mesh's (the world corners of its file's
    bounds, ``geometry.mesh_corners``) — or whose float32 intersection error reaches the
    eye's distance to it: a sphere's, 2⁻²³·(max|c_k| + r); a plane's, 2⁻²³·max|c_k| of its
    disk's centre c (where Mitsuba's float32 numbers put the plane), against the eye's
    height above it; a box's or a mesh's, 2⁻²³ times its largest corner coordinate,
    against the eye's distance to the axis-aligned box around those corners (a lower
    bound of its distance to the surface; not checked from inside it), or a box whose
    faces are so large that Mitsuba's float32 normal of them overflows; an eye past that
    range; a light so far from the shapes that its float32 1/d² underflows.
    """
    problems = []
    eye = scene.camera.eye
    if _largest(eye) > _EMBREE_LIMIT:
        problems.append(
            f"{_where(scene, scene.camera)}: the eye at {_largest(eye):g} from the origin is "
            f"beyond ±{_EMBREE_LIMIT:g}, the coordinates Mitsuba's CPU ray tracer (Embree) "
            f"accepts: its rays meet nothing there (docs/rendering-model.md)")
    lit = []        # (point, radius) around which each shape lies, for the lights' check
    for sphere in scene.spheres:
        extent = _largest(sphere.center) + sphere.radius
        problems.append(_reach_problem(
            _where(scene, sphere), f"sphere of radius {sphere.radius:g}", extent,
            _largest(sphere.center), _FLOAT32_ERROR_SCALE * extent,
            abs(math.dist(sphere.center, eye) - sphere.radius)))
        lit.append((sphere.center, sphere.radius))
    for plane in scene.planes:
        centre, radius = geometry.plane_disk(scene, plane)
        problems.append(_reach_problem(
            _where(scene, plane), f"plane (rendered as a disk of radius {radius:.3g})",
            _largest(centre) + radius, _largest(centre), _FLOAT32_ERROR_SCALE * _largest(centre),
            math.dist(centre, eye)))
        lit.append((centre, 0.0))
    for shape in scene.boxes + scene.meshes:
        box = type(shape) is model.Box
        corners = geometry.box_corners(shape) if box else geometry.mesh_corners(shape)
        if corners is None:                 # a mesh file unread: its transform's origin
            corners = [geometry.sphere_bounds(shape)[0]]
        extent = max(map(_largest, corners))
        distance = _box_distance(eye, corners) if len(corners) == 8 else 0.0
        problems.append(_reach_problem(_where(scene, shape), "box" if box else "mesh", extent,
                                       extent, _FLOAT32_ERROR_SCALE * extent,
                                       distance if distance > 0 else None))
        lit += [(corner, 0.0) for corner in corners]
        if not box:
            continue
        edges = [[a - b for a, b in zip(corners[k], corners[0])] for k in (4, 2, 1)]  # x, y, z
        face = max(math.sqrt(sum(c * c for c in cross(edges[k], edges[k - 1])))
                   for k in range(3))
        if face >= _FACE_LIMIT:
            problems.append(
                f"{_where(scene, shape)}: box with a face of {face:.3g} square units: Mitsuba's "
                f"float32 face normal (the cross product of two edges, normalised through its "
                f"square) overflows from {_FACE_LIMIT:.3g}, so that face is shaded black "
                f"(docs/rendering-model.md)")
    problems = [problem for problem in problems if problem]
    for light in scene.lights:
        farthest = max((math.dist(light.position, c) + r for c, r in lit), default=0.0)
        if farthest >= _LIGHT_DISTANCE_LIMIT:
            problems.append(
                f"{_where(scene, light)}: light {farthest:.3g} from the farthest shape point it "
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
        if mode == "path" and not isinstance(shape, model.Sphere) and subsurface is None:
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


in_object_space = model.in_object_space


def _product(a, b):
    """The 4×4 product a·b, in double precision (rows)."""
    return (np.asarray(a, dtype=np.float64) @ np.asarray(b, dtype=np.float64)).tolist()


def _transform(matrix):
    """A double-precision 4×4 (rows) as Mitsuba's transform: its entries rounded once to
    float32, and their inverse computed in double precision and rounded once — as Mitsuba's
    XML parser makes a ``<matrix>`` (src/core/parser.cpp), so an exported scene renders
    bit for bit as this dict (mimarble/tools/export.py), and a disk R wide, whose float32
    determinant R² would be far off, keeps an exact inverse."""
    import mitsuba as mi   # imported here: the module itself stays importable without it
    single = mi.ScalarMatrix4f([list(map(float, row)) for row in matrix])
    inverse = mi.ScalarTransform4d(mi.ScalarMatrix4d(single)).inverse_transpose
    return mi.ScalarTransform4f(single, mi.ScalarMatrix4f(inverse))


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


def disk_to_world(scene: model.Scene, plane: model.Plane):
    """The ``to_world`` (4×4 rows, double precision) of the Mitsuba ``disk`` that renders
    ``plane``: the unit disk (z = 0, normal +z) scaled by the radius R in its plane and
    centred as ``geometry.plane_disk`` says, its x, y, z axes the plane frame's
    bitangent, tangent and normal (``geometry.plane_frame``; right-handed, as bitangent ×
    tangent = normal). The normal is not scaled: Mitsuba inverts the matrix in float32,
    through its determinant, R² here (R³ would overflow from R ≈ 7·10¹², a scene's extent
    of 7·10⁸), and local z is then the height above the plane in world units."""
    centre, radius = geometry.plane_disk(scene, plane)
    tangent, normal, bitangent = geometry.plane_frame(plane.normal)
    return [[radius * bitangent[i], radius * tangent[i], normal[i], centre[i]]
            for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def cube_to_world(box: model.Box):
    """The ``to_world`` (4×4 rows, double precision) of the Mitsuba ``cube`` ([−1, 1]³)
    that renders ``box``: its transform · translate(centre) · scale(half extents)."""
    centre = [(lo + hi) / 2 for lo, hi in zip(box.min, box.max)]
    half = [(hi - lo) / 2 for lo, hi in zip(box.min, box.max)]
    placed = [[half[i] if j == i else 0.0 for j in range(3)] + [centre[i]] for i in range(3)]
    return _product(geometry.object_to_world(box), placed + [[0.0, 0.0, 0.0, 1.0]])


def shape_dict(scene: model.Scene, shape) -> dict:
    """The Mitsuba shape (without its BSDF) of one shape of ``scene``.

    * sphere → ``sphere`` (centre, radius);
    * plane → ``disk``, an analytic shape (its hit is the ray's, at the t where it meets
      the plane, accurate at any radius; ``rectangle`` is a two-triangle mesh whose hit is
      re-interpolated from its corners, ulp(R) off at radius R), placed by
      :func:`disk_to_world`;
    * box → ``cube``, a mesh of 12 triangles, placed by :func:`cube_to_world`;
    * mesh → ``ply`` or ``obj`` (by the file's ending), placed by its transform, with
      ``face_normals`` (flat shading, as the reference) and ``flip_tex_coords`` said out
      loud at Mitsuba's defaults (OBJ: v → 1 − v, so that an OBJ's v = 0 is an image's
      bottom row; PLY: as written). Mitsuba's loaders change nothing else: positions are
      the file's through ``to_world`` (rounded to float32), faces as given.
    """
    if isinstance(shape, model.Sphere):
        return {"type": "sphere", "center": list(shape.center), "radius": shape.radius}
    if isinstance(shape, model.Plane):
        return {"type": "disk", "to_world": _transform(disk_to_world(scene, shape))}
    if isinstance(shape, model.Box):
        return {"type": "cube", "to_world": _transform(cube_to_world(shape))}
    kind = os.path.splitext(shape.file)[1].lower()[1:]
    return {"type": kind, "filename": shape.location,
            "to_world": _transform(geometry.object_to_world(shape)), "face_normals": True,
            "flip_tex_coords": kind == "obj"}


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


def _facing_out(shape_out: dict, shape) -> None:
    """A translucent box's or mesh's normals facing out of it under a transform that
    mirrors (det < 0). Mitsuba enters a shape's ``interior`` when a ray crosses against its
    geometric normal, the cross product of a triangle's edges — which a mirror turns
    inwards: the medium would be outside. A mesh (flat, ``face_normals``) then gets
    ``flip_normals``; a box, whose ``cube`` carries vertex normals that the inverse
    transpose keeps outward, gets its cube mirrored back, to_world·diag(−1, 1, 1), the
    same points ([−1, 1]³ is symmetric) with det > 0. A sphere's and a plane's disk's
    normals face out (and up) whatever their placement."""
    if isinstance(shape, (model.Box, model.Mesh)) \
            and np.linalg.det(np.asarray(geometry.object_to_world(shape), dtype=np.float64)) < 0:
        if isinstance(shape, model.Box):
            mirror = [[-1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0],
                      [0.0, 0.0, 0.0, 1.0]]
            shape_out["to_world"] = _transform(_product(cube_to_world(shape), mirror))
        else:
            shape_out["flip_normals"] = True


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
