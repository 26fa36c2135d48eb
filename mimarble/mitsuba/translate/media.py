"""Translucent materials → Mitsuba: the ``subsurface_boundary`` surface and the ``marble_medium``
interior of a material with a ``subsurface`` (preview mode: its ``subsurface_preview`` surface)."""

from __future__ import annotations

from mimarble.contract import FLT_MAX, VOLPATH_RR_DEPTH
from mimarble.scene import model
from mimarble.scene.albedo_grid import albedo_grid
from mimarble.scene.band_limit import band_limited
from mimarble.texture import error_budget

from .modes import ModeError, roulette_depth
from .textures import texture_dict


def translucent_materials(scene: model.Scene) -> tuple:
    """The materials with a subsurface that some shape of ``scene`` uses, in file order:
    a scene with one renders in path mode only, under ``volpath`` (a material no shape
    uses changes no image, and is not asked about)."""
    used = {shape.material for _, shape in scene.shapes()}
    return tuple(m for m in scene.materials.values() if m.subsurface is not None and m.name in used)


def subsurface_boundary(subsurface: model.Subsurface) -> dict:
    """The BSDF of a translucent material's surface: ``subsurface_boundary``
    (mimarble/mitsuba/plugins/subsurface_boundary.py) of relative index ``ior`` (int_ior = ior,
    ext_ior = 1), at every ior, 1 included: a Fresnel-weighted mirror outside, a diffuse
    entry, and a diffuse exit on which ``volpath`` connects the walk to every light (point
    lights too: docs/rendering-model.md, "Translucent materials"). It is two-sided itself."""
    return {"type": "subsurface_boundary", "int_ior": subsurface.ior, "ext_ior": 1.0}


def subsurface_preview(subsurface: model.Subsurface, ref) -> dict:
    """Preview mode's BSDF of a translucent material's surface: ``subsurface_preview``
    (mimarble/mitsuba/plugins/subsurface_preview.py), the walk's limit as the mean free path
    goes to 0 — the boundary's Fresnel coat over a diffuse lobe of the spherical albedo the
    walk would return, from the subsurface's reflectance (or albedo) at the surface point
    (``ref(channel)``: its texture, placed as the surface's channels are); no medium. The
    density and the mean free path do not enter (docs/rendering-model.md, "The fast
    preview")."""
    kind = "reflectance" if subsurface.reflectance is not None else "albedo"
    return {"type": "subsurface_preview", kind: ref(getattr(subsurface, kind)),
            "int_ior": subsurface.ior, "ext_ior": 1.0}


def medium_dict(scene: model.Scene, subsurface: model.Subsurface, ref=None,
                shapes=()) -> dict:
    """The ``marble_medium`` (mimarble/mitsuba/plugins/marble_medium.py) of a subsurface: the
    textures of its albedo (or reflectance, with the boundary's ``ior`` for its inversion)
    and density channels (``ref(channel)``: a texture or a reference
    to one; default: :func:`texture_dict`), ``scale`` = 1/mean_free_path, so that
    σ_t(p) = scale·d(p), and ``density_bound`` ≥ every d(p) (the majorant is
    scale·density_bound): ``error_budget.mean_bound`` of the density channel (d is the mean
    of its components, at least 0), 1 without one (d = 1). Behind the boundary (not
    ``null``) no shadow ray from inside can reach an emitter, so the medium samples none
    (``sample_emitters`` false: the paths that leave find them; unbiased, and up to half the
    render time saved). A majorant past
    float32's range is refused (ModeError at the ``subsurface`` keyword): Mitsuba's
    arithmetic is single precision. The colour channel's marbles are band-limited to the
    mean free path (``band_limited``: octaves finer than it left out, as the reference walk
    does). Its albedo is read from a grid over ``shapes`` (those that hold the medium)
    where ``albedo_grid`` gives one (mimarble/scene/albedo_grid.py: ``grid_origin``,
    ``grid_spacing``, ``grid_counts``)."""
    ref = texture_dict if ref is None else ref
    subsurface = band_limited(subsurface)
    density = subsurface.density
    scale = 1.0 / subsurface.mean_free_path
    bound = 1.0 if density is None else max(0.0, error_budget.mean_bound(density))
    if not scale * bound <= FLT_MAX:
        raise ModeError.in_file(
            scene.source, subsurface.pos,
            f"mean_free_path {subsurface.mean_free_path:g} with a density up to {bound:g} is "
            f"an extinction of up to {scale * bound!r} per scene unit, past float32's "
            f"{FLT_MAX!r}, the most Mitsuba's single precision holds")
    out = {"type": "marble_medium"}
    if subsurface.reflectance is not None:       # inverted in the medium, for the boundary's ior
        out.update(reflectance=ref(subsurface.reflectance), ior=subsurface.ior)
    else:
        out["albedo"] = ref(subsurface.albedo)
    if density is not None:
        out["density"] = ref(density)
    out.update(scale=scale, density_bound=bound, sample_emitters=False)
    grid = albedo_grid(subsurface, shapes)
    if grid is not None:
        out.update(grid_origin=list(grid.origin), grid_spacing=grid.spacing,
                   grid_counts=list(grid.counts))
    out.update(roulette_phase(scene))
    return out


#: The selection weight, against 1 for each light, of a ``constant`` sky (the ambient, or an
#: environment colour) in the emitter sampling of a path-mode scene with a translucent
#: material and lights (issue 40, docs/rendering-model.md "Which light the exit samples").
CONSTANT_SKY_WEIGHT = 1.0 / 64.0


def constant_sky_weight(scene: model.Scene, mode: str) -> dict:
    """``{"sampling_weight": CONSTANT_SKY_WEIGHT}`` for a ``constant`` sky of a path-mode scene
    with a translucent material and at least one light, else nothing. A walk reaches the
    lights at its diffuse exit (``subsurface_boundary``), where volpath picks one emitter
    (with probability ∝ its weight, Mitsuba's ``sampling_weight``) and also samples the exit's
    cosine lobe, combining both by MIS. A point light only the first finds; a constant sky
    the cosine lobe finds at least as well as the sky's own uniform-sphere sampling, half
    of whose directions point into the object. Picking the sky as often as a light (Mitsuba's
    default) spends half of fig11a-translucent's connections where they add little: at
    weight 1/64 its noise is 0.47× (docs/benchmarks.md). Unbiased: a selection probability
    the MIS weights include. An ``envmap`` keeps weight 1 (a sun in it needs its own
    sampling), and so does every scene without a subsurface (their images unchanged)."""
    if mode == "path" and scene.lights and translucent_materials(scene):
        return {"sampling_weight": CONSTANT_SKY_WEIGHT}
    return {}


#: The power p of the walk's survival q = (max α)^p at each scattering where max α lies in
#: WALK_POWER_ALBEDOS (``roulette_isotropic``'s ``survival_power``; issue 40,
#: docs/rendering-model.md "Translucent materials"): p = 1 is the analog walk (weights ≤ 1);
#: p = 3 ends a walk of albedo α ≈ 1 three times as often, each survivor's weight multiplied
#: by α^(1 − p) ≥ 1 a scattering. Unbiased; the time and noise it gives: docs/benchmarks.md, "The
#: walk's survival power against Cycles".
WALK_SURVIVAL_POWER = 3.0
#: [lo, hi): the albedos at which the walk's survival takes the power (the phase's
#: ``power_albedo_min``, ``power_albedo_max``); elsewhere the analog walk's max α. From lo
#: the depth cap bounds the variance: a walk of k ≤ VOLPATH_MAX_DEPTH scatterings at albedo
#: α carries the second moment α^((2 − p)k) ≤ 0.99^(−256) = 13 (≤ 1 for p ≤ 2, which saved
#: too little time) and a weight ≤ 0.99^(−512) = 171; lower albedos end their walks soon
#: anyway (from 0.95 on, the honey onyx kept 0.89× of its efficiency; from 0.99, all). From hi (a
#: reflectance of ~0.93 at ior 1.5) the absorption length, 1000 scatterings, is 4× the
#: depth cap, so the boundary and the cap end white walks and the power only added noise
#: (efficiency 0.83–0.84×). docs/benchmarks.md, "The walk's survival power against Cycles".
WALK_POWER_ALBEDOS = (0.99, 0.999)


def roulette_phase(scene: model.Scene) -> dict:
    """``{"phase": {"type": "roulette_isotropic", "survival_power": WALK_SURVIVAL_POWER,
    "power_albedo_min": …, "power_albedo_max": …}}`` (:data:`WALK_POWER_ALBEDOS`) where path
    mode's volpath runs without Russian roulette (``modes.roulette_depth``: some albedo may
    pass 0.95), else nothing (Mitsuba's ``isotropic``). The phase function ends a walk at
    each scattering with probability 1 − q and divides a survivor's weight by q, q = (max α)^p
    at albedos in the window, max α elsewhere (mimarble/mitsuba/plugins/roulette_phase.py):
    without it a white walk runs
    to the boundary or the depth cap. Near albedo 1 it is more efficient than no roulette,
    or as efficient; below 0.95 volpath's own roulette is the better, which the scene keeps
    there (docs/benchmarks.md, "Russian roulette on white marble")."""
    if roulette_depth(translucent_materials(scene)) == VOLPATH_RR_DEPTH:
        lo, hi = WALK_POWER_ALBEDOS
        return {"phase": {"type": "roulette_isotropic", "survival_power": WALK_SURVIVAL_POWER,
                          "power_albedo_min": lo, "power_albedo_max": hi}}
    return {}
