"""The Mitsuba side: the plugins, the scene translator, rendering.

``plugins/`` holds mimarble's Mitsuba plugins (the ``marble`` texture, the channel
expressions, the paper's material, the Whitted integrator, the stratified area light and
``marble_medium``), ``translate/`` turns a scene model into a Mitsuba scene dict, and
``rendering/`` traces a loaded scene in passes. The names below load Mitsuba on first
use, so that a module of this package that needs neither (a crop window's words, say)
can be read before Dr.Jit loads.
"""

import importlib

__all__ = ["MODES", "render", "texture_dict", "to_mitsuba", "write_image"]

_NAMES = {"MODES": "translate.scene_dict", "texture_dict": "translate.scene_dict",
          "to_mitsuba": "translate.scene_dict", "render": "rendering.render",
          "write_image": "rendering.image_output"}


def __getattr__(name):
    if name in _NAMES:
        importlib.import_module(f"{__name__}.plugins")     # declares the plugins
        return getattr(importlib.import_module(f"{__name__}.{_NAMES[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
