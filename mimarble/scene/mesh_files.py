"""A scene's mesh files checked as the parser checks them (:func:`check_mesh_files`), for the
translator: over the one reader, mimarble/meshes/ (its facts, kept per version of a file).

``mimarble.scene.mesh_header`` (the reader before it moved to meshes/) names this module
one release (runtime/moved.py); its names are re-exported here for it.
"""

from __future__ import annotations

import math

from mimarble.meshes.facts import MeshFacts, mesh_bounds, mesh_facts
from mimarble.meshes.limits import (MAX_MESH_VERTICES, MAX_OBJ_LINE_BYTES, MAX_PLY_HEADER_BYTES,
                                    MAX_PRECISE_UV, MeshFileError, open_mesh)
from mimarble.meshes.obj_lines import obj_statements
from mimarble.meshes.ply_header import PLY_TYPES, PlyElement, PlyHeader, PlyProperty, ply_header
from .errors import SceneError
from .model import ImageChannel, walk
from .rules import image_map_uv_problem, mesh_triangles_problem, shortened

__all__ = ["check_mesh_files",
           # mimarble.scene.mesh_header's, one release (runtime/moved.py):
           "MeshFacts", "MeshFileError", "mesh_facts", "mesh_bounds", "MAX_PRECISE_UV",
           "MAX_PLY_HEADER_BYTES", "MAX_MESH_VERTICES", "MAX_OBJ_LINE_BYTES", "PLY_TYPES",
           "PlyProperty", "PlyElement", "PlyHeader", "ply_header", "obj_statements", "open_mesh"]


def check_mesh_files(scene) -> list[str]:
    """Every mesh file of ``scene`` checked as the parser checks it, for a scene the parser
    never saw or whose files changed since (built in Python, edited, a file rewritten after
    ``scene.load``): :func:`mesh_facts` (kept per version of the file, so a file parsed
    and unchanged is not read again), a smooth mesh's normals complete, the scene's
    triangles within MAX_MESH_TRIANGLES, and
    (u, v) in the file where the mesh's material reads an image map — else a SceneError at
    the mesh's ``file`` in the parser's sentence. Returns the warnings of texture
    coordinates past :data:`MAX_PRECISE_UV` read by an image map, one per mesh file.
    The translator calls it for every route into Mitsuba; the reference tracer reads the
    files with the same checks (tracer.read_meshes)."""
    imaged = {name for name, material in scene.materials.items()
              if any(isinstance(c, ImageChannel) for channel in material.channels().values()
                     for c in walk(channel))}
    total, warned, problems = 0, set(), []
    for mesh in scene.meshes:
        name = shortened(mesh.file, 256)
        try:
            facts = mesh_facts(mesh.location)
        except MeshFileError as e:
            raise SceneError.in_file(scene.source, mesh.pos, f"mesh file '{name}': {e}") from None
        if mesh.smooth and facts.normals_problem:
            raise SceneError.in_file(scene.source, mesh.pos,
                                     f"mesh file '{name}': {facts.normals_problem}")
        total += facts.triangles
        problem = mesh_triangles_problem(total)
        if problem:
            raise SceneError.in_file(scene.source, mesh.pos, problem)
        if mesh.material in imaged:
            if not facts.has_uv:
                raise SceneError.in_file(scene.source, mesh.pos, image_map_uv_problem(
                    mesh.material, "this mesh's file"))
            if facts.uv_extent > MAX_PRECISE_UV and mesh.location not in warned:
                warned.add(mesh.location)
                problems.append(
                    f"{scene.source or '<scene>'}:{mesh.pos or '?'}: mesh file '{name}' has "
                    f"texture coordinates up to {facts.uv_extent:g}, past ±{MAX_PRECISE_UV:g}: "
                    f"Mitsuba holds them in float32, whose step there "
                    f"({_float32_step(facts.uv_extent):.2g}) reaches a texel of a large image "
                    f"map, so its image may differ from the reference's there "
                    f"(docs/rendering-model.md)")
    return problems


def _float32_step(value: float) -> float:
    """The spacing of float32 numbers at |value| (value within float32's range)."""
    return 2.0 ** (math.frexp(value)[1] - 24)
