"""The rendering modes: the integrator and sampler each renders with, and the error
for a scene that a mode cannot render.

``whitted``: the paper's model exactly — ``channel_material`` BSDFs, ``point`` lights, the
``whitted`` integrator, a non-jittered ``stratified`` sampler and a ``box`` filter, so every
pixel is the mean of its n×n stratum centres.

``path``: physically based — the marble drives Mitsuba's own BSDFs under the ``path``
integrator (``volpath`` when a material has a ``subsurface``, max_depth
:data:`VOLPATH_MAX_DEPTH`, no Russian roulette where an albedo may pass its cap:
:func:`roulette_depth`; whitted mode refuses one: :class:`ModeError`, at its
``subsurface`` keyword). docs/rendering-model.md says how the paper's quantities map.

``preview``: path mode with every translucent material's fast preview in place of its
walk (``subsurface_preview``: a surface, no medium), so ``path`` for every scene, at
max_depth :data:`PREVIEW_MAX_DEPTH` (direct light only) where a material is translucent.
"""

from __future__ import annotations

from mimarble.contract import (PATH_MAX_DEPTH, PREVIEW_MAX_DEPTH, RENDER_MODES, ROULETTE_DEPTH,
                               ROULETTE_MAX, VOLPATH_MAX_DEPTH, VOLPATH_RR_DEPTH)
from mimarble.scene.errors import SceneError
from mimarble.scene.rules import shortened
from mimarble.texture import error_budget


MODES = RENDER_MODES


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


def refuse_translucent(scene, mode: str, translucent: tuple) -> None:
    """Whitted mode cannot render a ``subsurface``: ModeError at the first one's keyword."""
    if mode == "whitted" and translucent:
        material = translucent[0]
        raise ModeError.in_file(
            scene.source, material.subsurface.pos,
            f"material \"{shortened(material.name)}\" has a subsurface, a "
            f"scattering volume that whitted mode (the paper's surface shading) cannot render: "
            f"render the scene with --mode path (mode=\"path\")")


def integrator_and_sampler(scene, mode: str, spp: int, translucent: tuple,
                           smooth: bool = False) -> tuple[dict, dict]:
    """The mode's integrator and sampler: whitted with the scene's ambient and background
    over n×n stratum centres (``smooth``: the scene has a smooth mesh, whitted shades with
    shading normals); path (volpath with translucent materials: light scattered
    inside media, docs/rendering-model.md) over independent samples, stratified ones where a
    material is translucent (:func:`translucent_sampler`); preview as path
    without media: ``path`` always."""
    if mode == "whitted":
        integrator = {"type": "whitted", "ambient": list(scene.ambient),
                      "background": list(scene.image.background)}
        if smooth:              # only then: other scenes' dicts (and images) stay as they were
            integrator["shading_normals"] = True
        return integrator, {"type": "stratified", "sample_count": spp, "jitter": False}
    # The camera sees the scene's environment (and then its area lights too: Mitsuba hides
    # all emitters or none); without one, no emitter, as whitted mode sees no light.
    hidden = scene.environment is None
    if translucent and mode == "path":
        return ({"type": "volpath", "max_depth": VOLPATH_MAX_DEPTH,
                 "rr_depth": roulette_depth(translucent), "hide_emitters": hidden},
                translucent_sampler(spp))
    # preview: direct light only when a translucent material is previewed (its aim is speed)
    depth = PREVIEW_MAX_DEPTH if translucent and mode == "preview" else PATH_MAX_DEPTH
    return ({"type": "path", "max_depth": depth, "hide_emitters": hidden},
            {"type": "independent", "sample_count": spp})


def translucent_sampler(spp: int) -> dict:
    """Path mode's sampler for a scene with translucent materials: Mitsuba's
    ``multijitter`` where it takes ``spp`` samples as they are (an r × c grid, r = ⌊√spp⌋,
    c = ⌈spp/r⌉, r·c = spp), else ``independent`` (``multijitter`` would round spp up, with a
    warning). JIT variants load a scene at 1 spp (``multijitter`` too) and the pass
    renderer sets the render's spp, drawing a pixel's spp samples as one such sequence
    (``rendering.passes.stratify``): every dimension of the walk — the pixel position, the
    light sample at an exit, each scattering's distance and direction — is stratified
    across the pixel's samples, a per-pixel permutation of spp jittered strata (of a
    multi-jittered grid for 2-D draws), and still unbiased (each sample alone is uniform).
    What it does to the noise is measured in docs/benchmarks.md, "A stratified walk against
    Cycles". Opaque scenes keep ``independent`` (their images unchanged)."""
    rows = max(int(spp ** 0.5), 1)
    while rows > 1 and rows * rows > spp:      # ⌊√spp⌋ (a float root may round up)
        rows -= 1
    columns = -(-spp // rows)
    kind = "multijitter" if rows * columns == spp else "independent"
    return {"type": kind, "sample_count": spp}


def roulette_depth(translucent: tuple) -> int:
    """volpath's ``rr_depth`` for a scene with the translucent materials ``translucent``:
    :data:`VOLPATH_RR_DEPTH` (max_depth: no roulette) when some subsurface's
    single-scattering albedo may pass :data:`ROULETTE_MAX` — an albedo channel whose
    components' bound (``error_budget.channel_bound``, clamped to 1 as the medium clamps)
    passes it, or a subsurface without an albedo channel — else Mitsuba's default
    :data:`ROULETTE_DEPTH`. volpath's roulette survives a path with min(max β, 0.95): its
    weights grow as (α/0.95)ᵏ above that albedo, a few huge fireflies in white marble, while
    below it the roulette is the faster at equal noise (the efficiencies of both:
    docs/benchmarks.md, "Russian roulette on white marble"). Where it is off, the media's
    phase function ends walks by their albedo (``media.roulette_phase``)."""
    for material in translucent:
        albedo = getattr(material.subsurface, "albedo", None)
        if albedo is None or min(error_budget.channel_bound(albedo), 1.0) > ROULETTE_MAX:
            return VOLPATH_RR_DEPTH
    return ROULETTE_DEPTH
