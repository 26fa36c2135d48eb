"""``mimarble bake``: a shape's channel into an image through its (u, v), or a volume grid.

Checked against what does not come from the baker: Mitsuba's ``bitmap`` texture on
Mitsuba's sphere and mesh, rendered beside the procedural marble (the baked texture must
converge to it as bilinear interpolation does, as the texel shrinks); the float64
reference at points placed analytically; a volume file read back by a reader written
here, and Mitsuba's ``gridvolume`` evaluated at random points against trilinear
interpolation of those voxels.
"""

import math
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest

import mimarble
from mimarble.tools import bake
from mimarble import scene as scene_language
from mimarble.mitsuba.rendering.image_output import write_image
from mimarble.mitsuba.translate.scene_dict import to_mitsuba
from mimarble.reference.channels import channel_color

from commands import mimarble_cli

mi = mimarble.mi

SPHERE = """
image   { width 64 height 64 samples 1 background < 0 0 0 > }
camera  { eye < 0 -5 1.5 > lookat < 0 0 0 > up < 0 0 1 > fov 30 }
light   { position < 3 -6 4 > color < 1 1 1 > }
material "m" { diffuse { marble { scale 0.7 period 1 distortion 1.5 octaves 3 } } }
sphere { center < 0.2 0.1 -0.1 > radius 1.2 material "m" }
"""


def rendered(scene_dict):
    return np.array(mi.render(mi.load_dict(scene_dict), seed=0))


def procedural(scene):
    """(whitted dict, its render at one sample, the pixels showing a shape)."""
    scene_dict = to_mitsuba(scene, "whitted", 1)
    image = rendered(scene_dict)
    return scene_dict, image, image.sum(axis=-1) > 0


def with_texture(scene_dict, texture):
    """The dict with its (one) marble texture replaced by ``texture``."""
    key = next(k for k, v in scene_dict.items()
               if isinstance(v, dict) and v.get("type") == "marble")
    return {**scene_dict, key: texture}


def bitmap(path, raw):
    return {"type": "bitmap", "filename": str(path), "raw": raw, "filter_type": "bilinear",
            "wrap_mode": "clamp"}


def test_a_baked_sphere_renders_as_its_marble_converging_as_bilinear_interpolation(tmp_path):
    """Bilinear lookup between texel centres errs by O(h²) where the marble is smooth and
    O(h) at its kinks (abs_sine's zeros): so the mean error over the sphere's pixels falls
    about fourfold per halving of the texel (measured 3.4 and 3.8 from 64 to 256 texels),
    the largest about twofold. Measured: mean 4.9e-4, max 0.067 at 256² (EXR); the 8-bit PNG
    adds its rounding (mean 5.9e-4)."""
    scene = scene_language.parse(SPHERE)
    scene_dict, ours, on_sphere = procedural(scene)
    assert on_sphere.mean() > 0.3
    mean, largest = {}, {}
    for n in (64, 128, 256):
        path = tmp_path / f"baked{n}.exr"
        write_image(path, bake.bake_image(scene, "sphere_0", n))
        error = np.abs(rendered(with_texture(scene_dict, bitmap(path, True))) - ours)[on_sphere]
        mean[n], largest[n] = error.mean(), error.max()
    assert mean[64] / mean[128] > 2.5 and mean[128] / mean[256] > 3.0
    assert largest[64] / largest[256] > 3.0
    assert mean[256] < 1e-3 and largest[256] < 0.1
    png = tmp_path / "baked256.png"
    write_image(png, bake.bake_image(scene, "sphere_0", 256))
    error = np.abs(rendered(with_texture(scene_dict, bitmap(png, False))) - ours)[on_sphere]
    assert error.mean() < 1e-3 and error.max() < 0.1


def test_row_zero_is_the_plus_z_pole_and_texels_are_sampled_at_their_centres():
    """A marble of no noise along z depends on z alone: row j holds it at
    z = c_z + r·cos(π(j + ½)/N), the same across the row."""
    scene = scene_language.parse(SPHERE.replace("distortion 1.5", "distortion 0 axis z"))
    n = 8
    image = bake.bake_image(scene, "sphere_0", n)
    material = scene.materials["m"]
    z = -0.1 + 1.2 * np.cos(math.pi * (np.arange(n) + 0.5) / n)
    expected = channel_color(material.diffuse, np.stack([np.zeros(n), np.zeros(n), z], -1))
    np.testing.assert_allclose(image, np.broadcast_to(expected[:, None], (n, n, 3)),
                               rtol=1e-6, atol=1e-7)


def test_sphere_texels_are_the_reference_at_the_inverted_sphere_uv():
    scene = scene_language.parse(SPHERE)
    n = 16
    image = bake.bake_image(scene, "sphere_0", n)
    j, i = np.mgrid[0:n, 0:n]
    phi, theta = 2 * math.pi * (i + 0.5) / n, math.pi * (j + 0.5) / n
    p = np.array([0.2, 0.1, -0.1]) + 1.2 * np.stack(
        [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)
    expected = channel_color(scene.materials["m"].diffuse, p.reshape(-1, 3)).reshape(n, n, 3)
    np.testing.assert_allclose(image, expected, rtol=1e-6, atol=1e-7)


# ---------------------------------------------------------------------------
# Volumes

def read_vol(path):
    """Mitsuba's volume grid file, read here: header, bounding box, (z, y, x, channels)."""
    data = Path(path).read_bytes()
    assert data[:3] == b"VOL" and data[3] == 3
    encoding, nx, ny, nz, channels = struct.unpack_from("<5i", data, 4)
    assert encoding == 1
    box = np.array(struct.unpack_from("<6f", data, 24), dtype=np.float64)
    voxels = np.frombuffer(data, dtype="<f4", offset=48)
    assert voxels.size == nx * ny * nz * channels
    return box[:3], box[3:], voxels.reshape(nz, ny, nx, channels)


def trilinear(voxels, lo, hi, points):
    """The grid at world points, voxel centres at lo + (i + ½)·(hi − lo)/N, clamped at the
    edges (gridvolume's default wrap mode)."""
    n = np.array(voxels.shape[2::-1])
    x = (points - lo) / (hi - lo) * n - 0.5
    i0 = np.floor(x).astype(int)
    f = x - i0
    out = np.zeros((len(points), voxels.shape[3]))
    for corner in np.ndindex(2, 2, 2):
        idx = np.clip(i0 + corner, 0, n - 1)
        w = np.prod(np.where(corner, f, 1 - f), axis=1)
        out += w[:, None] * voxels[idx[:, 2], idx[:, 1], idx[:, 0]]
    return out


def outwards(lo, hi, true_lo, true_hi):
    """The box as float32 numbers around the true one, each the nearest that encloses it."""
    lo32, hi32 = np.float32(lo), np.float32(hi)
    assert (lo32 == lo).all() and (hi32 == hi).all()
    assert (lo <= true_lo).all() and (np.nextafter(lo32, np.float32(np.inf)) > true_lo).all()
    assert (hi >= true_hi).all() and (np.nextafter(hi32, np.float32(-np.inf)) < true_hi).all()


def test_a_sphere_volume_holds_the_reference_at_its_voxel_centres(tmp_path):
    scene = scene_language.parse(SPHERE)
    path = tmp_path / "sphere.vol"
    n = 6
    bake.bake_volume(scene, "sphere_0", path, n)
    lo, hi, voxels = read_vol(path)
    assert voxels.shape == (n, n, n, 3)
    centre = np.array([0.2, 0.1, -0.1])
    outwards(lo, hi, centre - 1.2, centre + 1.2)
    z, y, x = np.mgrid[0:n, 0:n, 0:n]
    centres = lo + (np.stack([x, y, z], -1) + 0.5) * (hi - lo) / n
    expected = channel_color(scene.materials["m"].diffuse, centres.reshape(-1, 3))
    np.testing.assert_allclose(voxels.reshape(-1, 3), expected, rtol=1e-6, atol=1e-7)


def test_mitsuba_reads_the_volume_as_trilinear_interpolation_of_its_voxels(tmp_path):
    scene = scene_language.parse(SPHERE)
    path = tmp_path / "sphere.vol"
    bake.bake_volume(scene, "sphere_0", path, 5)
    lo, hi, voxels = read_vol(path)
    volume = mi.load_dict(bake.gridvolume_dict(path)["volume"])
    rng = np.random.default_rng(7)
    points = lo + rng.uniform(0.02, 0.98, size=(200, 3)) * (hi - lo)
    it = mi.Interaction3f()
    it.p = mi.Point3f(*(points[:, k].astype(np.float32) for k in range(3)))
    theirs = np.array(volume.eval(it)).T                  # Color3f: (3, k)
    np.testing.assert_allclose(theirs, trilinear(voxels, lo, hi, points), rtol=2e-5, atol=2e-6)


def test_the_documented_volume_texture_renders_as_the_marble(tmp_path):
    """``bake.gridvolume_dict`` (docs/mitsuba-scene.md's snippet) in place of the marble:
    trilinear between voxel centres, so the mean error falls about fourfold per halving of
    the voxel where the marble is smooth (measured: 6.1e-3 at 32³, 1.9e-3 at 64³)."""
    scene = scene_language.parse(SPHERE)
    scene_dict, ours, on_sphere = procedural(scene)
    errors = []
    for n in (32, 64):
        bake.bake_volume(scene, "sphere_0", tmp_path / f"v{n}.vol", n)
        theirs = rendered(with_texture(scene_dict, bake.gridvolume_dict(tmp_path / f"v{n}.vol")))
        errors.append(np.abs(theirs - ours)[on_sphere].mean())
    assert errors[0] / errors[1] > 2.5 and errors[1] < 3e-3


def test_a_box_volume_spans_its_rotated_corners(tmp_path):
    box = scene_language.Box("m", (-1, -0.5, 0), (1, 0.5, 2),
                             transform=(("rotate", (0.0, 0.0, 30.0)),
                                        ("translate", (1.0, 2.0, 3.0))))
    scene = scene_language.Scene(materials={"m": scene_language.Material(
        "m", diffuse=scene_language.ColorChannel((0.25, 0.5, 0.75)))}, boxes=(box,))
    path = tmp_path / "box.vol"
    bake.bake_volume(scene, "box_0", path, 2)
    lo, hi, voxels = read_vol(path)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    xs = [1 + c * x - s * y for x in (-1, 1) for y in (-0.5, 0.5)]
    ys = [2 + s * x + c * y for x in (-1, 1) for y in (-0.5, 0.5)]
    outwards(lo, hi, [min(xs), min(ys), 3.0], [max(xs), max(ys), 5.0])
    np.testing.assert_array_equal(voxels, np.broadcast_to(np.float32([0.25, 0.5, 0.75]),
                                                          (2, 2, 2, 3)))


# ---------------------------------------------------------------------------
# Meshes

def write_ply(path, positions, uv, faces):
    lines = ["ply", "format ascii 1.0", f"element vertex {len(positions)}",
             "property float x", "property float y", "property float z"]
    if uv is not None:
        lines += ["property float u", "property float v"]
    lines += [f"element face {len(faces)}", "property list uchar int vertex_indices",
              "end_header"]
    for k, p in enumerate(positions):
        lines.append(" ".join(map(str, list(p) + (list(uv[k]) if uv is not None else []))))
    lines += ["3 " + " ".join(map(str, f)) for f in faces]
    Path(path).write_text("\n".join(lines) + "\n")


def write_obj(path, positions, uv, faces):
    lines = [f"v {x} {y} {z}" for x, y, z in positions]
    if uv is None:
        lines += ["f " + " ".join(str(k + 1) for k in f) for f in faces]
    else:
        lines += [f"vt {u} {v}" for u, v in uv]
        lines += ["f " + " ".join(f"{k + 1}/{k + 1}" for k in f) for f in faces]
    Path(path).write_text("\n".join(lines) + "\n")


QUAD = """
image   { width 48 height 48 samples 1 background < 0 0 0 > }
camera  { eye < 1 0.5 4 > lookat < 1 0.5 0 > up < 0 1 0 > fov 30 }
light   { position < 1 0.5 5 > color < 1 1 1 > }
material "m" { diffuse { marble { scale 0.9 period 1 distortion 1 octaves 3 } } }
mesh { file "quad.ply" transform { rotate < 0 0 5 > translate < 0.05 0 0 > } material "m" }
"""


def quad_scene(tmp_path, faces=((0, 1, 2), (0, 2, 3)), uv=((0, 0), (1, 0), (1, 1), (0, 1)),
               kind="ply", space="world"):
    """The 2×1 quad, its (u, v) as Mitsuba reads them: (x/2, y) (an OBJ file stores
    1 − v, which Mitsuba flips back)."""
    corners = [(0, 0, 0), (2, 0, 0), (2, 1, 0), (0, 1, 0)]
    if kind == "ply":
        write_ply(tmp_path / "quad.ply", corners, uv, faces)
    else:
        write_obj(tmp_path / "quad.obj", corners,
                  None if uv is None else [(u, 1 - v) for u, v in uv], faces)
    (tmp_path / "quad.scene").write_text(QUAD.replace("quad.ply", f"quad.{kind}")
                                         .replace("octaves 3", f"octaves 3 space {space}"))
    return scene_language.load(tmp_path / "quad.scene")


def test_mesh_texels_are_the_reference_at_their_barycentric_points(tmp_path):
    scene = quad_scene(tmp_path)
    n = 16
    image = bake.bake_image(scene, "mesh_0", n)
    j, i = np.mgrid[0:n, 0:n]
    u, v = (i + 0.5) / n, (j + 0.5) / n
    local = np.stack([2 * u, v, np.zeros_like(u)], -1).reshape(-1, 3)   # the quad's (u, v)
    c, s = math.cos(math.radians(5)), math.sin(math.radians(5))
    world = local @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T + [0.05, 0, 0]
    expected = channel_color(scene.materials["m"].diffuse, world).reshape(n, n, 3)
    np.testing.assert_allclose(image, expected, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("kind, space", [("ply", "world"), ("obj", "object")])
def test_a_baked_mesh_renders_as_its_marble(kind, space, tmp_path):
    """Mitsuba's ``ply`` (u, v) and ``bitmap``, against the procedural marble: as on the
    sphere, the mean error falls about fourfold per halving of the texel (measured: 9.9e-4
    at 64², 2.5e-4 at 128²; the largest 0.11 and 0.056)."""
    scene = quad_scene(tmp_path, kind=kind, space=space)
    scene_dict, ours, on_quad = procedural(scene)
    errors = []
    for n in (64, 128):
        path = tmp_path / f"quad{n}.exr"
        write_image(path, bake.bake_image(scene, "mesh_0", n))
        theirs = rendered(with_texture(scene_dict, bitmap(path, True)))
        errors.append(np.abs(theirs - ours)[on_quad].mean())
    assert errors[0] / errors[1] > 3.0 and errors[1] < 5e-4


def test_uncovered_texels_are_filled_two_deep_then_black(tmp_path):
    scene = quad_scene(tmp_path, faces=((0, 1, 2),))     # the upper-right half of (u, v)
    n = 16
    lit = bake.bake_image(scene, "mesh_0", n).any(axis=-1)
    j, i = np.mgrid[0:n, 0:n]
    # Texels below the diagonal (j > i) are uncovered; each pass reaches the eight around,
    # so two passes reach ⌈(j − i)/2⌉ ≤ 2.
    depth = np.ceil(np.maximum(j - i, 0) / 2)
    assert lit[depth <= bake.DILATION].all()
    # Neighbours wrap round (as ``repeat`` lookups do): the covered last column and first
    # row fill the first two columns and the last two rows too; the rest stays black.
    assert lit[(i < 2) | (j > n - 3)].all()
    assert not lit[(depth > bake.DILATION) & (i >= 2) & (j <= n - 3)].any()


def test_a_mesh_without_texture_coordinates_or_tiled_ones_is_refused(tmp_path):
    scene = quad_scene(tmp_path, uv=None)
    with pytest.raises(bake.BakeError, match="has no texture coordinates.*--volume"):
        bake.bake_image(scene, "mesh_0", 8)
    scene = quad_scene(tmp_path, uv=((0, 0), (3, 0), (3, 1), (0, 1)))
    with pytest.raises(bake.BakeError, match="more than one repeat of the image"):
        bake.bake_image(scene, "mesh_0", 8)


@pytest.mark.parametrize("kind, shift", [("ply", (1000, -3)), ("obj", (2 ** 31 + 5, -(2 ** 20))),
                                         ("obj", (2 ** 32 - 1, -(2 ** 32)))])
def test_texture_coordinates_whole_repeats_away_bake_the_same_image(tmp_path, kind, shift):
    """(u, v) moved by whole repeats of the image (exact in the file: float32 for PLY,
    float64 for OBJ) name the same texels, as a ``repeat`` lookup reads them."""
    base = bake.bake_image(quad_scene(tmp_path, kind=kind), "mesh_0", 16)
    uv = [(u + shift[0], v + shift[1]) for u, v in ((0, 0), (1, 0), (1, 1), (0, 1))]
    moved = bake.bake_image(quad_scene(tmp_path, uv=uv, kind=kind), "mesh_0", 16)
    np.testing.assert_array_equal(moved, base)


@pytest.mark.parametrize("value", [1e30, -2.0 ** 33])
def test_texture_coordinates_past_max_uv_are_refused_in_one_sentence(tmp_path, value):
    uv = ((0, 0), (1, 0), (1, value), (0, 1))
    scene = quad_scene(tmp_path, uv=uv, kind="obj")
    with warnings.catch_warnings():
        warnings.simplefilter("error")              # no NumPy warning on the way
        with pytest.raises(bake.BakeError) as e:
            bake.bake_image(scene, "mesh_0", 8)
    assert f"texture coordinates reach {abs(value):g}, past the ±4.29497e+09" in str(e.value)
    assert "\n" not in str(e.value)


def test_a_mesh_volume_spans_its_world_vertices(tmp_path):
    scene = quad_scene(tmp_path)
    lo, hi = bake.bake_volume(scene, "mesh_0", tmp_path / "q.vol", 2)
    c, s = math.cos(math.radians(5)), math.sin(math.radians(5))
    corners = np.array([(0, 0), (2, 0), (2, 1), (0, 1)], dtype=float)
    x = 0.05 + c * corners[:, 0] - s * corners[:, 1]
    y = s * corners[:, 0] + c * corners[:, 1]
    np.testing.assert_allclose(lo[:2], [x.min(), y.min()], rtol=1e-6)
    np.testing.assert_allclose(hi[:2], [x.max(), y.max()], rtol=1e-6)
    thickness = bake.FLAT_FRACTION * (x.max() - x.min())             # flat in z: thickened
    np.testing.assert_allclose([lo[2], hi[2]], [-thickness / 2, thickness / 2], rtol=1e-5)


# ---------------------------------------------------------------------------
# Object space

def test_an_object_space_marble_bakes_the_same_image_and_volume_on_any_sphere(tmp_path):
    """A sphere's object space is its unit sphere: moved and shrunk, the same texels (and
    the same voxels, its box moving with it) — and a world-space marble's differ."""
    text = SPHERE.replace("octaves 3", "octaves 3 space object")
    elsewhere = ("center < 0.2 0.1 -0.1 > radius 1.2", "center < -3 2 5 > radius 0.4")
    first = scene_language.parse(text)
    moved = scene_language.parse(text.replace(*elsewhere))
    a = bake.bake_image(first, "sphere_0", 16)
    np.testing.assert_allclose(bake.bake_image(moved, "sphere_0", 16), a, rtol=1e-5, atol=1e-6)
    world = scene_language.parse(SPHERE.replace(*elsewhere))
    assert np.abs(bake.bake_image(world, "sphere_0", 16) - a).max() > 0.1
    bake.bake_volume(first, "sphere_0", tmp_path / "a.vol", 4)
    bake.bake_volume(moved, "sphere_0", tmp_path / "b.vol", 4)
    np.testing.assert_allclose(read_vol(tmp_path / "b.vol")[2], read_vol(tmp_path / "a.vol")[2],
                               rtol=1e-5, atol=1e-6)


# ---------------------------------------------------------------------------
# What is refused

def two_shapes():
    m = scene_language.Material("m", diffuse=scene_language.ColorChannel((1.0, 0.0, 0.0)),
                                ambient=scene_language.ImageChannel("x.png"))
    return scene_language.Scene(materials={"m": m}, spheres=(scene_language.Sphere("m"),),
                                planes=(scene_language.Plane("m"),),
                                boxes=(scene_language.Box("m"),))


@pytest.mark.parametrize("shape, volume, words", [
    ("plane_0", False, "plane_0 is a plane: it has no (u, v)"),
    ("plane_0", True, "no bounds to bake a volume in"),
    ("box_0", False, "bake a volume with --volume"),
    ("sphere_9", False, "no shape 'sphere_9' in the scene (its shapes: sphere_0, plane_0, box_0)"),
])
def test_what_has_no_uv_or_no_bounds_or_no_id_is_refused_in_one_sentence(shape, volume, words):
    with pytest.raises(bake.BakeError) as e:
        bake.chosen(two_shapes(), shape, None, volume)
    assert words in str(e.value) and "\n" not in str(e.value)


def test_the_channel_is_diffuse_else_the_first_and_a_missing_one_is_named():
    assert bake.chosen(two_shapes(), "sphere_0")[1] == "diffuse"
    with pytest.raises(bake.BakeError,
                       match=r"has no specular channel \(it has ambient, diffuse\)"):
        bake.chosen(two_shapes(), "sphere_0", "specular")
    with pytest.raises(bake.BakeError, match="holds an image map, which has no value off"):
        bake.chosen(two_shapes(), "sphere_0", "ambient", volume=True)


def test_sizes_are_refused_before_anything_is_allocated(tmp_path):
    scene = two_shapes()
    with pytest.raises(bake.BakeError, match=f"must be in 1..{bake.MAX_IMAGE_SIZE}"):
        bake.bake_image(scene, "sphere_0", 10 ** 9)
    with pytest.raises(bake.BakeError, match=f"must be in 1..{bake.MAX_VOLUME_SIZE}"):
        bake.bake_volume(scene, "sphere_0", tmp_path / "x.vol", 10 ** 6)
    assert not (tmp_path / "x.vol").exists()


def test_the_command_bakes_and_refuses_in_one_line(tmp_path):
    scene = tmp_path / "s.scene"
    scene.write_text(SPHERE)
    out = tmp_path / "t.png"
    result = mimarble_cli("bake", scene, "--shape", "sphere_0", "-o", out, "--size", "8")
    assert result.returncode == 0, result.stderr
    assert out.exists() and "8x8 texels of sphere_0's diffuse channel" in result.stdout
    result = mimarble_cli("bake", scene, "--shape", "sphere_0", "-o", tmp_path / "t.vol",
                          "--volume", "--size", "3")
    assert result.returncode == 0 and read_vol(tmp_path / "t.vol")[2].shape == (3, 3, 3, 3)
    for args, words in [(["--shape", "sphere_1", "-o", out], "no shape 'sphere_1'"),
                        (["--shape", "sphere_0", "-o", tmp_path / "t.jpg"], "use .png or .exr"),
                        (["--shape", "sphere_0", "-o", out, "--size", "8193"], "1..8192"),
                        (["--shape", "sphere_0", "-o", out, "--volume"], "use .vol")]:
        result = mimarble_cli("bake", scene, *args)
        assert result.returncode == 2 and words in result.stderr, result.stderr
        assert len(result.stderr.strip().splitlines()) == 1
