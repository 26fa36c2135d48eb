"""The Mitsuba side: the scene translator, the paper's material and Whitted integrator, rendering."""

from . import channel_expression, marble_medium, material, whitted  # noqa: F401  (declare the plugins)
from .image_output import write_image
from .render import render
from .translate import MODES, texture_dict, to_mitsuba

__all__ = ["MODES", "render", "texture_dict", "to_mitsuba", "write_image"]
