"""The scene's value rules, written once for their two callers: the parser and the model.

Each rule takes a value and says what is wrong with it, in the language's words
(``radius must be > 0``), or None. The parser (builder.py) raises the sentence as a
:class:`~mimarble.scene.SceneError` at the token it read, adding ``found`` and the token
as written; the model's constructors (model.py) raise it as a ValueError, adding the
value. So a scene built in Python hears the same sentence as one read from a file.

Standard library only.
"""

from __future__ import annotations

import math
import numbers

from mimarble.contract import DEFAULT_MAX_SPP
from mimarble.parameters import single_precision
from mimarble.runtime.reading import shortened
from .limits import (FLT_MAX, FLT_MIN_NORMAL, LIMITS, MAX_AREA_LIGHT_SIZE, MAX_CHANNEL_DEPTH, MAX_CHANNEL_SIZE,
                     MAX_IMAGE_SAMPLES, MAX_LIGHT_SAMPLES, MAX_LIGHTS,
                     MAX_TEXTURES, MAX_MESH_TRIANGLES)

__all__ = ["number_problem", "integer_problem", "colour_problem", "fov_problem",
           "view_problem", "up_problem", "image_samples_problem", "radius_problem",
           "shininess_problem", "spp_problem", "seed_problem", "material_name_problem", "unknown_material", "count_problem", "too_many",
           "light_samples_problem", "area_axes_problem", "area_radius_problem",
           "area_light_enclosure_problem", "cross",
           "depth_problem", "size_problem", "mean_free_path_problem", "ior_problem", "listed_names", "shortened", "normal_problem",
           "box_problem", "mesh_format_problem", "texture_name_problem",
           "mesh_triangles_problem", "image_map_uv_problem"]


def number_problem(value: float) -> str | None:
    """What is wrong with a number of a scene: not finite, or past float32's range."""
    if not math.isfinite(value):
        return "is not finite"
    if abs(value) > FLT_MAX:
        return f"is too large: the renderer is single precision, |x| <= {FLT_MAX!r}"
    return None


def integer_problem(value: float, what: str, lo: int, hi: int) -> str | None:
    """An integral number in lo..hi (``8``, ``8.0`` and ``8e0`` are all 8)."""
    if not isinstance(value, int) and not float(value).is_integer():
        return f"{what} must be an integer"
    if not lo <= value <= hi:
        return f"{what} must be in {lo}..{hi}"
    return None


def colour_problem(value: float, what: str) -> str | None:
    """A colour component: ≥ 0 (no upper bound: linear RGB, HDR allowed)."""
    return None if value >= 0 else f"{what}: colour components must be >= 0"


def fov_problem(fov: float) -> str | None:
    """The full vertical field of view, in degrees: 0 < fov < 180, and > 0 in single
    precision too (Mitsuba's perspective camera refuses a fov its float32 holds as 0; the
    reference tracer would render it: one rule for both)."""
    if not 0 < fov < 180:
        return "fov must be in (0, 180) degrees"
    if single_precision(fov) == 0:
        return (f"fov must be > 0 in single precision (the renderer's): at least "
                f"{FLT_MIN_NORMAL!r} degrees")
    return None


def _sub(a, b):
    return tuple(y - x for x, y in zip(a, b))


def cross(a, b) -> tuple:
    """a × b, in double precision."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def view_problem(eye, lookat) -> str | None:
    """The camera looks somewhere: eye ≠ lookat (and their distance is finite)."""
    view = _sub(eye, lookat)
    length = math.sqrt(sum(c * c for c in view))
    if length == 0 or not math.isfinite(length):
        return "camera eye and lookat must be different points"
    return None


def up_problem(eye, lookat, up) -> str | None:
    """``up`` is not zero and not parallel to the view direction."""
    view = _sub(eye, lookat)
    view_len = math.sqrt(sum(c * c for c in view))
    up_len = math.sqrt(sum(c * c for c in up))
    cross_len = math.sqrt(sum(c * c for c in cross(up, view)))
    if up_len == 0 or not cross_len > 1e-9 * up_len * view_len:
        return "camera 'up' must not be zero or parallel to the view direction (lookat - eye)"
    return None


def image_samples_problem(width: int, height: int, samples: int) -> str | None:
    """width × height × samples within the sample limit."""
    total = width * height * samples
    if total > MAX_IMAGE_SAMPLES:
        return (f"image too large: width*height*samples = {total} exceeds 2^28 = "
                f"{MAX_IMAGE_SAMPLES}")
    return None


def spp_problem(spp, width: int, height: int) -> str | None:
    """A renderer's samples per pixel for an image of width × height: a whole number ≥ 1
    within the sample limit (Python callers: ``render``, ``reference.render``, sweeps)."""
    if isinstance(spp, bool) or not isinstance(spp, int) or spp < 1:
        return f"spp={shortened(repr(spp), 40)} must be a whole number ≥ 1"
    total = width * height * spp
    if total > MAX_IMAGE_SAMPLES:
        return (f"spp={spp}: {width}x{height} pixels at {spp} spp is {total} samples, more "
                f"than the {MAX_IMAGE_SAMPLES} allowed")
    return None




def default_max_spp(spp: int, max_spp=None):
    """``max_spp`` as given, else adaptive sampling's default for a first pass of ``spp``:
    :data:`DEFAULT_MAX_SPP`, or ``spp`` when that is more (the one rule of
    ``mimarble.render``, ``render_in_passes`` and the command line)."""
    return max(DEFAULT_MAX_SPP, spp) if max_spp is None else max_spp


def adaptive_problem(threshold, max_spp, spp: int, width: int, height: int) -> str | None:
    """Adaptive sampling's two numbers (``mimarble.render``'s ``adaptive`` and ``max_spp``,
    the command line's ``--adaptive`` and ``--max-spp``): a threshold that is a finite
    number > 0 (linear colour units), and a ``max_spp`` that is a perfect square ≥ the
    first pass's ``spp``, within the sample limit (None: only the threshold is checked)."""
    if isinstance(threshold, bool) or not isinstance(threshold, numbers.Real) \
            or not 0.0 < float(threshold) < math.inf:
        return f"adaptive={shortened(repr(threshold), 40)} must be a finite number > 0 " \
               f"(the estimated error, in linear colour units, above which a pixel is refined)"
    if max_spp is None:
        return None
    if isinstance(max_spp, bool) or not isinstance(max_spp, numbers.Integral) or max_spp < 1 \
            or math.isqrt(int(max_spp)) ** 2 != max_spp:
        return f"max_spp={shortened(repr(max_spp), 40)} must be a perfect square ≥ 1 " \
               f"(1, 4, 9, 16, …): the samples are an n×n grid"
    if max_spp < spp:
        return f"max_spp={max_spp} is below the first pass's {spp} spp"
    problem = spp_problem(int(max_spp), width, height)      # "spp=N: …"
    return None if problem is None else "max_" + problem


def seed_problem(seed) -> str | None:
    """A sampler seed: a whole number in 0..2³²−1 (Mitsuba's seeds are 32-bit)."""
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2 ** 32:
        return f"seed={shortened(repr(seed), 40)} must be a whole number in 0..{2 ** 32 - 1}"
    return None


def radius_problem(radius: float) -> str | None:
    return None if radius > 0 else "radius must be > 0"


def _too_small(what: str) -> str:
    return (f"{what} is too small: below {FLT_MIN_NORMAL!r} (float32's smallest normal "
            f"number) it is 0 in single precision (the renderer's)")


def area_radius_problem(radius: float) -> str | None:
    """A spherical area light's radius: > 0, > 0 in single precision too, and within
    :data:`MAX_AREA_LIGHT_SIZE`."""
    if radius > MAX_AREA_LIGHT_SIZE:
        return (f"an area light's radius must be at most {MAX_AREA_LIGHT_SIZE:g} (squared, "
                f"it must stay finite in single precision)")
    if radius > 0 and single_precision(radius) == 0:
        return _too_small("an area light's radius")
    return radius_problem(radius)


def area_light_enclosure_problem(position, radius: float, eye, lookat) -> str | None:
    """A spherical area light that encloses the camera's eye or look-at point: whitted mode
    and the reference light what it encloses (the light's samples face each shaded point),
    path mode does not (Mitsuba's sphere emits outwards, and its black surface hides what
    is inside from an eye outside): refused, one rule for every renderer."""
    for name, point in (("eye", eye), ("lookat", lookat)):
        distance = math.dist(position, point)
        if radius >= distance:
            return (f"an area light's sphere encloses the camera's {name} (radius {radius:g}, "
                    f"the {name} {distance:.6g} from its centre): a spherical light lights "
                    f"outwards only in path mode, so what it encloses would be dark there; "
                    f"keep the light outside the scene")
    return None


def intensity_problem(intensity: float) -> str | None:
    """An environment's intensity: a scale of its radiance, ≥ 0."""
    return None if intensity >= 0 else "intensity must be >= 0"


def environment_problem(has_file: bool, has_color: bool, has_rotate: bool) -> str | None:
    """An environment is an image (``file``) or a uniform ``color``, exactly one; only an
    image turns (``rotate``)."""
    if has_file == has_color:
        return ("an environment is an image or a colour: give exactly one of file and color, "
                + ("found both" if has_file else 'e.g. environment { file "sky.exr" }'))
    if has_rotate and has_color:
        return "rotate turns an environment image; a color is the same in every direction"
    return None


def shininess_problem(shininess: float) -> str | None:
    return None if shininess > 0 else "shininess must be > 0"


def light_samples_problem(samples: float) -> str | None:
    """An area light's samples: a whole n² (an n×n grid of stratum centres) in
    1..:data:`MAX_LIGHT_SAMPLES`."""
    problem = integer_problem(samples, "samples", 1, MAX_LIGHT_SAMPLES)
    if problem and "must be in" in problem:
        return (f"an area light takes 1..{MAX_LIGHT_SAMPLES} samples (each is a shadow ray "
                f"per shaded point; docs/scene-language.md, Limits)")
    if problem:
        return problem
    if math.isqrt(int(samples)) ** 2 != samples:
        return ("samples must be a perfect square n·n (1, 4, 9, 16, …): an area light is "
                "sampled on an n×n grid")
    return None


def area_axes_problem(axis1, axis2) -> str | None:
    """A rectangular area light's edges: neither zero, nor zero in single precision (every
    number below float32's smallest normal one: "too small"), not parallel (they span a
    parallelogram of non-zero area). Lengths by ``math.hypot``, which does not underflow:
    an axis of 1e-170 is tiny, not zero."""
    spanned = cross(axis1, axis2)
    lengths = [math.hypot(*v) for v in (axis1, axis2)]
    if min(lengths) == 0:
        return "an area light's axis1 and axis2 must not be zero"
    for name, axis in (("axis1", axis1), ("axis2", axis2)):
        if not any(single_precision(c) for c in axis):
            return _too_small(f"an area light's {name}")
    if max(lengths) > MAX_AREA_LIGHT_SIZE:
        return (f"an area light's axis1 and axis2 must be at most {MAX_AREA_LIGHT_SIZE:g} "
                f"long (squared, they must stay finite in single precision)")
    if not math.hypot(*spanned) > 1e-6 * lengths[0] * lengths[1]:
        return "an area light's axis1 and axis2 must not be parallel (they span its rectangle)"
    return None


def material_name_problem(name: str) -> str | None:
    return None if name else "a material name must not be empty"


def listed_names(names, most: int = 10) -> str:
    """``"a", "b"`` …: at most ``most`` names, each shortened, then how many more."""
    names = list(names)
    shown = ", ".join(f'"{shortened(n)}"' for n in names[:most]) or "none"
    return shown + (f" and {len(names) - most} more" if len(names) > most else "")


def unknown_material(name: str, materials) -> str | None:
    """A sphere's material is one of the scene's."""
    if name in materials:
        return None
    return f'unknown material "{shortened(name)}" (defined: {listed_names(materials)})'


_COUNTS = {"light": (MAX_LIGHTS, "the whitted integrator unrolls its loop over the lights"),
           "texture": (MAX_TEXTURES, "each is a channel kept by name")}


def count_problem(kind: str, count: int) -> str | None:
    """Lights and named textures per scene, within their limits (``kind``: light,
    texture; a shape's count is its kind's, shapes.py)."""
    most, why = _COUNTS[kind]
    return too_many(f"{kind}s", count, most, why)


def too_many(plural: str, count: int, most: int, why: str) -> str | None:
    """At most ``most`` of a thing (``plural``) per scene, because ``why``."""
    if count <= most:
        return None
    return f"too many {plural}: a scene holds at most {most} ({why}; docs/scene-language.md, Limits)"


def size_problem(count: int) -> str | None:
    """A channel holds at most :data:`MAX_CHANNEL_SIZE` channels, each use of a named
    texture counted again."""
    if count <= MAX_CHANNEL_SIZE:
        return None
    return (f"channel too large: at most {MAX_CHANNEL_SIZE} channels, counting a named "
            f"texture again at each use (this one holds {count})")


def mean_free_path_problem(value: float) -> str | None:
    """A subsurface's mean free path (where its density is 1), scene units: > 0, and not so
    small that its extinction 1/mean_free_path leaves float32's range."""
    if not value > 0:
        return "mean_free_path must be > 0 (scene units)"
    if 1.0 / value > FLT_MAX:
        return (f"mean_free_path is too small: its extinction 1/mean_free_path passes "
                f"{FLT_MAX!r}")
    if single_precision(1.0 / value) == 0:
        return (f"mean_free_path is too large: its extinction 1/mean_free_path is 0 in single "
                f"precision (the renderer's) past {1.0 / FLT_MIN_NORMAL!r}")
    return None


def ior_problem(value: float) -> str | None:
    """A subsurface boundary's relative index of refraction: > 0."""
    return None if value > 0 else "ior must be > 0 (the index inside over outside)"


def normal_problem(normal) -> str | None:
    """A plane's normal: not zero (nor so small that its length underflows)."""
    length = math.sqrt(sum(c * c for c in normal))
    return None if length > 1e-30 and math.isfinite(length) else "a plane's normal must not be zero"


def box_problem(lo, hi) -> str | None:
    """A box's corners: ``min`` below ``max`` on every axis."""
    if all(a < b for a, b in zip(lo, hi)):
        return None
    return "a box's min must be below its max on every axis (x, y and z)"


def mesh_format_problem(name: str) -> str:
    """The sentence for a mesh file that is neither PLY nor OBJ (by its name's ending)."""
    return (f"a mesh file is PLY (.ply) or Wavefront OBJ (.obj), found "
            f"{shortened(repr(name))}")


def texture_name_problem(name: str) -> str | None:
    """A texture's name: the material name rule, in a texture's words."""
    problem = material_name_problem(name)
    return problem and problem.replace("material", "texture")


def mesh_triangles_problem(total: int) -> str | None:
    """The triangles of all the meshes of a scene, together, within
    :data:`MAX_MESH_TRIANGLES`."""
    if total <= MAX_MESH_TRIANGLES:
        return None
    return (f"too many triangles: the meshes of a scene hold at most {MAX_MESH_TRIANGLES} "
            f"together, these {total} (the reference tracer keeps them all in double "
            f"precision; docs/scene-language.md, Limits)")


def image_map_uv_problem(material: str, shape: str) -> str:
    """The sentence for a material holding an image map on a shape without texture
    coordinates (``shape``: ``a plane``, ``a box``, ``this mesh's file``)."""
    return (f'material "{shortened(material)}" holds an image map, which is read at texture '
            f"coordinates (u, v), and {shape} has none: image maps go on spheres and on "
            f"meshes whose file has texture coordinates")


def depth_problem(depth: int) -> str | None:
    """Channels nested at most :data:`MAX_CHANNEL_DEPTH` deep."""
    if depth <= MAX_CHANNEL_DEPTH:
        return None
    return (f"channels nested too deep: at most {MAX_CHANNEL_DEPTH} levels "
            f"(this one is at level {depth})")


#: The bounds of the image's width and height (the integer rule's, for both callers).
IMAGE_SIZE: tuple[int, int] = LIMITS["image_size"]
