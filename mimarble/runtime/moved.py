"""Modules that moved in the second layout (0.2): their old import paths, kept one release.

``import mimarble.marble`` (or ``from mimarble.marble_parameters import …``) still works
and gives the module at its new place — the same module object, so a monkeypatch through
either name patches both — with a :class:`DeprecationWarning` naming the new path.
Modules of the public interface (``mimarble.noise``, ``mimarble.marble``) stay without a
warning. The table is the one list of what moved: docs/design-decisions.md ("Where things
are") gives the new layout.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import warnings

MOVED = {
    "mimarble.marble_parameters": "mimarble.parameters",
    "mimarble.noise": "mimarble.texture.noise",
    "mimarble.stripes": "mimarble.texture.stripes",
    "mimarble.ramp": "mimarble.texture.ramp",
    "mimarble.texture_mapping": "mimarble.texture.mapping",
    "mimarble.pixel_filter": "mimarble.texture.filters",
    "mimarble.prefilter": "mimarble.texture.prefilter",
    "mimarble.error_budget": "mimarble.texture.error_budget",
    "mimarble.srgb_model": "mimarble.texture.srgb_model",
    "mimarble.finite_arithmetic": "mimarble.texture.finite_arithmetic",
    "mimarble.marble": "mimarble.mitsuba.plugins.marble",
    "mimarble.plugins": "mimarble.mitsuba.plugins.registration",
    "mimarble.properties": "mimarble.parameters",
    "mimarble.mitsuba.properties": "mimarble.parameters",
    "mimarble.mitsuba.channel_expression": "mimarble.mitsuba.plugins.channel_expression",
    "mimarble.mitsuba.material": "mimarble.mitsuba.plugins.material",
    "mimarble.mitsuba.whitted": "mimarble.mitsuba.plugins.whitted",
    "mimarble.mitsuba.area_light": "mimarble.mitsuba.plugins.area_light",
    "mimarble.mitsuba.marble_medium": "mimarble.mitsuba.plugins.marble_medium",
    "mimarble.mitsuba.sphere_hit": "mimarble.mitsuba.plugins.sphere_hit",
    "mimarble.mitsuba.passes": "mimarble.mitsuba.rendering.passes",
    "mimarble.mitsuba.replay": "mimarble.mitsuba.rendering.replay",
    "mimarble.mitsuba.loaded_scenes": "mimarble.mitsuba.rendering.loaded_scenes",
    "mimarble.mitsuba.adaptive": "mimarble.mitsuba.rendering.adaptive",
    "mimarble.mitsuba.image_output": "mimarble.mitsuba.rendering.image_output",
    "mimarble.mitsuba.window": "mimarble.mitsuba.rendering.window",
    "mimarble.mitsuba.silhouettes": "mimarble.mitsuba.rendering.silhouettes",
    "mimarble.mitsuba.pixel_tracer": "mimarble.mitsuba.rendering.pixel_tracer",
    "mimarble.crop": "mimarble.mitsuba.rendering.crop",
    "mimarble.environment": "mimarble.runtime.environment",
    "mimarble.llvm_target": "mimarble.runtime.llvm_target",
    "mimarble.drjit_core": "mimarble.runtime.drjit_core",
    "mimarble.kernel_cache": "mimarble.runtime.kernel_cache",
    "mimarble.machine": "mimarble.runtime.machine",
    "mimarble.files": "mimarble.runtime.files",
    "mimarble.progress": "mimarble.runtime.progress",
    "mimarble.image_formats": "mimarble.runtime.image_formats",
    "mimarble.packaged_scenes": "mimarble.runtime.packaged_scenes",
    "mimarble.scene_edits": "mimarble.scene.edits",
    "mimarble.reference.mesh_file": "mimarble.meshes.arrays",
    "mimarble.scene.mesh_header": "mimarble.scene.mesh_files",
    "mimarble.scene.reading": "mimarble.runtime.reading",
    "mimarble.compare": "mimarble.tools.compare",
    "mimarble.bake": "mimarble.tools.bake",
    "mimarble.export": "mimarble.tools.export",
    "mimarble.povray": "mimarble.tools.povray",
    "mimarble.gallery": "mimarble.tools.gallery",
    "mimarble.stress": "mimarble.tools.stress",
    "mimarble.contact_sheet": "mimarble.sweeps.contact_sheet",
    "mimarble.bench_adam": "mimarble.bench.adam",
    "mimarble.bench_calls": "mimarble.bench.calls",
    "mimarble.bench_page": "mimarble.bench.page",
    "mimarble.bench_peers": "mimarble.bench.peers",
    "mimarble.bench_plot": "mimarble.bench.plot",
    "mimarble.bench_report": "mimarble.bench.report",
}
# Old names that are also the public interface (docs/design.md): no warning.
KEPT = frozenset(("mimarble.noise", "mimarble.marble", "mimarble.packaged_scenes"))


class _Alias:
    """Finds an old module name and loads it as the module at its new place (a meta path
    finder and loader by their methods: importlib.abc's base classes would import
    importlib.resources, tempfile and more into every start of the command)."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        if spec.name not in KEPT:
            warnings.warn(f"{spec.name} moved to {MOVED[spec.name]}; the old name goes in the "
                          "next release", DeprecationWarning, stacklevel=2)
        return importlib.import_module(MOVED[spec.name])

    def exec_module(self, module):
        pass                             # the module at its new place has run already


def install() -> None:
    """Let the old names import; idempotent."""
    if not any(isinstance(finder, _Alias) for finder in sys.meta_path):
        sys.meta_path.append(_Alias())
