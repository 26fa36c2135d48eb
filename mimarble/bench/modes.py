"""The benchmark's modes (how a scene is rendered: filter, edge samples, adaptive
sampling), its default spp and thresholds, and the paper's render times it compares with."""

from __future__ import annotations

import dataclasses

from mimarble.contract import DEFAULT_MAX_SPP



#: Edge samples of the runs' prefilter+edges mode unless --edge-spp says otherwise.
DEFAULT_EDGE_SPP = 64
#: The adaptive modes' thresholds unless --adaptive says otherwise: the estimated
#: per-pixel error (linear colour) above which a pixel gets more samples (times n³ at n²
#: samples), coarse to fine: 0.005 quartered down to 7.6e-8 (the bar's n³ reaches the last
#: level only far below the first pass's).
ADAPTIVE_THRESHOLDS = tuple(float(f"{0.005 * 4.0 ** -k:.2g}") for k in range(9))
#: The adaptive modes' first pass and cap on any pixel's samples (both perfect squares).
ADAPTIVE_FIRST_SPP = 1             # and DEFAULT_MAX_SPP, contract.py's (imported above)
#: The runs' spp (the adaptive modes' are their thresholds') and the converged reference's:
#: finer than the runs' finest, so that plain 64 spp's RMSE is an error, not zero.
DEFAULT_SPPS = (1, 4, 16, 64)
DEFAULT_CONVERGED_SPP = 256
#: The plain spp whose RMSE every mode's time is measured to (:func:`times_to_plain_rmse`).
TARGET_SPPS = (16, 64)


@dataclasses.dataclass(frozen=True)
class Mode:
    """How the benchmark renders a scene: every marble's ``filter``, and edge samples
    (None: none); ``adaptive``: through :func:`~mimarble.mitsuba.rendering.adaptive.render_adaptive`
    (a first pass, then more samples where a pixel's estimated error is above a
    threshold), once per threshold instead of once per spp."""

    name: str
    filter: str = "none"
    edge_spp: int | None = None
    adaptive: bool = False


def modes(filter: str | None = None, edge_spp: int | None = None,
          adaptive: bool = True) -> tuple[Mode, ...]:
    """The runs' modes: plain, bandlimit, prefilter and prefilter with edge samples, then
    (``adaptive``) adaptive sampling of plain and of prefiltered marble; with ``filter``,
    that filter alone (with edge samples when ``edge_spp`` is given), and adaptive
    sampling of it."""
    if filter is None:
        fixed = (Mode("plain"), Mode("bandlimit", "bandlimit"), Mode("prefilter", "prefilter"),
                 Mode("prefilter+edges", "prefilter", edge_spp or DEFAULT_EDGE_SPP))
        filters = ("none", "prefilter")
    else:
        name = "plain" if filter == "none" else filter
        fixed = (Mode(name + ("+edges" if edge_spp else ""), filter, edge_spp),)
        filters = (filter,)
    if not adaptive:
        return fixed
    return fixed + tuple(Mode("adaptive" + ("" if f == "none" else "+" + f), f, adaptive=True)
                         for f in filters)


MODES = modes()
#: The modes the fig11a targets compare (octaves 32 vs 8, time to RMSE ≤ 0.01).
TARGET_MODES = MODES[:2]


def is_paper_scene(name: str) -> bool:
    """Whether a run's scene is one of the paper's figures (``fig…``): the means are over
    these; every other scene (the fine veins, …) is reported on its own."""
    return name.startswith("fig")
# The paper's "render" column (seconds on a 2 GHz Pentium 4, 500×500) for Figs. 7–11.
PAPER_SECONDS = {
    "fig07a": 2.0, "fig07b": 2.0, "fig07c": 2.0, "fig07d": 2.0,
    "fig08a": 2.0, "fig08b": 2.0, "fig08c": 2.0, "fig08d": 2.0,
    "fig09a": 2.0, "fig09b": 2.0, "fig09c": 2.0, "fig09d": 2.0,
    "fig10a": 0.8, "fig10b": 1.0, "fig10c": 1.4, "fig10d": 2.0,
    "fig11a": 2.8, "fig11b": 6.3, "fig11c": 2.1, "fig11d": 2.1,
}
