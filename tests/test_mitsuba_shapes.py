"""Planes, boxes and meshes in Mitsuba: the translator's plugins and placements, object-space
textures per shape, named texture ids, clip planes, and renders checked against geometry
computed here in float64 (NumPy), independently of Mitsuba and of the translator."""

import math
import warnings

import numpy as np
import pytest

import mimarble
from mimarble.contract import EPS_REL, T_MIN_REL
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.mitsuba.rendering import adaptive, silhouettes
from mimarble.mitsuba.translate.scene_dict import (Float32RangeWarning, clip_planes,
    float32_range_problems)
from mimarble.scene import geometry
from mimarble.scene import model as m
from mimarble.texture.mapping import compute_uv_partials_scaled, differentials_from_the_eye

dr, mi = mimarble.dr, mimarble.mi

GREY = m.ColorChannel((0.5, 0.5, 0.5))
KD = 0.6


def write_ply(path, vertices, faces):
    """An ASCII PLY of triangles, no normals, no texture coordinates."""
    lines = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}",
             "property float x", "property float y", "property float z",
             f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    lines += [" ".join(map(repr, map(float, v))) for v in vertices]
    lines += ["3 " + " ".join(map(str, f)) for f in faces]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def write_obj(path, vertices, faces):
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices]
    lines += ["f " + " ".join(str(i + 1) for i in f) for f in faces]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


#: A tetrahedron with a corner at the origin.
TETRAHEDRON = ([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)],
               [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])


def marble(**kw):
    return m.MarbleChannel(scale=2.0, octaves=4, **kw)


def scene_of(materials, size=(24, 24), eye=(0.0, 1.5, 6.0), lookat=(0.0, 0.0, 0.0), fov=40.0,
             lights=((3.0, 5.0, 2.0),), ambient=(0.3, 0.3, 0.3), **shapes):
    return m.Scene(image=m.Image(*size, 1), camera=m.Camera(eye=eye, lookat=lookat, fov=fov),
                   ambient=ambient, lights=tuple(m.Light(p) for p in lights),
                   materials={k.name: k for k in materials}, **shapes)


def matrix_of(transform) -> np.ndarray:
    """A Mitsuba transform's 4×4 as float64."""
    return np.array(transform.matrix, dtype=np.float64).reshape(4, 4)


# ---------------------------------------------------------------------------
# The scene dict

def test_each_shape_is_mitsubas_own_plugin_at_the_hand_computed_place(variant, tmp_path):
    ply = write_ply(tmp_path / "t.ply", *TETRAHEDRON)
    obj = write_obj(tmp_path / "t.obj", *TETRAHEDRON)
    box = m.Box("g", (-1.0, 0.0, -2.0), (3.0, 1.0, 0.0),
                (("rotate", (0, 90, 0)), ("translate", (1, 2, 3))))
    plane = m.Plane("g", (0.0, -1.0, 0.0), (0.0, 2.0, 0.0))
    scene = scene_of([m.Material("g", diffuse=GREY)], spheres=(m.Sphere("g", (1, 2, 3), 0.5),),
                     planes=(plane,), boxes=(box,),
                     meshes=(m.Mesh("g", ply, transform=(("scale", 2),)),
                             m.Mesh("g", obj, transform=(("translate", (0, 0, -1)),))))
    d = to_mitsuba(scene)
    assert [k for k in d if k.endswith(("_0", "_1")) and not k.startswith("light")] == \
        ["sphere_0", "plane_0", "box_0", "mesh_0", "mesh_1"]
    assert d["sphere_0"] == {"type": "sphere", "center": [1.0, 2.0, 3.0], "radius": 0.5,
                             "bsdf": d["sphere_0"]["bsdf"]}
    # The box: rotate 90° about y takes (x, y, z) to (z, y, −x); then translate (1, 2, 3).
    # Its centre (1, 0.5, −1) and half extents (2, 0.5, 1) place Mitsuba's [−1, 1]³.
    assert d["box_0"]["type"] == "cube"
    np.testing.assert_allclose(matrix_of(d["box_0"]["to_world"]),
                               [[0, 0, 1, 0], [0, 0.5, 0, 2.5], [-2, 0, 0, 2], [0, 0, 0, 1]],
                               atol=1e-7)
    # The plane: a disk centred on the eye's foot (0, −1, 6), its normal the plane's unit
    # normal, its in-plane axes orthogonal and of the disk's radius.
    disk = matrix_of(d["plane_0"]["to_world"])
    assert d["plane_0"]["type"] == "disk"
    _, radius = geometry.plane_disk(scene, plane)
    np.testing.assert_allclose(disk[:3, 3], [0, -1, 6], atol=1e-6)
    np.testing.assert_allclose(disk[:3, 2], [0, 1, 0], atol=1e-7)
    for axis in (0, 1):
        assert abs(disk[1, axis]) < 1e-7 * radius
        assert np.linalg.norm(disk[:3, axis]) == pytest.approx(radius, rel=1e-7)
    assert abs(disk[:3, 0] @ disk[:3, 1]) < 1e-7 * radius ** 2
    assert np.linalg.det(disk[:3, :3]) > 0
    # Meshes: by the file's ending, flat, their transform; OBJ's v flipped as Mitsuba does.
    assert {k: d["mesh_0"][k] for k in ("type", "filename", "face_normals", "flip_tex_coords")} \
        == {"type": "ply", "filename": ply, "face_normals": True, "flip_tex_coords": False}
    assert (d["mesh_1"]["type"], d["mesh_1"]["flip_tex_coords"]) == ("obj", True)
    np.testing.assert_allclose(matrix_of(d["mesh_0"]["to_world"]), np.diag([2, 2, 2, 1]))
    np.testing.assert_allclose(matrix_of(d["mesh_1"]["to_world"])[:3, 3], [0, 0, -1])
    # Loaded, Mitsuba's shapes have the bounds worked out by hand (each by its id: without
    # optimize=False, load_dict merges the meshes of one BSDF into one shape).
    shapes = {s.id(): s for s in mi.load_dict(d, optimize=False).shapes()}
    bounds = {"box_0": ([0 - 1, 2, 2 - 2], [0 + 1, 3, 2 + 2]),     # (0, 2.5, 2) ± (1, 0.5, 2)
              "mesh_0": ([0, 0, 0], [2, 2, 2]), "mesh_1": ([0, 0, -1], [1, 1, 0])}
    for shape_id, (lo, hi) in bounds.items():
        box_bounds = shapes[shape_id].bbox()
        np.testing.assert_allclose(np.array(box_bounds.min), lo, atol=1e-6)
        np.testing.assert_allclose(np.array(box_bounds.max), hi, atol=1e-6)


def test_object_space_marbles_get_a_texture_per_shape_and_world_ones_stay_shared(variant):
    pattern = (("translate", (0.5, 0, 0)),)
    veins = marble(space="object", transform=pattern)
    world = marble(period=1.7)
    materials = [m.Material("o", ambient=world, diffuse=veins),
                 m.Material("w", ambient=world, diffuse=world)]
    box = m.Box("o", (0, 0, 0), (1, 1, 1), (("translate", (4, 0, 0)),))
    scene = scene_of(materials, spheres=(m.Sphere("o", (1, 2, 3), 2.0), m.Sphere("w", (0, 0, -4))),
                     planes=(m.Plane("o", (0, -1, 0)),), boxes=(box,))
    d = to_mitsuba(scene)
    marbles = {k: v for k, v in d.items() if isinstance(v, dict) and v.get("type") == "marble"}
    # One world texture, four references to it; one object-space texture per shape.
    assert sorted(marbles) == ["texture_0", "texture_1_box_0", "texture_1_plane_0",
                               "texture_1_sphere_0"]
    assert [d[s]["bsdf"]["ambient"]["id"] for s in ("sphere_0", "sphere_1", "plane_0", "box_0")] \
        == ["texture_0"] * 4
    assert d["sphere_1"]["bsdf"]["diffuse"]["id"] == "texture_0"
    # v = scale·(S·M)⁻¹·p: S the shape's object space, M = translate(0.5, 0, 0), by hand.
    expected = {"sphere_0": [[2, 0, 0, 1 + 2 * 0.5], [0, 2, 0, 2], [0, 0, 2, 3]],   # T(c)·S(r)·M
                "plane_0": [[1, 0, 0, 0.5], [0, 1, 0, -1], [0, 0, 1, 0]],          # +y: no turn
                "box_0": [[1, 0, 0, 4.5], [0, 1, 0, 0], [0, 0, 1, 0]]}
    for shape_id, rows in expected.items():
        texture = d[d[shape_id]["bsdf"]["diffuse"]["id"]]
        assert texture is marbles[f"texture_1_{shape_id}"]
        np.testing.assert_allclose(matrix_of(texture["to_world"]), rows + [[0, 0, 0, 1]],
                                   atol=1e-7)
    assert "to_world" not in marbles["texture_0"]
    # Path mode: the same textures under Mitsuba's BSDFs, two-sided on planes and boxes.
    path = to_mitsuba(scene, mode="path", spp=4)
    assert path["box_0"]["bsdf"]["type"] == "twosided"
    assert path["box_0"]["bsdf"]["bsdf"]["reflectance"]["id"] == "texture_1_box_0"
    assert path["sphere_1"]["bsdf"]["reflectance"]["id"] == "texture_0"
    image = mimarble.render(scene, mode="path", spp=4)
    assert np.isfinite(image).all() and image.max() > 0


def test_named_textures_lend_their_names_to_the_ids_and_take_no_other_id(variant):
    veins, other, third = marble(), marble(period=2.0), marble(period=3.0)
    materials = [m.Material("a", ambient=veins, diffuse=other, specular=third)]
    scene = scene_of(materials, spheres=(m.Sphere("a"),),
                     textures={"white veins": veins, "3 d": other, "sphere 0": third})
    d = to_mitsuba(scene)
    bsdf = d["sphere_0"]["bsdf"]
    assert (bsdf["ambient"]["id"], bsdf["diffuse"]["id"], bsdf["specular"]["id"]) == \
        ("white_veins", "texture_3_d", "sphere_0_2")
    assert d["sphere_0"]["type"] == "sphere"
    assert np.isfinite(mimarble.render(scene)).all()


# ---------------------------------------------------------------------------
# Clip planes and float32's range

def test_clip_planes_enclose_every_shape_and_spheres_keep_theirs(tmp_path):
    g = [m.Material("g", diffuse=GREY)]
    eye = (0.0, 0.0, 10.0)
    # A sphere alone: ||c − e| − r| and |c − e| + r, as ever.
    assert clip_planes(scene_of(g, eye=eye, spheres=(m.Sphere("g"),))) == (4.5, 11 * 1.001)
    # A box: 9 from the eye (its face z = 1), its farthest corner √(1 + 1 + 11²).
    near, far = clip_planes(scene_of(g, eye=eye, boxes=(m.Box("g"),)))
    assert near == 4.5 and far == pytest.approx(math.sqrt(123) * 1.001)
    # A plane 2 below the eye: near 1, far just past the rim of its disk.
    plane = m.Plane("g", (0.0, -2.0, 0.0), (0.0, 1.0, 0.0))
    scene = scene_of(g, eye=eye, planes=(plane,))
    _, radius = geometry.plane_disk(scene, plane)
    near, far = clip_planes(scene)
    assert near == 1.0 and far == pytest.approx(math.hypot(2.0, radius) * 1.001)
    # Inside a box: the reference's smallest hit distance; a mesh: that too, far the cap.
    floor = T_MIN_REL * (1 + 10)
    around = m.Box("g", (-20, -20, -20), (20, 20, 20))
    assert clip_planes(scene_of(g, eye=eye, boxes=(around,)))[0] == floor
    mesh = m.Mesh("g", write_ply(tmp_path / "t.ply", *TETRAHEDRON))
    assert clip_planes(scene_of(g, eye=eye, spheres=(m.Sphere("g"),), meshes=(mesh,))) == \
        (floor, 2.0 ** 125)


def test_shapes_beyond_float32s_reach_are_warned_about():
    g = [m.Material("g", diffuse=GREY)]
    assert float32_range_problems(scene_of(g, planes=(m.Plane("g"),), boxes=(m.Box("g"),))) == []
    far = scene_of(g, lights=((0.0, 2e14, 0.0),), planes=(m.Plane("g"),))   # its disk: 2e18
    (problem,) = float32_range_problems(far)
    assert "plane (rendered as a disk of radius 2e+18)" in problem and "Embree" in problem
    huge = scene_of(g, boxes=(m.Box("g", (-1e10, -1e10, -1e10), (1e10, 1e10, 1e10)),))
    assert any("face normal" in p for p in float32_range_problems(huge))
    on_plane = scene_of(g, eye=(1e6, 1e-3, 0.0), lookat=(0.0, 0.0, 0.0),
                        planes=(m.Plane("g"),))
    with pytest.warns(Float32RangeWarning, match="plane .* beyond float32's reach"):
        to_mitsuba(on_plane)


def test_a_mesh_past_embrees_range_or_too_near_for_float32_is_warned_about(tmp_path):
    """A mesh is judged by the world corners of its file's bounds, not by its transform's
    origin: a triangle of coordinates ±10¹⁹ about the origin (untransformed) reaches 10¹⁹
    (past Embree's 1.8·10¹⁸), moved by 10¹⁸ further; a triangle at x = 10⁹ seen from 1
    away is nearer than float32's error there (2⁻²³·(10⁹ + 1) ≈ 119), from 1000 away it
    is not."""
    g = [m.Material("g", diffuse=GREY)]
    unit = write_obj(tmp_path / "unit.obj", [(-1, -1, 0), (1, -1, 0), (0, 1, 0)], [(0, 1, 2)])
    huge = write_obj(tmp_path / "huge.obj", [(-1e19, -1e19, 0), (1e19, -1e19, 0), (0, 1e19, 0)],
                     [(0, 1, 2)])
    for mesh, reach in ((m.Mesh("g", huge), "1e+19"),
                        (m.Mesh("g", huge, transform=(("translate", (1e18, 0, 0)),)), "1.1e+19")):
        problems = float32_range_problems(scene_of(g, meshes=(mesh,)))
        assert any(f"mesh reaches {reach} from the origin" in p and "Embree" in p
                   for p in problems), problems
    with pytest.warns(Float32RangeWarning) as caught:     # and the light's, 1.4e19 away
        to_mitsuba(scene_of(g, meshes=(m.Mesh("g", huge),)))
    assert any("mesh reaches 1e+19" in str(w.message) for w in caught)
    far = write_obj(tmp_path / "far.obj", [(1e9, -1, -1), (1e9, 1, -1), (1e9, 0, 1)], [(0, 1, 2)])
    mesh = m.Mesh("g", far)
    for distance, warned in ((1.0, True), (1000.0, False)):
        scene = scene_of(g, eye=(1e9 + distance, 0.0, 0.0), lookat=(1e9, 0.0, 0.0),
                         lights=((1e9 + 5, 0.0, 0.0),), meshes=(mesh,))
        problems = float32_range_problems(scene)
        assert any("mesh at 1e+09 from the origin is beyond float32's reach" in p
                   for p in problems) == warned, problems
    assert float32_range_problems(scene_of(g, meshes=(m.Mesh("g", unit),))) == []


# ---------------------------------------------------------------------------
# Renders against float64 geometry

def primary_rays(scene):
    """(eye, unit directions (H, W, 3)) of the pixel centres, by the rendering model."""
    cam, width, height = scene.camera, scene.image.width, scene.image.height
    f = np.subtract(cam.lookat, cam.eye)
    f /= np.linalg.norm(f)
    r = np.cross(f, cam.up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    tan_half = math.tan(math.radians(cam.fov) / 2)
    x, y = np.meshgrid((np.arange(width) + 0.5) / width, (np.arange(height) + 0.5) / height)
    d = f + ((2 * x - 1) * tan_half * width / height)[..., None] * r \
        + ((1 - 2 * y) * tan_half)[..., None] * u
    return np.array(cam.eye), d / np.linalg.norm(d, axis=-1, keepdims=True)


def plane_hits(scene, plane):
    """(t, points, unit normal) of the primary rays and the plane (t ≤ 0: no hit)."""
    eye, d = primary_rays(scene)
    n = np.array(plane.normal) / np.linalg.norm(plane.normal)
    t = ((np.array(plane.point) - eye) @ n) / (d @ n)
    return t, eye + t[..., None] * d, n


def test_a_box_seen_face_on_covers_the_analytic_rectangle(variant):
    # Eye on the z axis, 9 from the front face z = 1 of a box 2 wide and 1 high.
    scene = scene_of([m.Material("g", ambient=GREY)], size=(20, 20), eye=(0.0, 0.0, 10.0),
                     fov=20.0, lights=(), ambient=(1, 1, 1),
                     boxes=(m.Box("g", (-1.0, -0.5, -1.0), (1.0, 0.5, 1.0)),))
    eye, d = primary_rays(scene)
    t = (1.0 - eye[2]) / d[..., 2]
    x, y = t * d[..., 0], t * d[..., 1]
    assert np.abs(np.abs(x) - 1).min() > 0.02 and np.abs(np.abs(y) - 0.5).min() > 0.02  # no
    covered = (np.abs(x) < 1) & (np.abs(y) < 0.5)                          # centre on an edge
    image = mimarble.render(scene)
    np.testing.assert_array_equal(image[..., 0] > 0, covered)
    assert 0.1 < covered.mean() < 0.6
    np.testing.assert_allclose(image[covered], 0.5, atol=1e-6)


def test_lights_on_materials_without_diffuse_or_specular_add_nothing(variant):
    # (Traced, such lights made Dr.Jit emit invalid LLVM IR and abort the process.)
    scene = scene_of([m.Material("g", ambient=GREY)], size=(8, 8), ambient=(1, 1, 1),
                     spheres=(m.Sphere("g"),), planes=(m.Plane("g", (0.0, -1.0, 0.0)),))
    image = mimarble.render(scene)
    assert (image[image > 0] == 0.5).all() and (image > 0).mean() > 0.5


def test_a_plane_under_the_camera_fills_the_lower_half_up_to_its_horizon(variant):
    plane = m.Plane("g", (0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    scene = scene_of([m.Material("g", ambient=GREY)], size=(16, 24), eye=(0.0, 1.0, 0.0),
                     lookat=(0.0, 1.0, -1.0), fov=30.0, lights=(), ambient=(1, 1, 1),
                     planes=(plane,))
    t, p, _ = plane_hits(scene, plane)
    centre, radius = geometry.plane_disk(scene, plane)
    seen = (t > 0) & (np.linalg.norm(p - centre, axis=-1) <= radius)
    first_row = np.argmax(seen, axis=0)                 # the horizon, analytically
    assert (first_row == 12).all()                      # just below the middle of 24 rows
    image = mimarble.render(scene)
    rendered = np.argmax(image[..., 0] > 0, axis=0)
    assert np.abs(rendered - first_row).max() <= 1
    np.testing.assert_allclose(image[13:], 0.5, atol=1e-6)
    assert (image[:11] == 0).all()


@pytest.mark.parametrize("normal", [(0.0, 1.0, 0.0), (0.2, 1.0, 0.1), (0.0, -1.0, 0.3)])
def test_a_diffuse_plane_is_shaded_by_n_dot_l_at_its_float64_hit(variant, normal):
    light = np.array([1.0, 3.0, 2.0])
    plane = m.Plane("g", (0.0, -1.0, 0.0), normal)
    scene = scene_of([m.Material("g", diffuse=m.ColorChannel((KD, KD, KD)))],
                     size=(16, 16), lights=(tuple(light),), ambient=(0, 0, 0), planes=(plane,))
    t, p, n = plane_hits(scene, plane)
    eye, d = primary_rays(scene)
    facing = np.where((d @ n)[..., None] < 0, n, -n)                # two-sided
    to_light = light - p
    n_dot_l = np.sum(facing * to_light, axis=-1) / np.linalg.norm(to_light, axis=-1)
    expected = np.where(t > 0, KD * np.maximum(n_dot_l, 0.0), 0.0)
    image = mimarble.render(scene)
    assert (t > 0).mean() > 0.3 and (expected > 0.1).any()
    np.testing.assert_allclose(image[..., 0], expected, atol=1e-5)


def shadowed_plane(offset, scale, size=40):
    """A unit sphere (times ``scale``) resting on a plane, all moved by ``offset``."""
    at = lambda v: tuple(np.add(offset, np.multiply(scale, v)))  # noqa: E731
    colour = m.Material("g", ambient=m.ColorChannel((0.1,) * 3), diffuse=m.ColorChannel((KD,) * 3))
    return scene_of([colour], size=(size, size), eye=at((0, 1.5, 6)), lookat=at((0, 0, 0)),
                    lights=(at((3, 5, 2)),), ambient=(0.5, 0.5, 0.5),
                    spheres=(m.Sphere("g", at((0, 0, 0)), scale),),
                    planes=(m.Plane("g", at((0, -1, 0))),))


def expected_plane_pixels(scene):
    """(where the plane is the first hit, its colour, where a shadow edge is near) by the
    rendering model: ka·A + kd·(n·l)·V, V the shadow ray from p + ε·n against the sphere,
    ε = EPS_REL·(1 + max|p_k|) (either root: the ray may start inside it)."""
    plane, sphere = scene.planes[0], scene.spheres[0]
    t, p, n = plane_hits(scene, plane)
    eye, d = primary_rays(scene)
    oc = eye - sphere.center
    b = d @ oc
    disc = b * b - (oc @ oc - sphere.radius ** 2)
    t_sphere = np.where(disc > 0, -b - np.sqrt(np.maximum(disc, 0)), np.inf)
    on_plane = (t > 0) & (t < t_sphere)
    light = np.array(scene.lights[0].position)
    to_light = light - p
    n_dot_l = (to_light @ n) / np.linalg.norm(to_light, axis=-1)
    start = p + (EPS_REL * (1 + np.abs(p).max(axis=-1)))[..., None] * n
    towards = light - start
    length = np.linalg.norm(towards, axis=-1)
    towards /= length[..., None]
    q = start - sphere.center
    bq = np.sum(q * towards, axis=-1)
    dq = bq * bq - (np.sum(q * q, axis=-1) - sphere.radius ** 2)
    roots = [-bq - np.sqrt(np.maximum(dq, 0)), -bq + np.sqrt(np.maximum(dq, 0))]
    shadow = (dq > 0) & np.any([(r > 0) & (r < length) for r in roots], axis=0)
    colour = 0.1 * 0.5 + np.where((n_dot_l > 0) & ~shadow, KD * n_dot_l, 0.0)
    padded = np.pad(shadow | ~on_plane, 1, mode="edge")
    near_edge = np.zeros_like(shadow)
    for dy in range(3):
        for dx in range(3):
            near_edge |= padded[dy:dy + shadow.shape[0], dx:dx + shadow.shape[1]] != shadow
    return on_plane, colour, near_edge


@pytest.mark.parametrize("offset, scale", [((0, 0, 0), 1.0), ((0, -1e3, 0), 1.0),
                                           ((1e3, 1e3, 1e3), 1.0), ((0, 0, 0), 1e3),
                                           ((1e4, 0, 1e4), 10.0), ((0, 0, 0), 1e-3)])
def test_a_plane_under_a_sphere_has_no_acne_at_any_scale(jit_variant, offset, scale):
    scene = shadowed_plane(offset, scale)
    on_plane, colour, near_edge = expected_plane_pixels(scene)
    image = mimarble.render(scene)[..., 0]
    checked = on_plane & ~near_edge
    assert checked.mean() > 0.3
    assert (colour[checked] < 0.1).any() and (colour[checked] > 0.3).any()   # shade and light
    np.testing.assert_allclose(image[checked], colour[checked], atol=2e-5)


def test_moving_a_box_moves_its_object_space_marble_with_it(variant):
    # Face-on, 9 from the front face: a move of k pixel widths there moves its image by k.
    # (Off by (−0.3, 0.2) pixels: no pixel centre on a face's diagonal, between its two
    # triangles, where scalar_rgb's Embree lets a ray through to the back face.)
    size, fov = 24, 20.0
    pixel = 2 * 9 * math.tan(math.radians(fov) / 2) / size
    images = {}
    for space in ("object", "world"):
        veins = m.Material("v", ambient=marble(space=space, distortion=2.0))
        for k in (0, 3):
            box = m.Box("v", (-1.0, -1.0, -1.0), (1.0, 1.0, 1.0),
                        (("translate", ((k - 0.3) * pixel, 0.2 * pixel, 0.0)),))
            scene = scene_of([veins], size=(size, size), eye=(0.0, 0.0, 10.0), fov=fov,
                             lights=(), ambient=(1, 1, 1), boxes=(box,))
            images[space, k] = mimarble.render(scene)
    inside = np.s_[6:18, 6:15]                   # pixels of the front face in both images
    moved = np.s_[6:18, 9:18]
    np.testing.assert_allclose(images["object", 3][moved], images["object", 0][inside],
                               atol=1e-4)
    assert np.abs(images["world", 3][moved] - images["world", 0][inside]).max() > 0.05


# ---------------------------------------------------------------------------
# Footprints, edge samples and adaptive sampling on a disk, a cube and a mesh without uv

def shape_scenes(tmp_path, scale=1.0, size=32):
    """One scene per kind of shape, each seen at a slant, all coordinates times ``scale``."""
    at = lambda v: tuple(np.multiply(scale, v))  # noqa: E731
    quad = write_ply(tmp_path / "quad.ply", [(-5, -1, -5), (5, -1, -5), (5, -0.5, 5), (-5, -1, 5)],
                     [(0, 1, 2), (0, 2, 3)])
    shapes = {"plane": {"planes": (m.Plane("g", at((0, -1, 0)), (0.2, 1.0, 0.1)),)},
              "box": {"boxes": (m.Box("g", at((-3, -1, -3)), at((3, 0.5, 3)),
                                      (("rotate", (10, 20, 5)),)),)},
              "mesh": {"meshes": (m.Mesh("g", quad, transform=(("scale", scale),)),)}}
    return {kind: scene_of([m.Material("g", diffuse=GREY)], size=(size, size),
                           eye=at((0, 1.5, 6)), lookat=at((0, -1, 0)), lights=(at((3, 5, 2)),),
                           **more) for kind, more in shapes.items()}


PIXELS = np.array([(x, y) for x in range(4, 28, 5) for y in range(18, 30, 4)], float)


def film(size, dx=0.0, dy=0.0):
    """The film positions of :data:`PIXELS`' centres, moved by (dx, dy) pixels."""
    return mi.Point2f(mi.Float((PIXELS[:, 0] + 0.5 + dx) / size),
                      mi.Float((PIXELS[:, 1] + 0.5 + dy) / size))


def footprints(loaded, size, solve=compute_uv_partials_scaled):
    """(dp/dx, dp/dy) at :data:`PIXELS` as the whitted integrator makes them, and the steps
    to the next pixels' hits on the same face (float64: Mitsuba's hits), where they are."""
    camera = loaded.sensors()[0]

    def hits(position):
        ray, _ = camera.sample_ray(0.0, 0.0, position, mi.Point2f(0.5))
        si = loaded.ray_intersect(ray)
        return np.array(si.p, np.float64).T, np.array(si.prim_index) // 2, np.array(si.is_valid())

    ray, _ = camera.sample_ray_differential(0.0, 0.0, film(size), mi.Point2f(0.5))
    ray.scale_differential(1.0)
    si = loaded.ray_intersect(ray)
    solve(si, differentials_from_the_eye(ray, loaded))
    dp_dx = np.array(si.dp_du * si.duv_dx.x + si.dp_dv * si.duv_dx.y, np.float64).T
    dp_dy = np.array(si.dp_du * si.duv_dy.x + si.dp_dv * si.duv_dy.y, np.float64).T
    (p, face, hit), (px, face_x, _), (py, face_y, _) = \
        hits(film(size)), hits(film(size, dx=1)), hits(film(size, dy=1))
    same = hit & (face == face_x) & (face == face_y)          # a box's face: 2 triangles
    return dp_dx[same], dp_dy[same], (px - p)[same], (py - p)[same]


@pytest.mark.parametrize("scale", [1.0, 1e-3, 1e3, 1e8])
def test_the_footprint_is_the_step_to_the_next_pixels_hit_on_every_shape(jit_variant, tmp_path,
                                                                        scale):
    for kind, scene in shape_scenes(tmp_path, scale).items():
        dp_dx, dp_dy, step_x, step_y = footprints(mi.load_dict(to_mitsuba(scene)),
                                                  scene.image.width)
        assert len(dp_dx) >= 10, kind
        # A differential ray is the next pixel's ray: on a flat face it meets the next hit.
        for got, step in ((dp_dx, step_x), (dp_dy, step_y)):
            np.testing.assert_allclose(got, step, atol=1e-4 * np.abs(step).max(), err_msg=kind)


def test_mitsubas_own_solve_loses_the_footprint_on_a_large_disk(jit_variant, tmp_path):
    scene = shape_scenes(tmp_path, 1e8)["plane"]       # the disk's radius: 6·10¹²
    own = footprints(mi.load_dict(to_mitsuba(scene)), scene.image.width,
                     solve=lambda si, ray: si.compute_uv_partials(ray))
    assert not np.isclose(own[0], own[2], rtol=0.01).any()     # 0 or NaN: no footprint


@pytest.mark.parametrize("marble_filter", ["prefilter", "bandlimit"])
def test_edge_samples_and_adaptive_rounds_on_shapes_are_plain_renders(llvm, tmp_path,
                                                                       marble_filter):
    veins = marble(filter=marble_filter, distortion=3.0)
    quad = write_ply(tmp_path / "tet.ply", *TETRAHEDRON)
    scene = scene_of([m.Material("v", ambient=veins, diffuse=veins)], size=(32, 32),
                     eye=(0.5, 2.0, 5.0), lookat=(0.0, 0.0, 0.0),
                     planes=(m.Plane("v", (0.0, -0.5, 0.0)),),
                     boxes=(m.Box("v", (-1.8, -0.5, -0.5), (-0.8, 0.5, 0.5)),),
                     meshes=(m.Mesh("v", quad, transform=(("translate", (0.6, -0.5, 0)),)),))
    loaded = mi.load_dict(to_mitsuba(scene))
    once, sixteen = render_in_passes(loaded, 1), render_in_passes(loaded, 16)
    both = render_in_passes(loaded, 1, edge_spp=16)
    edges = silhouettes.edge_mask(loaded, 1)
    assert 0 < edges.mean() < 0.5
    np.testing.assert_array_equal(both[edges], sixteen[edges])
    np.testing.assert_array_equal(both[~edges], once[~edges])
    result = adaptive.render_adaptive(loaded, 1, 0.02, 16)      # levels 1, 9, 16
    assert len(np.unique(result.samples)) > 1
    # A filtered pixel at 3 or 9 keeps its 1-spp centre with that pass's wider footprint
    # (tests/test_adaptive.py); the first pass and a level that replaces are plain renders.
    for spp in set(np.unique(result.samples).tolist()) - {3, 9}:
        where = result.samples == spp
        plain = render_in_passes(loaded, int(spp))
        np.testing.assert_array_equal(result.image[where], plain[where])
    # The filtered pixel at 1 sample is nearer the 16-sample one than the point sample is.
    point = render_in_passes(mi.load_dict(to_mitsuba(scene, filter="none")), 1)
    inside = ~edges
    assert np.abs(once - sixteen)[inside].mean() < np.abs(point - sixteen)[inside].mean()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.isfinite(mimarble.render(scene, edge_spp=4)).all()
