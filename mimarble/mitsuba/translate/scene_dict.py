"""Scene model → Mitsuba scene dict (:func:`to_mitsuba`), in its modes (modes.py): the
sensor, then the channels' textures (textures.py), the materials' BSDFs (materials.py),
the shapes (shapes.py) with a translucent material's medium (media.py), the lights
(lights.py).

What code, tests and docs imported from this module before it was split is importable
from it still: ``__all__``, and the private ``_sensor`` (here) and ``mitsuba_transform``.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

from mimarble.contract import VOLPATH_MAX_DEPTH
from mimarble.scene import geometry, model
from mimarble.scene.albedo_grid import medium_holders
from mimarble.scene.environment_header import check_environment
from mimarble.scene.image_header import check_image_maps
from mimarble.scene.mesh_files import check_mesh_files
from mimarble.scene.rules import spp_problem

from .float32_range import Float32RangeWarning, float32_range_problems
from .lights import (AREA_LIGHT_POINT_SIZE, RECTANGLE_LIGHT_SHORTEST_EDGE, ambient_dict,
                     area_light_dict, environment_dict, point_light_dict)
from .materials import CALCITE_IOR, surface_bsdf
from .media import (constant_sky_weight, medium_dict, subsurface_boundary,
                    translucent_materials)
from .modes import MODES, ModeError, integrator_and_sampler, refuse_translucent
from .shapes import (facing_out, matrix_product, mitsuba_transform, clip_planes, cube_to_world,
                     is_smooth, disk_to_world, in_object_space, is_two_sided, shape_dict)
from .textures import (scene_marble_gains, named_texture_id, unused_texture, marble_tolerance,
                       texture_dict)

__all__ = ["AREA_LIGHT_POINT_SIZE", "CALCITE_IOR", "Float32RangeWarning", "LOAD_DICT_KEYS",
           "MODES", "ModeError", "RECTANGLE_LIGHT_SHORTEST_EDGE", "VOLPATH_MAX_DEPTH",
           "area_light_dict", "checked_samples", "clip_planes", "cube_to_world",
           "disk_to_world", "float32_range_problems", "marble_tolerance", "medium_dict",
           "point_light_dict", "shape_dict", "subsurface_boundary", "texture_dict",
           "to_mitsuba", "translucent_materials"]

#: The keys ``mi.load_dict`` reads as a dict's own — its plugin type and its id — never as
#: a child (a texture under the key ``id`` became the scene's id: "std::bad_cast"). No
#: top-level entry takes one: a named texture called ``id`` gets the id ``id_2``.
LOAD_DICT_KEYS = ("type", "id")


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
    refuse_translucent(scene, mode, translucent)
    check_image_maps(scene)        # the header check of maps the parser never saw
    check_environment(scene)       # and of an environment's file
    uv_problems = check_mesh_files(scene)      # and of mesh files, as the parser checks them
    for problem in float32_range_problems(scene) + uv_problems:
        warnings.warn(problem, Float32RangeWarning, stacklevel=2)

    out: dict = {"type": "scene"}
    # (channel value, its shape's object-to-world for a channel with an object-space
    # marble, else None) -> texture id: equal channels are one texture.
    textures: dict = {}
    bases: dict = {}        # channel value -> its texture's id (placed: id_SHAPE)
    # Top-level ids, so that a named texture's id (Scene.textures) takes none of them.
    taken = set(LOAD_DICT_KEYS) | {"integrator", "sensor", "ambient", "environment"} \
        | {i for i, _ in scene.shapes()} \
        | {f"light_{k}" for k in range(len(scene.lights))}
    names: dict = {}
    for name, channel in scene.textures.items():
        names.setdefault(channel, name)

    gains = scene_marble_gains(scene)

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
                texture["to_world"] = mitsuba_transform(matrix_product(placement[1], channel.to_world))
            if channel not in bases:      # one name for the channel, placed or not
                bases[channel] = unused_texture(named_texture_id(named) if named is not None
                                         else f"texture_{len(bases)}", taken)
            textures[key] = bases[channel] if placement is None else \
                unused_texture(f"{bases[channel]}_{placement[0]}", taken)
            out[textures[key]] = texture
        return {"type": "ref", "id": textures[key]}

    out["integrator"], sampler = integrator_and_sampler(
        scene, mode, spp, translucent, smooth=any(map(is_smooth, scene.meshes)))
    out["sensor"] = _sensor(scene, sampler)

    bsdfs: dict = {}       # (material name, placement's matrix or None) -> its BSDF

    def placed(material) -> bool:
        """Whether some channel the material's BSDF reads is in object space: its
        surface channels', and in preview mode its subsurface's too."""
        channels = list(material.channels().values())
        if mode == "preview" and material.subsurface is not None:
            channels += material.subsurface.channels().values()
        return any(in_object_space(c) for c in channels)

    def bsdf_of(name, placement=None):
        """The material's BSDF: one for every shape that uses it, or with object-space
        marbles one per placement (``placement`` as for ``ref``)."""
        material = scene.materials[name]
        if not placed(material):
            placement = None
        key = (name, None if placement is None else placement[1])
        if key not in bsdfs:
            bsdfs[key] = surface_bsdf(material, mode, lambda channel: ref(channel, placement))
        return bsdfs[key]

    for name, material in scene.materials.items():   # their textures, in the file's order
        if not placed(material):
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
            holders = medium_holders((shape for _, shape in scene.shapes()), name,
                                     None if placement is None else placement[1])
            media[key] = medium_dict(scene, subsurface, lambda channel: ref(channel, placement),
                                     holders)
        return media[key]

    two_sided: dict = {}       # id of a path BSDF -> the one twosided wrapper of it
    for shape_id, shape in scene.shapes():
        placement = (shape_id, geometry.object_to_world(shape))
        bsdf = bsdf_of(shape.material, placement)
        subsurface = scene.materials[shape.material].subsurface
        if mode != "whitted" and is_two_sided(shape) \
                and (subsurface is None or mode == "preview"):
            # Mitsuba's BSDFs reflect on the side their normal points to; planes, boxes
            # and meshes are shaded on either side (whitted flips n to the viewer). A
            # subsurface boundary is two-sided itself (and twosided refuses transmission);
            # its preview is a one-sided reflection, as an opaque material's BSDF.
            bsdf = two_sided.setdefault(id(bsdf), {"type": "twosided", "bsdf": bsdf})
        # Its medium's textures first: a reference follows what it refers to.
        interior = medium_of(shape.material, placement) \
            if mode == "path" and subsurface is not None else None
        out[shape_id] = shape_dict(scene, shape)
        out[shape_id]["bsdf"] = bsdf
        if interior is not None:
            out[shape_id]["interior"] = interior
            facing_out(out[shape_id], shape)

    lighting = "path" if mode == "preview" else mode      # the preview is lit as path mode
    for k, light in enumerate(scene.lights):
        if light.area is not None:
            out[f"light_{k}"] = area_light_dict(light, scene.camera.lookat, lighting)
            continue
        out[f"light_{k}"] = point_light_dict(light, scene.camera.lookat, lighting)

    ambient = ambient_dict(scene, lighting)
    if ambient is not None:
        out["ambient"] = {**ambient, **constant_sky_weight(scene, mode)}
    if scene.environment is not None:
        out["environment"] = environment_dict(scene.environment)
        if out["environment"]["type"] == "constant":
            out["environment"].update(constant_sky_weight(scene, mode))
    return out
