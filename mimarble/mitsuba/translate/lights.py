"""Scene lights → Mitsuba emitters: a point light, an area light (a sphere or a rectangle)
as the mode renders it, path mode's ambient environment, and the scene's ``environment``
(Mitsuba's ``envmap`` or ``constant``, in every mode).

A light of colour I → ``point`` intensity I (whitted) or I·π·d² (path), d its distance to
the camera's look-at point: a Lambertian surface there then receives kd·I·cosθ in both
modes, and the 1/d² falloff is physical elsewhere. The background colour is not rendered
in path mode (misses are black).
"""

from __future__ import annotations

import math

from mimarble.scene import model
from mimarble.scene.rules import cross


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


def ambient_dict(scene: model.Scene, mode: str) -> dict | None:
    """Path mode: the global ambient A as a hidden ``constant`` environment of radiance A (a
    Lambertian surface open to the sky reflects kd⊙A: the ambient term with kd in place of
    ka); None without one, in whitted mode, whose integrator adds the paper's term, and in
    a scene with an ``environment``, which is its sky instead (Mitsuba takes one)."""
    if mode == "path" and any(scene.ambient) and scene.environment is None:
        return {"type": "constant", "radiance": {"type": "rgb", "value": list(scene.ambient)}}
    return None


def environment_rotation(rotate):
    """``rotate < a b c >`` (degrees about x, then y, then z) as Mitsuba's own
    ``ScalarTransform4f``: R = R_z(c)·R_y(b)·R_x(a), made by Mitsuba's ``rotate`` and
    multiplied as a hand-written scene writes it, ``T().rotate([0, 0, 1], c) @
    T().rotate([0, 1, 0], b) @ T().rotate([1, 0, 0], a)`` — left to right, the zero angles
    left out (float32 products are not associative: so such a scene is the same, bit for
    bit)."""
    import mitsuba as mi   # imported here: the module itself stays importable without it
    a, b, c = rotate
    turns = [mi.ScalarTransform4f().rotate(axis=axis, angle=angle)
             for axis, angle in (([0, 0, 1], c), ([0, 1, 0], b), ([1, 0, 0], a)) if angle != 0]
    transform = turns[0]
    for turn in turns[1:]:
        transform = transform @ turn
    return transform


def environment_dict(environment: model.Environment) -> dict:
    """The scene's ``environment`` as Mitsuba's emitter, in every mode: a file is an
    ``envmap`` (``filename``, ``scale`` = intensity, ``to_world`` = the rotation), a colour
    a ``constant`` of radiance colour × intensity. Path mode renders it as the sky (the
    camera sees it: the integrator's ``hide_emitters`` is off, modes.py); whitted mode's
    integrator looks it up for the rays that miss (the paper's background)."""
    if environment.color is not None:
        radiance = [c * environment.intensity for c in environment.color]
        return {"type": "constant", "radiance": {"type": "rgb", "value": radiance}}
    out = {"type": "envmap", "filename": environment.location, "scale": environment.intensity}
    if any(environment.rotate):
        out["to_world"] = environment_rotation(environment.rotate)
    return out
