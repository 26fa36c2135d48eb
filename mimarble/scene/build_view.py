"""The scene builder's ``image``, ``camera``, ``light`` (with a light's ``area``) and
``environment`` statements: their keys read and checked together (a view, a light's
samples, an environment's file or colour), at the key at fault.
"""

from __future__ import annotations

from lark import Tree

from mimarble.scene import rules
from .build_values import ValueReader, pos_of, source_of
from .environment_header import environment_file_sentence
from .limits import MAX_IMAGE_SAMPLES
from .model import AREA_SAMPLES, Camera, Environment, Image, Light, Pos, RectangleArea, SphereArea


class ViewBuilder(ValueReader):
    """The image, the camera, the lights and the environment."""

    def image(self, st: Tree) -> Image:
        f = self.fields(st, "'image' block")
        lo, hi = rules.IMAGE_SIZE
        d = Image()
        width = self.integer(f["width"].children[0], "width", lo, hi) if "width" in f else d.width
        height = self.integer(f["height"].children[0], "height", lo, hi) if "height" in f else d.height
        samples = d.samples
        if "samples" in f:
            tok = f["samples"].children[0]
            # Any count: path mode takes any; whitted mode and the reference tracer need a
            # perfect square (their n×n grid) and say so when asked to render it.
            samples = self.integer(tok, "samples", 1, MAX_IMAGE_SAMPLES)
        problem = rules.image_samples_problem(width, height, samples)
        if problem:
            raise self.error(f.get("samples") or f.get("width") or f.get("height") or st, problem)
        background = self.color(f["background"].children[0], "background") if "background" in f else d.background
        return Image(width, height, samples, background, pos=pos_of(st),
                     source=source_of(st, f))

    def camera(self, st: Tree) -> Camera:
        f = self.fields(st, "'camera' block")
        d = Camera()
        eye = self.point(f["eye"].children[0], "eye") if "eye" in f else d.eye
        lookat = self.point(f["lookat"].children[0], "lookat") if "lookat" in f else d.lookat
        up = self.point(f["up"].children[0], "up") if "up" in f else d.up
        fov = d.fov
        if "fov" in f:
            tok = f["fov"].children[0]
            fov = self.number(tok)
            self.refuse(tok, rules.fov_problem(fov))
        problem = rules.view_problem(eye, lookat)
        if problem:
            raise self.error(f.get("lookat") or f.get("eye") or st, problem)
        problem = rules.up_problem(eye, lookat, up)
        if problem:
            raise self.error(f.get("up") or st, problem)
        return Camera(eye, lookat, up, fov, pos=pos_of(st), source=source_of(st, f))

    def light(self, st: Tree) -> Light:
        f = self.fields(st, "'light' block")
        if "position" not in f:
            raise self.error(st, "light has no 'position'")
        position = self.point(f["position"].children[0], "position")
        color = self.color(f["color"].children[0], "light color") if "color" in f else Light(position).color
        area = self.area(f["area"]) if "area" in f else None
        return Light(position, color, area, pos=pos_of(st), source=source_of(st, f))

    def area(self, st: Tree) -> RectangleArea | SphereArea:
        """``area { axis1 <> axis2 <> samples N }`` (a rectangle) or ``area { radius R
        samples N }`` (a sphere); samples a square n² within the limit, at the number."""
        f = self.fields(st, "'area' block")
        edges = [f[k] for k in ("axis1", "axis2") if k in f]
        if edges and "radius" in f:
            second = max(edges + [f["radius"]], key=lambda t: (t.meta.line, t.meta.column))
            raise self.error(second, "an area light is a rectangle (axis1 and axis2) or a "
                                     "sphere (radius), not both")
        if not edges and "radius" not in f:
            raise self.error(st, "area needs axis1 and axis2 (a rectangle) or radius (a "
                                 "sphere), e.g. area { radius 0.5 samples 16 }")
        samples = AREA_SAMPLES
        if "samples" in f:
            tok = f["samples"].children[0]
            samples = self.number(tok)
            self.refuse(tok, rules.light_samples_problem(samples))
        if "radius" in f:
            tok = f["radius"].children[0]
            radius = self.number(tok)
            self.refuse(tok, rules.area_radius_problem(radius))
            return SphereArea(radius, samples, pos=pos_of(st))
        if len(edges) < 2:
            missing = "axis2" if "axis1" in f else "axis1"
            raise self.error(st, f"a rectangular area light needs both axis1 and axis2 "
                                 f"(no '{missing}')")
        axis1, axis2 = (self.point(f[k].children[0], k) for k in ("axis1", "axis2"))
        problem = rules.area_axes_problem(axis1, axis2)
        if problem:
            at = ("axis1" if not any(axis1) else "axis2") if "zero" in problem else \
                "axis1" if "axis1 is too small" in problem else "axis2"
            raise self.error(f[at], problem)
        return RectangleArea(axis1, axis2, samples, pos=pos_of(st))

    def environment(self, st: Tree) -> Environment:
        """``environment { file "…" intensity X rotate <> }`` or ``environment { color <>
        intensity X }``: exactly one of file and color (refused at the second, or at the
        keyword when neither), rotate with a file only; the file found relative to the
        scene file and its header checked (environment_header.py) at its string."""
        f = self.fields(st, "'environment' block")
        problem = rules.environment_problem("file" in f, "color" in f, False)
        if problem:
            both = [f[k] for k in ("file", "color") if k in f]
            raise self.error(max(both, key=lambda t: (t.meta.line, t.meta.column))
                             if both else st, problem)
        if "rotate" in f and "color" in f:
            raise self.error(f["rotate"], rules.environment_problem(False, True, True))
        intensity = 1.0
        if "intensity" in f:
            tok = f["intensity"].children[0]
            intensity = self.number(tok)
            self.refuse(tok, rules.intensity_problem(intensity))
        rotate = self.point(f["rotate"].children[0], "rotate") if "rotate" in f else (0.0,) * 3
        if "color" in f:
            color = self.color(f["color"].children[0], "environment color")
            return Environment(color=color, intensity=intensity, pos=pos_of(st),
                               source=source_of(st, f))
        tok = f["file"].children[0]
        name, path = self.found_file(tok, "an environment", environment_file_sentence)
        return Environment(file=name, path=path, intensity=intensity, rotate=rotate,
                           pos=Pos(tok.line, tok.column), source=source_of(st, f))
