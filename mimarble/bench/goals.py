"""The issue's benchmark targets, each written once: its bound and its stretch goal.

The report (:mod:`.report`) and the page (:mod:`.page`) both print them from here.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Goal", "OCTAVES_32_OVER_8", "MARBLE_OVER_CONSTANT", "OCTAVE_RATE", "RMSE_SPEEDUP",
           "PROCESS_SECONDS", "POVRAY_OVER_OURS", "ADAPTIVE_TARGETS"]


@dataclass(frozen=True)
class Goal:
    """A target: ``bound`` as the report writes it ("≤ 1.3"), and its ``stretch`` goal."""

    bound: str
    stretch: str | None = None

    def in_report(self) -> str:
        """"target ≤ 3.0, stretch 2.0", as the text report writes it."""
        return f"target {self.bound}" + (f", stretch {self.stretch}" if self.stretch else "")

    def stretched(self) -> str:
        """" (stretch 2.0)", or "" without one: as the page writes it after the target."""
        return f" (stretch {self.stretch})" if self.stretch else ""


#: time(octaves 32) / time(octaves 8): octaves past the 8th cost little.
OCTAVES_32_OVER_8 = Goal("≤ 1.3")
#: time(marble, 8 octaves) / time(constant colour).
MARBLE_OVER_CONSTANT = Goal("≤ 3.0", "2.0")
#: Octave evaluations per second per core in the render.
OCTAVE_RATE = Goal("≥ 100 M", "200 M")
#: How much sooner the band-limited (prefiltered) render reaches RMSE ≤ 0.01 than plain.
RMSE_SPEEDUP = Goal("≥ 4×")
#: A whole `python -m mimarble` process: --help, a malformed scene's error.
PROCESS_SECONDS = Goal("< 0.15")
#: POV-Ray's trace time over ours, on the same marble sphere.
POVRAY_OVER_OURS = Goal("≥ 10")
#: ``--adaptive``'s speed-up to plain supersampling's error, by plain's spp.
ADAPTIVE_TARGETS = {"16": 4.0, "64": 6.0}
