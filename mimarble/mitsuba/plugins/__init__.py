"""mimarble's Mitsuba plugins: the marble texture, expressions, material, integrator, light, medium, boundary, preview, phase.

Importing the package declares the Python classes (``registration.install`` registers
them with Mitsuba for every variant).
"""

from mimarble.mitsuba.plugins import (channel_expression, marble_medium,  # noqa: F401
                                      material, roulette_phase, subsurface_boundary,
                                      subsurface_preview, whitted)
