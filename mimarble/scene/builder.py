"""The scene builder: Lark's tree -> the frozen :class:`~mimarble.scene.model.Scene`, one
statement at a time through its kind's reader (build_view, build_materials, build_shapes),
then the checks across statements (materials named, image maps on shapes with (u, v),
area lights against the camera).

It checks what the grammar does not: duplicates, arity, ranges, names, references, how
deep channels nest; named textures are resolved into the channels they name (a texture
defined anywhere in the file, none using itself), and mesh files' facts read (meshes/).
The values are checked by the rules the model's constructors apply (rules.py), here with
the token's position; a marble's by the parameter table's own rules (``Parameter.check``).
"""

from __future__ import annotations

import os

from lark import Token, Tree

from mimarble.scene import rules
from .build_materials import MaterialBuilder
from .build_shapes import ShapeBuilder
from .build_values import keyword_of, unquoted
from .build_view import ViewBuilder
from .model import Camera, FrozenMap, Image, ImageChannel, Light, Material, Scene, SphereArea, walk
from .shapes import BY_KEYWORD, SHAPE_KINDS, kind_of

__all__ = ["SceneBuilder", "image_maps_of"]


def image_maps_of(materials) -> tuple:
    """Every distinct image map of ``materials`` (Scene.image_maps' walk; a channel holds at
    most LIMITS["max_channel_size"] channels, so walking every use of a texture is bounded)."""
    return tuple(dict.fromkeys(c for m in materials for ch in m.channels().values()
                               for c in walk(ch) if isinstance(c, ImageChannel)))


class SceneBuilder(ViewBuilder, MaterialBuilder, ShapeBuilder):
    """One parse's builder: :meth:`scene` walks the statements."""

    def __init__(self, text: str, filename: str, source: str | None = None) -> None:
        self.text = text
        self.filename = filename
        # Image maps and meshes are found relative to the scene file (else the working
        # directory).
        self.folder = os.path.dirname(os.path.abspath(source)) if source else os.getcwd()
        self.meshes_read: dict = {}      # mesh file path -> its MeshFacts, in this parse
        #: The texture definitions, by name (the first of a name), and the channels of
        #: those resolved so far.
        self.definitions: dict[str, Tree] = {}
        self.resolved: dict[str, object] = {}
        #: The triangles of the meshes read so far (the limit is on their sum).
        self.triangles = 0

    # -- statements -----------------------------------------------------------
    def scene(self, tree: Tree, source: str | None) -> Scene:
        """The scene of ``tree``: each statement read by its kind's reader, in file order
        (textures and materials may be used before they are defined), then the checks
        across statements."""
        once: dict[str, Tree] = {}      # image, camera, ambient, environment: one each
        image, camera, ambient, environment = Image(), Camera(), (0.0, 0.0, 0.0), None
        lights: list[tuple[Light, Tree]] = []           # each light, with its statement
        materials: dict[str, tuple[Material, Token]] = {}  # each, with its name token
        # Every shape, in file order: (shape, its material's name token, whether it has
        # texture coordinates for image maps).
        shapes: list[tuple[object, Token, bool]] = []
        for st in tree.children:
            if st.data == "texture_definition":
                self.definitions.setdefault(unquoted(st.children[0]), st)
        for st in tree.children:
            kind = st.data
            if kind in ("image", "camera", "ambient_light", "environment"):
                self.once(st, once)
            if kind == "image":
                image = self.image(st)
            elif kind == "camera":
                camera = self.camera(st)
            elif kind == "ambient_light":
                ambient = self.color(st.children[0], "ambient")
            elif kind == "environment":
                environment = self.environment(st)
            elif kind == "light":
                lights.append((self.light(st), st))
            elif kind == "material":
                self.add_material(st, materials)
            elif kind == "texture_definition":
                self.texture_definition(st)
            elif kind in BY_KEYWORD:
                shapes.append(self.read_shape(BY_KEYWORD[kind], st))
            else:  # pragma: no cover - grammar and builder out of step
                raise self.error(st, f"internal error: unhandled statement {kind}")
        materials = {name: mat for name, (mat, _) in materials.items()}
        self.check_shapes(shapes, materials)
        self.check_area_lights(lights, camera)
        of = {kind.plural: tuple(s for s, _, _ in shapes if isinstance(s, kind.cls))
              for kind in SHAPE_KINDS}
        return Scene(
            image=image,
            camera=camera,
            ambient=ambient,
            lights=tuple(light for light, _ in lights),
            materials=FrozenMap(materials),
            **of,
            textures=FrozenMap((name, self.resolved[name]) for name in self.definitions),
            environment=environment,
            source=source,
        )

    def once(self, st: Tree, once: dict[str, Tree]) -> None:
        """``image``, ``camera``, ``ambient``, ``environment``: a second one is refused at its keyword."""
        kw = keyword_of(st)
        if kw in once:
            first = once[kw].meta
            raise self.error(
                st,
                f"duplicate '{kw}' statement (first given at {first.line}:{first.column}); "
                f"a scene has at most one",
            )
        once[kw] = st

    def add_material(self, st: Tree, materials: dict[str, tuple[Material, Token]]) -> None:
        """A ``material`` statement, read into ``materials``; a second of a name is refused
        at its name."""
        name_tok = st.children[0]
        mat = self.material(st)
        if mat.name in materials:
            first = materials[mat.name][1]
            raise self.error(
                name_tok,
                f"duplicate material {rules.shortened(name_tok)} (first defined at "
                f"{first.line}:{first.column})",
            )
        materials[mat.name] = (mat, name_tok)

    # -- across statements ------------------------------------------------------
    def check_shapes(self, shapes, materials: dict[str, Material]) -> None:
        """Each shape's material is defined, and has no image map on a shape without
        texture coordinates; refused at the material's name in the shape."""
        imaged = {m.name for m in materials.values() if image_maps_of([m])}
        for shape, name_tok, has_uv in shapes:
            problem = rules.unknown_material(shape.material, materials)
            if problem:
                raise self.error(name_tok, problem)
            if not has_uv and shape.material in imaged:
                raise self.error(name_tok, rules.image_map_uv_problem(
                    shape.material, kind_of(shape).without_uv))

    def check_area_lights(self, lights, camera: Camera) -> None:
        """A spherical area light does not enclose the camera (wherever the camera
        statement is); refused at its radius."""
        for light, st in lights:
            if isinstance(light.area, SphereArea):
                problem = rules.area_light_enclosure_problem(light.position, light.area.radius,
                                                             camera.eye, camera.lookat)
                if problem:
                    area = self.fields(st, "'light' block")["area"]
                    raise self.error(self.fields(area, "'area' block")["radius"].children[0],
                                     problem)
