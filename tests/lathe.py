"""A lathe vase for the smooth-mesh tests and benchmark (issue 42): a profile turned about
+y, written as PLY (binary, with or without vertex normals) or OBJ (with or without vn).

The profile is r(y) = 0.35 + 0.45·sin(π·(y − 0.05)/1.9) on y ∈ [0.05, 1.95], clamped: a
round belly between a narrow foot and neck. Vertex j of ring i lies at angle
φ_j = 2π·j/around, (r·cos φ, y, −r·sin φ), and its exact normal, from the profile's
derivative, is (y′·cos φ, −r′, −y′·sin φ)/|…| (outward; the triangles wind
counter-clockwise seen from outside, so their cross products point out too). The ring
closes on itself (no repeated seam vertex). NumPy and the standard library only.
"""

import struct

import numpy as np

BODY = (0.05, 1.95)


def radius(y):
    t = np.clip((np.asarray(y, dtype=np.float64) - BODY[0]) / (BODY[1] - BODY[0]), 0.0, 1.0)
    return 0.35 + 0.45 * np.sin(np.pi * t)


def slope(y):
    """dr/dy (0 outside the body)."""
    y = np.asarray(y, dtype=np.float64)
    t = (y - BODY[0]) / (BODY[1] - BODY[0])
    inside = (t > 0.0) & (t < 1.0)
    return np.where(inside, 0.45 * np.pi / (BODY[1] - BODY[0]) * np.cos(np.pi * t), 0.0)


def vase(rings: int = 24, around: int = 32):
    """(positions (V, 3), exact normals (V, 3), triangles (T, 3)) of the vase, y from 0 to 2."""
    y = np.linspace(0.0, 2.0, rings + 1)
    phi = 2.0 * np.pi * np.arange(around) / around
    r, dr = radius(y)[:, None], slope(y)[:, None]
    c, s = np.cos(phi)[None, :], np.sin(phi)[None, :]
    positions = np.stack(np.broadcast_arrays(r * c, y[:, None] + 0 * c, -r * s), -1).reshape(-1, 3)
    normals = np.stack(np.broadcast_arrays(c, -dr + 0 * c, -s), -1).reshape(-1, 3)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    triangles = []
    for i in range(rings):
        for j in range(around):
            a, b = i * around + j, i * around + (j + 1) % around
            triangles += [(a, b, b + around), (a, b + around, a + around)]
    return positions, normals, np.array(triangles, dtype=np.int64)


def write_ply(path, positions, triangles, normals=None):
    """A binary little-endian PLY: x y z [nx ny nz] as float, faces as uchar/int lists."""
    names = ["x", "y", "z"] + (["nx", "ny", "nz"] if normals is not None else [])
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(positions)}"]
    header += [f"property float {n}" for n in names]
    header += [f"element face {len(triangles)}", "property list uchar int vertex_indices",
               "end_header"]
    columns = [positions] + ([normals] if normals is not None else [])
    body = np.concatenate(columns, axis=1).astype("<f4").tobytes()
    faces = b"".join(struct.pack("<B3i", 3, *map(int, t)) for t in triangles)
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode("ascii") + body + faces)
    return str(path)


def write_obj(path, positions, triangles, normals=None, uv=False):
    """An OBJ: v lines, vt lines (u = x/2 + 0.5, v = y/2: one per vertex) with ``uv``, vn
    lines (one per vertex) when given; faces v, v/vt, v//vn or v/vt/vn."""
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in positions]
    if uv:
        lines += [f"vt {x / 2 + 0.5:.9g} {y / 2:.9g}" for x, y, _ in positions]
    if normals is not None:
        lines += [f"vn {x:.9g} {y:.9g} {z:.9g}" for x, y, z in normals]
    corner = "{0}" + ("/{0}" if uv else "/" if normals is not None else "") + \
        ("/{0}" if normals is not None else "")
    lines += ["f " + " ".join(corner.format(k + 1) for k in t) for t in triangles]
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return str(path)


def scene_text(mesh: str, smooth: str = "", size: int = 96, extra: str = "") -> str:
    """A scene of the vase (file ``mesh``, ``smooth`` its key as written or nothing), a
    white plastic material under one light, seen from the front at ``size``²."""
    return (f"image {{ width {size} height {size} }}\n"
            f"camera {{ eye < 0 1 6 > lookat < 0 1 0 > fov 26 }}\n"
            f"ambient < 0.1 0.1 0.1 >\n"
            f"light {{ position < 4 3 6 > color < 1 1 1 > }}\n"
            f'material "m" {{ ambient {{ color < 1 1 1 > }} diffuse {{ color < 0.7 0.7 0.7 > }} '
            f"specular {{ color < 0.3 0.3 0.3 > }} shininess 12 }}\n"
            f'mesh {{ file "{mesh}" {smooth} {extra} material "m" }}\n')


def belly_profile(image) -> np.ndarray:
    """The luminance (Rec. 709 weights) along the image row where the vase is widest, over
    the pixels it covers (its silhouette's pixels left out)."""
    lum = image[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
    covered = lum > 1e-6
    row = int(np.argmax(covered.sum(axis=1)))
    hit = np.flatnonzero(covered[row])
    return lum[row, hit[0] + 1:hit[-1]]


def steps_against_the_slope(profile) -> float:
    """How far the profile goes against its monotone fall away from its highlight (its
    maximum): the largest rise moving outward from the maximum on either side (0 for a
    profile monotone between its highlight and its ends; a flat-shaded facet, lit by a
    point light at a finite distance, rises across itself: a saw-tooth)."""
    top = int(np.argmax(profile))
    left = np.diff(profile[:top + 1][::-1])      # outward to the left
    right = np.diff(profile[top:])               # outward to the right
    rises = np.concatenate([left, right, [0.0]])
    return float(rises.max())


def band_ratio(profile) -> float:
    """The largest step between neighbouring pixels over the mean of the steps on either
    side of it (those below 10⁻³ counted as 10⁻³): about 1 where the shading is smooth,
    tens at a flat facet's edge (a jump between two near-constant runs)."""
    steps = np.abs(np.diff(profile))
    beside = np.maximum(0.5 * (steps[:-2] + steps[2:]), 1e-3)
    return float(np.max(steps[1:-1] / beside))
