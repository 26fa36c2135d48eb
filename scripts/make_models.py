"""Write the meshes of scenes/beyond-spheres/models/: a vase (binary PLY) and a chess pawn
(Wavefront OBJ), both surfaces of revolution about the y axis with texture coordinates.

    ./go python scripts/make_models.py [FOLDER]     (default: scenes/beyond-spheres/models)

Each is its profile r(s), y(s), s in [0, 1] from the bottom centre up, turned about +y:
the vertex at profile sample i and angle φ_j = 2π·j/around is (r·cos φ, y, −r·sin φ)
(counter-clockwise seen from +y), with (u, v) = (j/around, 1 − s_i): v = 0 at the top, as
an image's top row (Mitsuba's convention; the OBJ file stores 1 − v, which its loader flips). The seam repeats its vertices (u = 0 and u = 1), so that (u, v) is
continuous on every triangle. The PLY holds float32 numbers, little-endian (Mitsuba warns
that ASCII PLY is slow to read); the OBJ 7 significant digits, which both renderers read as
the same float32 numbers.
"""

from __future__ import annotations

import math
import struct
import sys
from pathlib import Path


def _smooth(a: float, b: float, t: float) -> float:
    """a to b along a smoothstep in t ∈ [0, 1]."""
    t = min(max(t, 0.0), 1.0)
    return a + (b - a) * t * t * (3.0 - 2.0 * t)


def vase_profile(s: float):
    """(r, y) of the vase: a foot, a round belly, a narrow neck and a flared lip; open at
    the top, closed at the bottom (r = 0 at s = 0)."""
    if s < 0.04:                                  # the base disk, from the axis out
        return 0.55 * s / 0.04, 0.0
    t = (s - 0.04) / 0.96
    y = 2.6 * t
    belly = 0.95 * math.exp(-((y - 0.9) / 0.62) ** 2)
    neck = 0.28 + 0.22 * _smooth(0.0, 1.0, (y - 2.15) / 0.45)
    r = max(0.55 * (1.0 - _smooth(0.0, 1.0, y / 0.5)) + belly, neck if y > 1.6 else 0.0)
    r = max(r, 0.3)
    return r, y


def pawn_profile(s: float):
    """(r, y) of a chess pawn: base, collar, tapering body and a ball head, closed at
    both ends."""
    # (y, r) control points, joined piecewise by smoothsteps; the head is a circle.
    points = [(0.0, 0.0), (0.0, 0.62), (0.12, 0.62), (0.18, 0.5), (0.3, 0.46), (0.36, 0.36),
              (1.05, 0.2), (1.12, 0.34), (1.18, 0.34), (1.22, 0.16)]
    head_centre, head_radius = 1.52, 0.32
    body = len(points) - 1
    steps = body + 8                                # 8 of the parameter's steps on the head
    k = s * steps
    if k < body:
        i = int(k)
        (y0, r0), (y1, r1) = points[i], points[i + 1]
        t = k - i
        return _smooth(r0, r1, t), y0 + (y1 - y0) * t
    # The head: from its lower join (angle below the equator) over the top.
    start = math.asin(min(1.0, (head_centre - 1.22) / head_radius))
    angle = -start + (math.pi / 2 + start) * (k - body) / 8.0
    return head_radius * math.cos(angle), head_centre + head_radius * math.sin(angle)


def lathe(profile, rings: int, around: int):
    """(positions, uvs, triangles) of the surface of revolution: vertices per ring
    around + 1 (the seam repeated), two triangles per quad, counter-clockwise from
    outside."""
    positions, uvs, triangles = [], [], []
    for i in range(rings + 1):
        s = i / rings
        r, y = profile(s)
        for j in range(around + 1):
            phi = 2.0 * math.pi * j / around
            positions.append((r * math.cos(phi), y, -r * math.sin(phi)))
            uvs.append((j / around, 1.0 - s))
    width = around + 1
    for i in range(rings):
        for j in range(around):
            a, b = i * width + j, i * width + j + 1
            c, d = a + width, b + width
            triangles.append((a, b, d))
            triangles.append((a, d, c))
    return positions, uvs, triangles


def _number(x: float) -> str:
    return f"{x:.7g}"


def write_ply(path: Path, positions, uvs, triangles) -> None:
    lines = ["ply", "format binary_little_endian 1.0", "comment mimarble scripts/make_models.py",
             f"element vertex {len(positions)}", "property float x", "property float y",
             "property float z", "property float u", "property float v",
             f"element face {len(triangles)}", "property list uchar int vertex_indices",
             "end_header"]
    data = bytearray(("\n".join(lines) + "\n").encode("ascii"))
    for p, uv in zip(positions, uvs):
        data += struct.pack("<5f", *p, *uv)
    for t in triangles:
        data += struct.pack("<B3i", 3, *t)
    path.write_bytes(bytes(data))


def write_obj(path: Path, positions, uvs, triangles) -> None:
    lines = ["# mimarble scripts/make_models.py"]
    lines += ["v " + " ".join(map(_number, p)) for p in positions]
    # OBJ's v runs up the image; Mitsuba's OBJ loader flips it (flip_tex_coords, default
    # true), so that its (u, v) is the one given here.
    lines += [f"vt {_number(u)} {_number(1.0 - v)}" for u, v in uvs]
    lines += ["f " + " ".join(f"{k + 1}/{k + 1}" for k in t) for t in triangles]
    path.write_text("\n".join(lines) + "\n")


def main(folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    write_ply(folder / "vase.ply", *lathe(vase_profile, rings=72, around=96))
    write_obj(folder / "pawn.obj", *lathe(pawn_profile, rings=90, around=72))


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else
         Path(__file__).resolve().parent.parent / "scenes" / "beyond-spheres" / "models")
