"""The scene builder's shapes, each built with its material's name token and whether it has texture coordinates (u, v).

A kind's block is read from its record's keys (shapes.py: vectors and numbers, each
refused at its value by its rule); ``box`` (its corners checked together) and ``mesh``
(its file's facts read once per file, meshes/, its triangles counted toward the
scene's limit) have readers of their own.
"""

from __future__ import annotations

import os

from lark import Token, Tree

from mimarble.meshes.limits import MeshFileError
from mimarble.scene import rules
from .build_values import ValueReader, pos_of, unquoted, vector_text
from .model import MESH_FORMATS, Box, Mesh, Pos
from .shapes import ShapeKind


class ShapeBuilder(ValueReader):
    """The shapes. ``folder``: where mesh files are found; ``meshes_read``: each mesh
    file's facts read in this parse; ``triangles``: the triangles of the meshes so far."""

    folder: str
    meshes_read: dict
    triangles: int

    def shape_fields(self, st: Tree) -> tuple[dict[str, Tree], Token]:
        """A shape block's keys and its material's name token (required)."""
        kind = str(st.data)
        f = self.fields(st, f"'{kind}' block")
        if "material" not in f:
            raise self.error(st, f"{kind} has no 'material'; add material \"name\"")
        return f, f["material"].children[0]

    def read_shape(self, kind: ShapeKind, st: Tree) -> tuple[object, Token, bool]:
        """A block of ``kind``: by its own reader (box, mesh) or from its keys."""
        own = _OWN_READERS.get(kind.keyword)
        return own(self, st) if own else self.shape_of_keys(kind, st)

    def shape_of_keys(self, kind: ShapeKind, st: Tree) -> tuple[object, Token, bool]:
        """A shape whose keys are vectors and numbers, each absent one its class's default:
        a number's problem is refused at the number as written, a vector's at the vector
        with its value (a plane's zero normal)."""
        f, name_tok = self.shape_fields(st)
        default = kind.cls("")
        values = {}
        for key in kind.keys:
            value = getattr(default, key.name)
            if key.syntax == "vector":
                value = self.point_of(f, key.name, value)
                problem = key.problem(value) if key.problem else None
                if problem:
                    raise self.error(f[key.name].children[0],
                                     f"{problem}, found {vector_text(value)}")
            elif key.syntax == "number" and key.name in f:
                tok = f[key.name].children[0]
                value = self.number(tok)
                if key.problem:
                    self.refuse(tok, key.problem(value))
            values[key.name] = value
        shape = kind.cls(unquoted(name_tok), **values, pos=pos_of(st))
        return shape, name_tok, kind.without_uv is None

    def box(self, st: Tree) -> tuple[Box, Token, bool]:
        """``box { min <> max <> transform { … } material "m" }``: corners out of order
        are refused at ``max`` (else ``min``); the transform is a marble's."""
        f, name_tok = self.shape_fields(st)
        d = Box("")
        lo, hi = self.point_of(f, "min", d.min), self.point_of(f, "max", d.max)
        problem = rules.box_problem(lo, hi)
        if problem:
            raise self.error(f.get("max") or f["min"], f"{problem}, found min "
                                                       f"{vector_text(lo)} max {vector_text(hi)}")
        steps = self.transform(f["transform"]) if "transform" in f else ()
        return Box(unquoted(name_tok), lo, hi, steps, pos=pos_of(st)), name_tok, False

    def mesh(self, st: Tree) -> tuple[Mesh, Token, bool]:
        """``mesh { file "…" transform { … } smooth B material "m" }``: the file, relative to the
        scene file, is checked at its string — a PLY or OBJ name, then what
        meshes.facts.mesh_facts says of it (a regular file there, within the size limit,
        in the image maps' words; its header; each sentence after ``mesh file 'NAME':``)
        — and its triangles counted toward the scene's limit; the mesh is refused at its
        file string when they pass it, or when it is shaded smooth and the file's normals
        are incomplete (``MeshFacts.normals_problem``). ``smooth``: true or false, refused
        at the word otherwise; not written, None (the file's normals decide)."""
        f, name_tok = self.shape_fields(st)
        if "file" not in f:
            raise self.error(st, "mesh has no 'file'; write mesh { file \"models/vase.ply\" "
                                 "material \"m\" }")
        tok = f["file"].children[0]
        name = unquoted(tok)
        self.file_name(tok, "a mesh")
        if not name.lower().endswith(MESH_FORMATS):
            raise self.error(tok, rules.mesh_format_problem(name))
        path = os.path.normpath(os.path.join(self.folder, name))
        facts = self.meshes_read.get(path)       # a file used by several meshes: read once
        if facts is None:
            from mimarble.meshes.facts import mesh_facts     # here: only meshes need it
            try:
                facts = self.meshes_read[path] = mesh_facts(path)
            except MeshFileError as e:
                raise self.error(tok, f"mesh file '{rules.shortened(name, 256)}': {e}") from None
        self.triangles += facts.triangles
        problem = rules.mesh_triangles_problem(self.triangles)
        if problem:
            raise self.error(tok, problem)
        steps = self.transform(f["transform"]) if "transform" in f else ()
        smooth = self.switch(f["smooth"].children[0], "smooth") if "smooth" in f else None
        if smooth and facts.normals_problem:
            raise self.error(tok, f"mesh file '{rules.shortened(name, 256)}': "
                                  f"{facts.normals_problem}")
        # Its position is the file string's, where every error about the file points.
        mesh = Mesh(unquoted(name_tok), name, path, steps, pos=Pos(tok.line, tok.column),
                    digest=facts.digest, smooth=smooth)
        return mesh, name_tok, facts.has_uv


#: The kinds read by a reader of their own, not from their keys alone.
_OWN_READERS = {"box": ShapeBuilder.box, "mesh": ShapeBuilder.mesh}
