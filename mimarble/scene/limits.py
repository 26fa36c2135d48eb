"""The scene language's limits, one record each: its value, how the docs show it and why.

Each limit is enforced at the edge — when the file is opened, when the image map's
header is read, when the parser meets the statement or the channel past it, when a
model is constructed in Python — before anything in proportion to it is allocated, and
each is refused in one sentence (a :class:`~mimarble.scene.SceneError` at its
FILE:LINE:COL, or a ValueError from a constructor). The reasons are written here only:
docs/scene-language.md's table ("Limits") is generated from :data:`RECORDS`
(``./go python scripts/limits_table.py``; a test compares).

Standard library only (the scene package's rule); the marble's own limits are its
parameter table's, the float32 range is :mod:`mimarble.contract`'s.
"""

from __future__ import annotations

from dataclasses import dataclass

from mimarble.contract import FLT_MAX, FLT_MIN_NORMAL
from mimarble.meshes import limits as mesh_limits
from mimarble.parameters import BY_NAME

__all__ = ["Limit", "RECORDS", "BY_KEY", "IMAGE_SIZE", "markdown_table",
           "LIMITS", "FLT_MAX", "FLT_MIN_NORMAL", "MAX_SCENE_BYTES", "MAX_IMAGE_MAP_PIXELS", "MAX_CHANNEL_DEPTH",
           "MAX_AREA_LIGHT_SIZE", "MAX_CHANNEL_SIZE", "MAX_LIGHTS", "MAX_LIGHT_SAMPLES", "MAX_SPHERES", "MAX_IMAGE_SAMPLES",
           "MAX_PLANES", "MAX_BOXES", "MAX_MESHES", "MAX_MESH_TRIANGLES", "MAX_MESH_BYTES",
           "MAX_TEXTURES"]

# FLT_MAX and FLT_MIN_NORMAL (mimarble.contract): the float32 range. Messages print them
# with every digit of their double (repr): rounded, "3.4e38" reads as if 3.4028235e38
# (FLT_MAX to 8 digits, past it) were within.


@dataclass(frozen=True)
class Limit:
    """One limit: ``key`` its name in :data:`LIMITS` (None for a rule without a number),
    ``what`` it limits, ``value``, ``shown`` its value as the docs write it, and
    ``reason``: why it has that value, with what was measured, and where it is refused."""

    key: str | None
    what: str
    value: object
    shown: str
    reason: str

    def markdown_row(self) -> str:
        value = f"{self.shown}; `{self.key}`" if self.key else self.shown
        return f"| {self.what} | {value} | {self.reason} |"


#: The limits, in the order of the docs' table (which says where they were measured).
RECORDS: tuple[Limit, ...] = (
    Limit('max_scene_bytes', 'scene file size', 1 << 22,
          '4 MiB (4 194 304 bytes)',
          'The file is read whole and Lark builds a tree of it: 4.5 MB of dense statements took 14 s and '
          '320 MB to parse. The largest scene the other limits allow (10 000 spheres, 1024 lights) is about'
          ' 0.7 MB written out. A larger file is refused from its size, and no more than the limit and one '
          'byte is ever read (`render /dev/zero` read 4 GB). `parse(text)` refuses longer text alike.'),
    Limit(None, 'regular files only', None,
          'scene files, image maps and mesh files',
          'A FIFO blocks a reader until a writer comes, a device such as `/dev/zero` never ends: anything '
          'but a regular file (or a directory, which is said as such) is refused from `os.stat` without '
          'being opened for a blocking read.'),
    Limit('max_image_map_pixels', 'image-map pixels', 1 << 26,
          '8192 × 8192 = 2²⁶ = 67 108 864, width × height from the header (PNG: IHDR; JPEG: its frame '
          'header, SOFn)',
          'A small file can decode into gigabytes: an 8192² map rendered at 0.9 GB through Mitsuba and 2.1 '
          'GB through the reference tracer (float64 texels); 16384² took 3.1 GB in Mitsuba, and 40000² (a '
          "4.7 MB PNG) crashed it. Below Pillow's own bomb limit (89 M pixels), and checked by the same "
          "header rule in the parser, in the reference tracer's loader and in the Mitsuba path's image "
          'check, so both renderers refuse alike, at the `file` string, in the same sentence. An '
          "environment's file is held to the same limit (OpenEXR: its dataWindow; Radiance HDR: its "
          'resolution line), by scene/environment_header.py.'),
    Limit(None, 'complete image maps', None,
          'a PNG ends with its IEND chunk, a JPEG with its EOI marker (FF D9), then zero bytes only',
          'libjpeg decodes a truncated JPEG with a warning and the missing rows grey, where Pillow refuses '
          "it; so a truncated map is refused while parsing, for both: `image file 'x.jpg' cannot be "
          'decoded: a truncated JPEG: …`.'),
    Limit('max_channel_depth', 'channel nesting depth', 64,
          '64 levels (a colour, marble or image map is level 1; each `add`, `multiply` or `mix` around it '
          'one more)',
          'The parser, the translator and both renderers walk a channel recursively; about 400 levels ran '
          "out of Python's stack. Refused at the keyword of the first channel past the limit, as the parser"
          ' reads it (100 000 levels: at once). 64 compiles in 2 s in whitted mode.'),
    Limit('max_channel_size', 'channel size', 4096,
          '4096 channels in one channel, a named texture counted again at each use',
          'A texture of textures doubles at each level (`texture "b" { add { texture "a" texture "a" } }`),'
          " so sixty lines could stand for 2⁶⁰ channels, and the model's hashing and comparison and the "
          "renderers' walks visit every use. Refused at the keyword of the expression that passes it."),
    Limit('max_lights', 'lights per scene', 1024,
          '1024',
          'The whitted integrator unrolls its loop over the lights into the kernel, whose compilation grows'
          ' faster than linearly: 256 lights rendered in 2.5 s, 512 in 7.3 s, 1024 in 31 s at 0.4 GB; 250 '
          '000 took more than 8 GB. Refused at the first `light` too many, before the rest of the file is '
          'parsed. An area light counts as one: its samples are a loop, traced once.'),
    Limit('max_light_samples', 'samples per area light', 1024,
          '1024 (32 × 32)',
          'Each sample is a shadow ray per shaded point: time grows with them, the kernel does not (one '
          'light of 4 or 256 samples traces the same operations). One light of 1024 samples rendered 48×48 '
          '(a sphere on a floor) in 0.02 s warm in whitted mode, in 1.4 s by the reference tracer (a point '
          'light: 0.04 s). Refused at the `samples` number.'),
    Limit('max_area_light_size', 'area light radius, edge lengths', 1e18,
          '1e18',
          "Squared (distances to the samples, the rectangle's area) they stay finite in float32; past it "
          'the light would vanish into overflow, silently black. Refused at the `radius` number or the '
          '`axis2` vector.'),
    Limit('max_spheres', 'spheres per scene', 10_000,
          '10 000',
          '10 000 spheres parsed in 1.7 s and rendered in 4 s at 0.7 GB; 20 000 took 11 s at 1.3 GB, 100 '
          '000 took 88 s at 5 GB. Refused at the first `sphere` too many.'),
    Limit('max_planes', 'planes per scene', 64,
          '64',
          'Each is a disk reaching far past the scene (`plane` above) that every ray is tested against; a '
          'scene needs a floor and a wall or two, not hundreds. Refused at the first `plane` too many.'),
    Limit('max_boxes', 'boxes per scene', 10_000,
          '10 000',
          'As spheres: parse time and render memory grow with them. Refused at the first `box` too many.'),
    Limit('max_meshes', 'meshes per scene', 256,
          '256',
          "Each is a file read while parsing and a shape of its own in Mitsuba's scene. Refused at the "
          'first `mesh` too many.'),
    Limit('max_mesh_triangles', 'mesh triangles', mesh_limits.MAX_MESH_TRIANGLES,
          '2²⁰ = 1 048 576, all the meshes of a scene together (polygons counted as the triangles of their '
          'fans)',
          'The reference tracer holds them in float64 with a bounding-volume hierarchy, about 0.3 GB at the'
          " limit; each file's counts are read from its header, before anything is read past it. Refused at"
          ' the `file` string of the mesh that passes the limit.'),
    Limit('max_mesh_bytes', 'mesh file size', mesh_limits.MAX_MESH_BYTES,
          '256 MiB (268 435 456 bytes)',
          'A million triangles fit in a tenth of it, in any of the PLY or OBJ encodings read; a larger file'
          ' is refused from its size, at its `file` string, before it is read.'),
    Limit('max_textures', 'named textures', 10_000,
          '10 000',
          'Each is a channel kept by name. Refused at the first `texture "NAME" { … }` definition too many '
          '(a `texture "NAME"` used as a channel is no definition and is not counted).'),
    Limit('max_image_samples', 'image samples', 1 << 28,
          'width × height × samples ≤ 2²⁸',
          'About 4 GiB of float32 RGBA samples (see `image` above); checked for scenes built in Python too '
          '(a 30000 × 30000 `Image` is refused). Checked on what renders: `--width`/`--height` with `--spp`'
          ' (`render(width=…, height=…, spp=…)`) are applied together, so `--width 16384 --height 16384 '
          '--spp 1` of a `samples 4` scene is within it (`scene_edits.with_image_size`); one sample more is'
          ' one sentence, exit 2.'),
    Limit('max_abs_number', 'numbers', FLT_MAX,
          f"finite, \\|x\\| ≤ {FLT_MAX!r}",
          'The Mitsuba path is single precision (messages print the limit to every digit: 3.4028235e38, '
          "float32's largest rounded up, is past it). A fov, an area light's radius or axis and "
          "1/mean_free_path must be ≥ 1.1754943508222875e-38 (float32's smallest normal number, "
          "`FLT_MIN_NORMAL`) where they must be > 0: smaller ones are 0 to the renderer. A marble's bounds "
          '(`scale` > 0, `tolerance` ≥ 0) hold for the value and for its float32: `scale 1e-40` is > 0 but '
          '0 in single precision, so it is refused as `scale must be > 0 in single precision (the '
          "renderer's)` — by the parser, the plugin and sweeps alike (they all check with the parameter "
          'table).'),
)
#: The records by key.
BY_KEY: dict[str, Limit] = {record.key: record for record in RECORDS if record.key}

MAX_SCENE_BYTES = BY_KEY["max_scene_bytes"].value
MAX_IMAGE_MAP_PIXELS = BY_KEY["max_image_map_pixels"].value
MAX_CHANNEL_DEPTH = BY_KEY["max_channel_depth"].value
MAX_CHANNEL_SIZE = BY_KEY["max_channel_size"].value
MAX_LIGHTS = BY_KEY["max_lights"].value
MAX_LIGHT_SAMPLES = BY_KEY["max_light_samples"].value
MAX_AREA_LIGHT_SIZE = BY_KEY["max_area_light_size"].value
MAX_SPHERES = BY_KEY["max_spheres"].value
MAX_PLANES = BY_KEY["max_planes"].value
MAX_BOXES = BY_KEY["max_boxes"].value
MAX_MESHES = BY_KEY["max_meshes"].value
MAX_MESH_TRIANGLES = BY_KEY["max_mesh_triangles"].value
MAX_MESH_BYTES = BY_KEY["max_mesh_bytes"].value
MAX_TEXTURES = BY_KEY["max_textures"].value
MAX_IMAGE_SAMPLES = BY_KEY["max_image_samples"].value

#: An image's width and height, pixels (the ``image`` block's keys; docs/scene-language.md).
IMAGE_SIZE = (1, 16384)

#: The limits by name (``mimarble.scene.LIMITS``; documented in docs/scene-language.md).
LIMITS = {
    "image_size": IMAGE_SIZE,                       # width and height, pixels
    "max_image_samples": MAX_IMAGE_SAMPLES,         # width * height * samples
    "octaves": BY_NAME["octaves"].bounds,           # the marble's parameter table
    "ramp_colours": BY_NAME["ramp"].bounds,         # the marble's parameter table
    "max_abs_number": FLT_MAX,                      # float32 max: single precision
    "max_scene_bytes": MAX_SCENE_BYTES,
    "max_image_map_pixels": MAX_IMAGE_MAP_PIXELS,
    "max_channel_depth": MAX_CHANNEL_DEPTH,
    "max_channel_size": MAX_CHANNEL_SIZE,
    "max_lights": MAX_LIGHTS,
    "max_light_samples": MAX_LIGHT_SAMPLES,
    "max_area_light_size": MAX_AREA_LIGHT_SIZE,
    "max_spheres": MAX_SPHERES,
    "max_planes": MAX_PLANES,
    "max_boxes": MAX_BOXES,
    "max_meshes": MAX_MESHES,
    "max_mesh_triangles": MAX_MESH_TRIANGLES,
    "max_mesh_bytes": MAX_MESH_BYTES,
    "max_textures": MAX_TEXTURES,
}

def markdown_table() -> str:
    """The docs' table of limits, one row a record."""
    return "\n".join(["| limit | value | why |", "|---|---|---|", *(r.markdown_row() for r in RECORDS)])

