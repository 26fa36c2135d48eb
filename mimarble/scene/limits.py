"""The scene language's limits, stated once: what a scene (and an image map) may hold.

Each limit is enforced at the edge — when the file is opened, when the image map's
header is read, when the parser meets the statement or the channel past it, when a
model is constructed in Python — before anything in proportion to it is allocated, and
each is refused in one sentence (a :class:`~mimarble.scene.SceneError` at its
FILE:LINE:COL, or a ValueError from a constructor). docs/scene-language.md ("Limits")
says why each has its value, with what was measured.

Standard library only (the scene package's rule); the marble's own limits are its
parameter table's.
"""

from __future__ import annotations

from mimarble.contract import FLT_MAX, FLT_MIN_NORMAL
from mimarble.meshes.limits import MAX_MESH_BYTES, MAX_MESH_TRIANGLES
from mimarble.parameters import BY_NAME

# FLT_MAX, FLT_MIN_NORMAL: float32's (contract.py); MAX_MESH_TRIANGLES, MAX_MESH_BYTES:
# what a mesh file may hold (meshes/limits.py). Each is stated there, with why.

__all__ = ["LIMITS", "FLT_MAX", "FLT_MIN_NORMAL", "MAX_SCENE_BYTES", "MAX_IMAGE_MAP_PIXELS", "MAX_CHANNEL_DEPTH",
           "MAX_AREA_LIGHT_SIZE", "MAX_CHANNEL_SIZE", "MAX_LIGHTS", "MAX_LIGHT_SAMPLES", "MAX_SPHERES", "MAX_IMAGE_SAMPLES",
           "MAX_PLANES", "MAX_BOXES", "MAX_MESHES", "MAX_MESH_TRIANGLES", "MAX_MESH_BYTES",
           "MAX_TEXTURES"]

#: A scene file's size, bytes (4 MiB). The file is read whole and Lark builds a tree of it,
#: in time and memory that grow with it; the largest scene the other limits allow is a
#: fraction of this.
MAX_SCENE_BYTES = 1 << 22

#: An image map's pixels, width × height (2²⁶: 8192 × 8192), read from its header: a
#: small file can decode into gigabytes (and a large enough map crashed Mitsuba). Below
#: Pillow's own bomb limit, so both renderers refuse alike, in the same sentence.
MAX_IMAGE_MAP_PIXELS = 1 << 26

#: How deep channels nest (a leaf channel is at depth 1; each add, multiply or mix adds
#: one). The parser, the translator and both renderers walk a channel recursively, and
#: Python's stack runs out a few hundred levels down. 64 is far past any written by hand.
MAX_CHANNEL_DEPTH = 64

#: Channels in one channel, expanded: a named texture counts again at each use. A texture
#: of textures doubles at each level (``texture "b" { add { texture "a" texture "a" } }``),
#: so sixty lines could stand for 2⁶⁰ channels; the model's hashing and comparison, and
#: the renderers' walks, visit each use. 4096 is far past any written by hand.
MAX_CHANNEL_SIZE = 4096

#: Lights per scene. The whitted integrator unrolls its loop over the lights into the
#: kernel, whose compilation grows faster than linearly with them. An area light counts
#: as one: its samples are a loop in the kernel (traced once, whatever their number).
MAX_LIGHTS = 1024

#: Samples of one area light (``area { … samples N }``, N = n², 32 × 32 at most). Each is
#: a shadow ray per shaded point: render time grows with them (the kernel does not).
MAX_LIGHT_SAMPLES = 1024

#: An area light's radius and edge lengths: squared (distances to its samples, the
#: rectangle's area) they stay finite in float32 (3.4e38); past it the light would
#: vanish into overflow, silently black.
MAX_AREA_LIGHT_SIZE = 1e18

#: Spheres per scene: parse time and render memory grow with them; 10 000 stay within
#: seconds and a gigabyte.
MAX_SPHERES = 10_000

#: Planes per scene. Each is a disk reaching far past the scene (geometry.plane_disk) that
#: every ray is tested against; a scene needs a floor and a wall or two, not hundreds.
MAX_PLANES = 64

#: Boxes per scene: as spheres, parse time and render memory grow with them.
MAX_BOXES = 10_000

#: Mesh statements per scene (each a file read, and a shape in Mitsuba's scene).
MAX_MESHES = 256

#: Named textures per scene (``texture "NAME" { … }``).
MAX_TEXTURES = 10_000

#: width × height × samples of the image (2²⁸, about 4 GiB of float32 RGBA samples), so
#: that a typo cannot exhaust memory.
MAX_IMAGE_SAMPLES = 1 << 28

#: The limits by name (``mimarble.scene.LIMITS``; documented in docs/scene-language.md).
LIMITS = {
    "image_size": (1, 16384),                       # width and height, pixels
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
