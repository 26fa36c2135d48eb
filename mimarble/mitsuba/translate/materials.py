"""Scene materials → Mitsuba BSDFs: the paper's ``channel_material`` in whitted mode; in
path mode ``diffuse``, or ``roughplastic`` with a specular channel, or a translucent
material's ``subsurface_boundary`` (preview mode: its ``subsurface_preview``; else as path).

Path mode: the diffuse channel kd → ``diffuse`` reflectance; with a specular channel,
``roughplastic`` (diffuse_reflectance kd, specular_reflectance ks, Beckmann
α = √(2/(shininess+2)), the usual Phong-exponent match, interior IOR 1.6 of calcite): a
physical polished marble, whose highlight is a few percent of the light — far dimmer than
the paper's Phong highlight (measured side by side in docs/rendering-model.md).
"""

from __future__ import annotations

import math

from mimarble.scene import model

from .media import subsurface_boundary, subsurface_preview


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


def surface_bsdf(material: model.Material, mode: str, ref) -> dict:
    """The material's BSDF in ``mode``, its channels' textures given by ``ref(channel)``."""
    if mode == "path" and material.subsurface is not None:
        return subsurface_boundary(material.subsurface)   # its channels: unused
    if mode == "preview" and material.subsurface is not None:
        return subsurface_preview(material.subsurface, ref)   # the subsurface's colour
    if mode == "whitted":
        bsdf = {"type": "channel_material", "shininess": material.shininess}
        for channel_name, channel in material.channels().items():
            bsdf[channel_name] = ref(channel)
        return bsdf
    return _path_bsdf(material, ref)
