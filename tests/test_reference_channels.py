"""The reference tracer's channels (mimarble.reference.channels, .image_map) against hand values:
sRGB decoding, bilinear repeating lookup, the sphere's (u, v), channel arithmetic, whole renders."""

import math
import os

import numpy as np
import pytest
from PIL import Image

from mimarble import reference
from mimarble import scene as sc
from mimarble.reference import channels, image_map, tracer

# A 4×3 image, written row by row from the top: every texel different.
PIXELS = np.array([
    [[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]],
    [[10, 20, 30], [128, 64, 32], [200, 100, 50], [0, 0, 0]],
    [[1, 2, 3], [250, 240, 230], [77, 88, 99], [40, 41, 42]],
], dtype=np.uint8)


def decode(byte):
    """IEC 61966-2-1, written out for one 8-bit value."""
    c = byte / 255.0
    return c / 12.92 if c <= 0.04045 else math.pow((c + 0.055) / 1.055, 2.4)


def decoded(pixels):
    return np.vectorize(decode, otypes=[float])(np.asarray(pixels, dtype=np.int64))


@pytest.fixture
def png(tmp_path):
    path = tmp_path / "texels.png"
    Image.fromarray(PIXELS, "RGB").save(path)
    return str(path)


@pytest.fixture
def texels(png):
    return image_map.load_image(png)


# ---------------------------------------------------------------------------
# sRGB decoding and loading

def test_srgb_decode_of_known_bytes():
    lut = image_map.SRGB8_TO_LINEAR
    assert lut[0] == 0.0
    assert lut[255] == 1.0
    assert lut[128] == pytest.approx(0.2158605001138992, rel=1e-15)
    assert lut[10] == pytest.approx((10 / 255) / 12.92, rel=1e-15)          # linear segment
    assert lut[11] == pytest.approx(((11 / 255 + 0.055) / 1.055) ** 2.4, rel=1e-15)
    assert np.all(np.diff(lut) > 0)


def test_srgb_to_linear_on_values_either_side_of_the_threshold():
    got = image_map.srgb_to_linear([0.04045, 0.5, 1.0])
    np.testing.assert_allclose(got, [0.04045 / 12.92, ((0.5 + 0.055) / 1.055) ** 2.4, 1.0],
                               rtol=1e-15, atol=0)


def test_loaded_png_is_the_decoded_bytes_with_row_0_the_first_row(texels):
    assert texels.shape == (3, 4, 3) and texels.dtype == np.float64
    np.testing.assert_allclose(texels, decoded(PIXELS), rtol=1e-15, atol=0)
    assert not texels.flags.writeable


def test_grayscale_png_loads_as_equal_rgb(tmp_path):
    grey = np.array([[0, 128], [255, 37]], dtype=np.uint8)
    path = tmp_path / "grey.png"
    Image.fromarray(grey, "L").save(path)
    t = image_map.load_image(path)
    np.testing.assert_allclose(t, decoded(np.stack([grey] * 3, axis=-1)), rtol=1e-15, atol=0)


def test_palette_png_loads_as_its_rgb_entries(tmp_path):
    im = Image.new("P", (2, 1))
    im.putpalette([200, 100, 50, 0, 128, 255] + [0] * (3 * 254))
    im.putdata([1, 0])
    path = tmp_path / "palette.png"
    im.save(path)
    t = image_map.load_image(path)
    np.testing.assert_allclose(t[0], decoded([[0, 128, 255], [200, 100, 50]]), rtol=1e-15, atol=0)


def test_alpha_is_dropped_without_premultiplying(tmp_path):
    rgba = np.array([[[200, 100, 50, 0], [10, 20, 30, 128]]], dtype=np.uint8)
    path = tmp_path / "alpha.png"
    Image.fromarray(rgba, "RGBA").save(path)
    t = image_map.load_image(path)
    np.testing.assert_allclose(t[0], decoded(rgba[0, :, :3]), rtol=1e-15, atol=0)


def test_jpeg_loads_as_rgb(tmp_path):
    path = tmp_path / "flat.jpg"
    Image.new("RGB", (8, 8), (200, 100, 50)).save(path, quality=100)
    t = image_map.load_image(path)
    assert t.shape == (8, 8, 3)
    # a flat colour survives JPEG to within a code value or two
    np.testing.assert_allclose(t, np.broadcast_to(decoded([200, 100, 50]), t.shape), atol=0.01)


def test_image_is_loaded_once_and_again_when_the_file_changes(tmp_path):
    path = tmp_path / "cached.png"
    Image.new("RGB", (2, 2), (255, 0, 0)).save(path)
    first = image_map.load_image(path)
    assert image_map.load_image(path) is first
    Image.new("RGB", (2, 2), (0, 0, 255)).save(path)            # same size on disk
    st = os.stat(path)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))   # a later mtime, surely
    again = image_map.load_image(path)
    assert again is not first
    np.testing.assert_array_equal(again[0, 0], [0.0, 0.0, 1.0])


def test_missing_image_file_raises_value_error_naming_it(tmp_path):
    path = tmp_path / "nowhere" / "veins.png"
    with pytest.raises(ValueError, match="veins.png"):
        image_map.load_image(path)


def test_undecodable_image_file_raises_value_error_naming_it(tmp_path):
    path = tmp_path / "broken.png"
    path.write_bytes(b"this is not a picture")
    with pytest.raises(ValueError, match="broken.png"):
        image_map.load_image(path)
    truncated = tmp_path / "truncated.png"
    Image.fromarray(PIXELS, "RGB").save(truncated)
    truncated.write_bytes(truncated.read_bytes()[:40])
    with pytest.raises(ValueError, match="truncated.png"):
        image_map.load_image(truncated)


# ---------------------------------------------------------------------------
# Bilinear lookup, repeating

def centre(i, j, W=4, H=3):
    """(u, v) of texel column i, row j."""
    return [(i + 0.5) / W, (j + 0.5) / H]


def test_lookup_at_texel_centres_gives_the_texel(texels):
    uv = [centre(i, j) for j in range(3) for i in range(4)]
    got = image_map.bilinear(texels, uv).reshape(3, 4, 3)
    np.testing.assert_allclose(got, decoded(PIXELS), rtol=0, atol=1e-15)


def test_lookup_half_way_between_texels_gives_the_mean(texels):
    want = decoded(PIXELS)
    got = image_map.bilinear(texels, [[2 / 4, 0.5 / 3],        # columns 1 and 2 of row 0
                                      [1.5 / 4, 1 / 3],          # rows 0 and 1 of column 1
                                      [2 / 4, 2 / 3]])           # columns 1, 2 × rows 1, 2
    np.testing.assert_allclose(got[0], (want[0, 1] + want[0, 2]) / 2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(got[1], (want[0, 1] + want[1, 1]) / 2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(got[2], want[1:3, 1:3].mean(axis=(0, 1)), rtol=0, atol=1e-15)


def test_lookup_quarter_way_weights_three_to_one(texels):
    want = decoded(PIXELS)
    got = image_map.bilinear(texels, [[1.75 / 4, 0.5 / 3]])[0]   # x = 1.25: ¾ column 1, ¼ column 2
    np.testing.assert_allclose(got, 0.75 * want[0, 1] + 0.25 * want[0, 2], rtol=0, atol=1e-15)


def test_lookup_at_the_edges_wraps_around(texels):
    want = decoded(PIXELS)
    v0 = 0.5 / 3                                                 # row 0's centre
    # u = 0 and u = 1 are half-way between the last column and the first
    edge = (want[0, 3] + want[0, 0]) / 2
    got = image_map.bilinear(texels, [[0.0, v0], [1.0, v0]])
    np.testing.assert_allclose(got, [edge, edge], rtol=0, atol=1e-15)
    # just past 1 reads as just past 0; just below 0 as just below 1
    eps = 1e-3
    np.testing.assert_allclose(image_map.bilinear(texels, [[1 + eps, v0], [-eps, v0]]),
                               image_map.bilinear(texels, [[eps, v0], [1 - eps, v0]]),
                               rtol=0, atol=1e-12)
    # x = 1 + ε·W − ½ = 3.5 + 0.004 − 4: 0.504 of column 0, 0.496 of column 3
    w = 0.5 + eps * 4
    np.testing.assert_allclose(image_map.bilinear(texels, [[1 + eps, v0]])[0],
                               (1 - w) * want[0, 3] + w * want[0, 0], rtol=0, atol=1e-12)
    # v wraps too: v = 0 mixes the top and bottom rows; whole periods change nothing
    np.testing.assert_allclose(image_map.bilinear(texels, [[0.5 / 4, 0.0]])[0],
                               (want[0, 0] + want[2, 0]) / 2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(image_map.bilinear(texels, [centre(2, 1)[0] - 3, centre(2, 1)[1] + 2]),
                               want[1:2, 2], rtol=0, atol=1e-13)


def test_v_0_reads_the_top_row(texels):
    want = decoded(PIXELS)
    us = [(i + 0.5) / 4 for i in range(4)]
    top = image_map.bilinear(texels, [[u, 0.5 / 3] for u in us])
    np.testing.assert_allclose(top, want[0], rtol=0, atol=1e-15)  # the file's first row
    # nearer v = 0 than row 0's centre: y = −¼, so ¾ of row 0 and ¼ of the wrapped bottom row
    near0 = image_map.bilinear(texels, [[u, 0.25 / 3] for u in us])
    np.testing.assert_allclose(near0, 0.75 * want[0] + 0.25 * want[2], rtol=0, atol=1e-15)
    bottom = image_map.bilinear(texels, [[u, 1 - 0.5 / 3] for u in us])
    np.testing.assert_allclose(bottom, want[2], rtol=0, atol=1e-15)


# ---------------------------------------------------------------------------
# The sphere's (u, v)

def test_sphere_uv_of_the_axes():
    pts = np.array([[1.0, 0, 0], [0, 1.0, 0], [-1.0, 0, 0], [0, -1.0, 0], [0, 0, 1.0], [0, 0, -1.0]])
    uv = channels.sphere_uv(pts, np.zeros(3), np.array(1.0))
    np.testing.assert_allclose(uv[:4], [[0, 0.5], [0.25, 0.5], [0.5, 0.5], [0.75, 0.5]],
                               rtol=0, atol=1e-15)
    assert uv[4, 1] == 0.0                                       # +z pole
    assert uv[5, 1] == 1.0                                       # −z pole


def test_sphere_uv_uses_the_centre_and_radius():
    c = np.array([[5.0, -2.0, 1.0], [0.0, 0.0, 0.0]])
    r = np.array([2.0, 3.0])
    s = math.sqrt(0.5)
    # local (−s, −s, 0): φ = 225°, on the equator; the 2nd: φ = 45°, θ = arccos ½ = 60°
    local = np.array([[-s, -s, 0.0],
                      [math.sin(math.pi / 3) * s, math.sin(math.pi / 3) * s, 0.5]])
    uv = channels.sphere_uv(c + r[:, None] * local, c, r)
    np.testing.assert_allclose(uv, [[225 / 360, 0.5], [45 / 360, 1 / 3]], rtol=0, atol=1e-15)


def test_sphere_u_is_in_0_1_below_the_x_axis():
    uv = channels.sphere_uv([[1.0, -1e-9, 0.0]], [0.0, 0.0, 0.0], 1.0)
    assert 0.0 <= uv[0, 0] <= 1.0 and uv[0, 0] == pytest.approx(1.0, abs=1e-9)


# ---------------------------------------------------------------------------
# Channel arithmetic

PTS = np.array([[0.3, -1.2, 0.7], [1.7, 0.25, -0.4]])
UV = np.array([[0.1, 0.2], [0.8, 0.9]])
A, B, C = (0.5, 0.25, 2.0), (0.125, 1.0, -1.0), (3.0, 0.5, 0.0)


def const(rgb):
    return sc.ColorChannel(rgb)


def test_color_channel_is_constant():
    np.testing.assert_array_equal(channels.channel_color(const(A), PTS, UV), [A, A])


def test_add_sums_componentwise():
    got = channels.channel_color(sc.Add((const(A), const(B), const(C))), PTS, UV)
    np.testing.assert_allclose(got, [[3.625, 1.75, 1.0]] * 2, rtol=0, atol=1e-15)


def test_multiply_multiplies_componentwise():
    got = channels.channel_color(sc.Multiply((const(A), const(B), const(C))), PTS, UV)
    np.testing.assert_allclose(got, [[0.1875, 0.125, -0.0]] * 2, rtol=0, atol=1e-15)


def test_mix_with_a_channel_weight_is_componentwise():
    w = (0.0, 0.5, 0.25)
    got = channels.channel_color(sc.Mix(const(A), const(B), const(w)), PTS, UV)
    # a(1−w) + b w: 0.5, 0.25·0.5 + 1·0.5, 2·0.75 − 0.25
    np.testing.assert_allclose(got, [[0.5, 0.625, 1.25]] * 2, rtol=0, atol=1e-15)


def test_mix_with_a_float_weight():
    got = channels.channel_color(sc.Mix(const(A), const(B), 0.25), PTS, UV)
    np.testing.assert_allclose(got, [[0.40625, 0.4375, 1.25]] * 2, rtol=0, atol=1e-15)


def test_mix_float_weight_is_not_clamped():
    got = channels.channel_color(sc.Mix(const(A), const(B), 2.0), PTS, UV)   # 2b − a
    np.testing.assert_allclose(got, [[-0.25, 1.75, -4.0]] * 2, rtol=0, atol=1e-15)


def test_nested_expression():
    inner = sc.Multiply((const(A), const((2.0, 2.0, 2.0))))       # (1, 0.5, 4)
    expr = sc.Add((inner, sc.Mix(const(B), const(C), 0.5)))       # + (1.5625, 0.75, −0.5)
    got = channels.channel_color(expr, PTS, UV)
    np.testing.assert_allclose(got, [[2.5625, 1.25, 3.5]] * 2, rtol=0, atol=1e-15)


def test_marble_channel_is_the_marble_of_the_points():
    m = sc.MarbleChannel(distortion=0.0, period=1.0, scale=1.0)      # |sin πx| on the Fig. 5 ramp
    t = np.abs(np.sin(math.pi * PTS[:, 0]))
    s = t * 7
    k = np.minimum(np.floor(s), 6)
    f = s - k
    want = np.stack([np.ones(2), (k + f) / 8, np.zeros(2)], axis=-1)  # ramp k/8 green, linear
    np.testing.assert_allclose(channels.channel_color(m, PTS), want, rtol=0, atol=1e-15)


def test_image_channel_is_the_lookup_at_uv(png):
    want = decoded(PIXELS)
    uv = np.array([centre(1, 2), centre(3, 0)])
    got = channels.channel_color(sc.ImageChannel(png), PTS, uv)
    np.testing.assert_allclose(got, [want[2, 1], want[0, 3]], rtol=0, atol=1e-15)


def test_mix_of_an_image_and_a_colour_weighted_by_the_image(png):
    want = decoded(PIXELS)
    img = sc.ImageChannel(png)
    uv = np.array([centre(1, 1)])
    got = channels.channel_color(sc.Mix(img, const(A), img), PTS[:1], uv)[0]
    t = want[1, 1]
    np.testing.assert_allclose(got, t * (1 - t) + np.array(A) * t, rtol=0, atol=1e-15)


def test_image_channel_without_uv_is_an_error(png):
    with pytest.raises(ValueError, match="texels.png"):
        channels.channel_color(sc.Add((const(A), sc.ImageChannel(png))), PTS)


def test_equal_sub_channels_are_evaluated_once(monkeypatch):
    calls = []
    real = channels.marble_color

    def counting(points, channel):
        calls.append(channel)
        return real(points, channel)

    monkeypatch.setattr(channels, "marble_color", counting)
    m = sc.MarbleChannel(scale=2.0)
    expr = sc.Add((m, sc.Multiply((sc.MarbleChannel(scale=2.0), const(A)))))
    got = channels.channel_color(expr, PTS)
    assert len(calls) == 1
    once = real(PTS, m)
    np.testing.assert_allclose(got, once + once * np.array(A), rtol=0, atol=1e-15)


def test_tracer_still_exports_channel_color():
    np.testing.assert_array_equal(tracer.channel_color(const(A), PTS), [A, A])


# ---------------------------------------------------------------------------
# In the tracer

def image_scene(file, size=16, diffuse=None):
    return sc.Scene(
        image=sc.Image(width=size, height=size, samples=1, background=(0.0, 0.0, 0.0)),
        camera=sc.Camera(eye=(0.0, -5.0, 0.0), lookat=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), fov=30.0),
        ambient=(0.1, 0.1, 0.1),
        lights=(sc.Light(position=(0.0, -5.0, 0.0), color=(1.0, 1.0, 1.0)),),
        materials={"m": sc.Material("m", ambient=sc.ImageChannel(file),
                                    diffuse=diffuse or sc.ImageChannel(file), shininess=8.0)},
        spheres=(sc.Sphere("m", center=(0.0, 0.0, 0.0), radius=1.0),),
    )


def test_hits_read_the_image_at_the_hit_sphere_uv(tmp_path):
    grid = np.arange(4 * 4 * 3, dtype=np.uint8).reshape(4, 4, 3) * 5
    path = tmp_path / "grid.png"
    Image.fromarray(grid, "RGB").save(path)
    s = sc.Scene(
        materials={"m": sc.Material("m", diffuse=sc.ImageChannel(str(path)))},
        spheres=(sc.Sphere("m", center=(0.0, 0.0, 0.0), radius=1.0),
                 sc.Sphere("m", center=(5.0, 0.0, 0.0), radius=2.0)),
    )
    # hits at (5, 2, 0) on the second sphere (local +y: u = ¼, v = ½) and at (−1, 0, 0)
    # on the first (local −x: u = ½, v = ½)
    o = np.array([[5.0, 10.0, 0.0], [-10.0, 0.0, 0.0]])
    d = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
    rec = tracer.hit(tracer.prepare(s), o, d)
    np.testing.assert_array_equal(rec.sphere, [1, 0])
    want = decoded(grid)
    # u = ¼ → x = 0.5: columns 0, 1; u = ½ → x = 1.5: columns 1, 2; v = ½ → y = 1.5: rows 1, 2
    expected = [want[1:3, 0:2].mean(axis=(0, 1)), want[1:3, 1:3].mean(axis=(0, 1))]
    np.testing.assert_allclose(rec.colors["diffuse"], expected, rtol=0, atol=1e-14)


def test_render_with_an_image_map_is_finite_and_textured(png):
    img = reference.render(image_scene(png))
    assert img.shape == (16, 16, 3)
    assert np.all(np.isfinite(img))
    assert np.all(img[0, 0] == 0.0)                              # background in the corner
    centre_block = img[6:10, 6:10].reshape(-1, 3)
    assert np.ptp(centre_block, axis=0).max() > 0.01             # the texture shows


def test_render_of_a_uniform_image_equals_its_decoded_colour(tmp_path):
    path = tmp_path / "flat.png"
    Image.new("RGB", (5, 3), (200, 100, 50)).save(path)
    rgb = tuple(decoded([200, 100, 50]))
    textured = reference.render(image_scene(str(path), size=8))
    s = image_scene(str(path), size=8)
    plain = sc.Scene(image=s.image, camera=s.camera, ambient=s.ambient, lights=s.lights,
                     materials={"m": sc.Material("m", ambient=sc.ColorChannel(rgb),
                                                 diffuse=sc.ColorChannel(rgb), shininess=8.0)},
                     spheres=s.spheres)
    np.testing.assert_allclose(textured, reference.render(plain), rtol=0, atol=1e-15)


def test_render_with_a_missing_image_raises_a_scene_error_naming_it(tmp_path):
    from mimarble.scene import SceneError
    missing = str(tmp_path / "maps" / "no-such-veins.png")
    with pytest.raises(SceneError, match="no-such-veins.png"):
        reference.render(image_scene(missing, size=4))
