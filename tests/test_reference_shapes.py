"""The reference tracer's planes, boxes and meshes (mimarble.reference.tracer, .triangles)
against analytic hits, brute force over all triangles, and the analytic sphere."""

import dataclasses
import math
import struct
import tracemalloc

import numpy as np
import pytest

from mimarble import reference
from mimarble.reference import preparation, tracer
from mimarble.reference.marble import marble_color
from mimarble.reference.triangles import TriangleBVH
from mimarble.scene import SceneError, geometry
from mimarble.scene.model import (Box, Camera, ColorChannel, Image, ImageChannel, Light,
                                  MarbleChannel, Material, Mesh, Plane, Scene, Sphere)

GREY = Material("grey", ambient=ColorChannel((0.1, 0.1, 0.1)),
                diffuse=ColorChannel((0.6, 0.5, 0.4)), specular=ColorChannel((0.2, 0.2, 0.2)),
                shininess=16.0)


def scene_of(*, materials=(GREY,), **shapes):
    return Scene(image=Image(width=8, height=8, background=(0.0, 0.0, 0.5)),
                 camera=Camera(eye=(0.0, 1.0, 9.0), lookat=(0.0, 0.0, 0.0), fov=30.0),
                 ambient=(1.0, 1.0, 1.0), lights=(Light((4.0, 6.0, 5.0)),),
                 materials={m.name: m for m in materials}, **shapes)


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


# ---------------------------------------------------------------------------
# The hierarchy against brute force

def brute_force(o, d, v0, v1, v2, t_lo, t_hi):
    """Every ray against every triangle, by another route than Möller–Trumbore: the plane's
    t = n·(v0 − o)/(n·d), then the point inside iff on the inner side of all three edges
    (signs of (vj − vi) × (p − vi) along n)."""
    n = np.cross(v1 - v0, v2 - v0)                                    # (T, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.einsum("tk,tk->t", n, v0)[None, :] - o @ n.T
        t = t / (d @ n.T)                                             # (R, T)
    p = o[:, None, :] + t[:, :, None] * d[:, None, :]
    inside = np.ones(t.shape, dtype=bool)
    for a, b in ((v0, v1), (v1, v2), (v2, v0)):
        side = np.einsum("rtk,tk->rt", np.cross(b - a, p - a[None]), n)
        inside &= side >= 0
    t = np.where(inside & (t > t_lo[:, None]) & (t < t_hi[:, None]), t, np.inf)
    return t.min(axis=1), np.where(np.isfinite(t.min(axis=1)), t.argmin(axis=1), -1)


def random_soup(rng, count):
    centre = rng.uniform(-1.0, 1.0, (count, 3))
    return [centre + rng.normal(0.0, 0.15, (count, 3)) for _ in range(3)]


def test_closest_hit_equals_brute_force_over_all_triangles():
    rng = np.random.default_rng(7)
    v0, v1, v2 = random_soup(rng, 300)
    bvh = TriangleBVH(v0, v1, v2)
    assert bvh.depth >= 6                              # a real hierarchy, not one leaf
    # rays from outside towards the soup, and from inside it in every direction
    o = np.concatenate([rng.uniform(-3, 3, (300, 3)), rng.uniform(-0.5, 0.5, (300, 3))])
    d = unit(np.concatenate([rng.uniform(-0.6, 0.6, (300, 3)) - o[:300], rng.normal(size=(300, 3))]))
    t_lo = np.full(len(o), 1e-9)
    t_lo[::7] = 0.5                                    # some rays start further on
    t_hi = np.full(len(o), np.inf)
    t_hi[::5] = 1.5
    want_t, want_i = brute_force(o, d, v0, v1, v2, t_lo, t_hi)
    t, i, b1, b2 = bvh.closest(o, d, t_lo, t_hi)
    assert (want_i >= 0).sum() > 300                   # most rays hit something
    np.testing.assert_array_equal(i, want_i)
    np.testing.assert_allclose(t[i >= 0], want_t[i >= 0], rtol=1e-12, atol=0)
    assert np.all(np.isinf(t[i < 0]))
    # the barycentrics rebuild the hit point
    hit = i >= 0
    point = (1 - b1 - b2)[hit, None] * v0[i[hit]] + b1[hit, None] * v1[i[hit]] + b2[hit, None] * v2[i[hit]]
    np.testing.assert_allclose(point, o[hit] + t[hit, None] * d[hit], rtol=0, atol=1e-12)


def test_any_hit_equals_brute_force_within_the_segment():
    rng = np.random.default_rng(11)
    v0, v1, v2 = random_soup(rng, 200)
    bvh = TriangleBVH(v0, v1, v2)
    o = rng.uniform(-1.5, 1.5, (500, 3))
    d = unit(rng.normal(size=(500, 3)))
    t_max = rng.uniform(0.1, 3.0, 500)
    want_t, _ = brute_force(o, d, v0, v1, v2, np.zeros(500), t_max)
    blocked = bvh.any_hit(o, d, t_max)
    assert 50 < blocked.sum() < 450
    np.testing.assert_array_equal(blocked, np.isfinite(want_t))


def test_hierarchy_memory_grows_within_the_limit_budget():
    """Held bytes per triangle, measured at 2¹⁴: at MAX_MESH_TRIANGLES (2²⁰) the hierarchy
    stays within 0.3 GB (72 bytes of vertices and edges, a node's box per two triangles)."""
    rng = np.random.default_rng(3)
    v0, v1, v2 = random_soup(rng, 1 << 14)
    tracemalloc.start()
    bvh = TriangleBVH(v0, v1, v2)
    held = tracemalloc.get_traced_memory()[0]
    tracemalloc.stop()
    assert bvh.count == 1 << 14
    assert held / (1 << 14) * (1 << 20) < 0.3e9


def test_equal_distances_go_to_the_lowest_triangle_index():
    """Triangle 17, moved away from the others, repeated at the end of the list: rays from
    either side meet both at the same t and report 17, not 200 (the ordering that makes the
    result independent of the traversal: brute force's argmin)."""
    rng = np.random.default_rng(2)
    soup = random_soup(rng, 200)
    for v in soup:
        v[17] += (10.0, 0.0, 0.0)
    v0, v1, v2 = (np.concatenate([v, v[17:18]]) for v in soup)
    bvh = TriangleBVH(v0, v1, v2)
    assert bvh.depth >= 5
    target = (v0[17] + v1[17] + v2[17]) / 3.0
    o = target + unit(np.cross(v1[17] - v0[17], v2[17] - v0[17])) * np.array([[3.0], [-3.0]])
    t, i, _, _ = bvh.closest(o, unit(target - o), 0.0)
    assert i.tolist() == [17, 17]
    np.testing.assert_allclose(t, [3.0, 3.0], rtol=1e-14)


def test_tiny_and_empty_hierarchies():
    one = TriangleBVH([(0, 0, 0)], [(1, 0, 0)], [(0, 1, 0)])
    t, i, b1, b2 = one.closest((0.25, 0.25, 1.0), [(0.0, 0.0, -1.0)], 0.0)
    assert (i[0], t[0], b1[0], b2[0]) == (0, 1.0, 0.25, 0.25)
    empty = TriangleBVH(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)))
    t, i, _, _ = empty.closest((0, 0, 1.0), [(0.0, 0.0, -1.0)], 0.0)
    assert i[0] == -1 and math.isinf(t[0])
    assert not empty.any_hit((0, 0, 1.0), [(0.0, 0.0, -1.0)], [5.0])[0]


# ---------------------------------------------------------------------------
# Boxes and planes, analytically

BOX_STEPS = (("rotate", (0.0, 0.0, 30.0)), ("scale", (2.0, 1.0, 1.0)), ("translate", (0.5, -0.25, 1.0)))


def test_box_hit_and_normal_are_the_analytic_ones():
    """M = T·S·R (steps in order). The +x face's world normal is (M_lin)⁻ᵀ·e_x ∝ S⁻¹·R·e_x
    = (cos 30°/2, sin 30°, 0); a ray along −normal from 3 units off a face point hits it at
    t = 3 with that normal."""
    box = Box("grey", (-1.0, -2.0, -0.5), (1.0, 2.0, 0.5), BOX_STEPS)
    prep = tracer.prepare(scene_of(boxes=(box,)))
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    normal = unit([c / 2.0, s, 0.0])
    face_point = np.array(geometry.apply(geometry.object_to_world(box), (1.0, 0.3, 0.1)))
    o = face_point + 3.0 * normal
    rec = tracer.closest_hit(prep, o[None], -normal[None])
    assert rec.shape.tolist() == [0] and rec.sphere.tolist() == [-1]
    np.testing.assert_allclose(rec.t, [3.0], rtol=1e-14)
    np.testing.assert_allclose(rec.p[0], face_point, rtol=0, atol=1e-14)
    np.testing.assert_allclose(rec.n[0], normal, rtol=0, atol=1e-15)
    # from the box's centre the ray sees the inside of the same face, its normal towards it
    centre = np.array(geometry.apply(geometry.object_to_world(box), (0.0, 0.3, 0.1)))
    rec = tracer.closest_hit(prep, centre[None], unit(face_point - centre)[None])
    np.testing.assert_allclose(rec.p[0], face_point, rtol=0, atol=1e-14)
    np.testing.assert_allclose(rec.n[0], -normal, rtol=0, atol=1e-15)
    # along object −x at object y = 2 ∓ 1e-9, the ray meets the face's edge or passes it
    m = geometry.object_to_world(box)
    o = np.array([geometry.apply(m, (4.0, 2.0 + f, 0.1)) for f in (1e-9, -1e-9)])
    rec = tracer.closest_hit(prep, o, unit([geometry.apply_linear(m, (-1.0, 0.0, 0.0))] * 2))
    assert rec.index.tolist() == [1]


def test_box_shadow_is_the_segment_test():
    box = Box("grey", (-1.0, -1.0, -1.0), (1.0, 1.0, 1.0), (("translate", (0.0, 2.0, 0.0)),))
    prep = tracer.prepare(scene_of(boxes=(box,)))
    o = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    d = np.array([[0.0, 1.0, 0.0]] * 4)
    # enters at t = 1: blocked when the light is beyond it, not when it is before the box;
    # a ray beside the box passes
    blocked = tracer.occluded(prep, o, d, np.array([5.0, 0.99, 5.0, 1.01]))
    assert blocked.tolist() == [True, False, False, True]


def test_plane_hit_is_analytic_within_its_disk():
    plane = Plane("grey", (0.0, -1.0, 0.0), (0.0, 2.0, 0.0))        # y = −1, normal given unnormalised
    scene = scene_of(planes=(plane,))
    prep = tracer.prepare(scene)
    o = np.array([[0.0, 3.0, 0.0], [0.5, -4.0, 0.25]])
    d = unit([[1.0, -1.0, 0.0], [0.0, 1.0, 1.0]])
    rec = tracer.closest_hit(prep, o, d)
    np.testing.assert_allclose(rec.t, [4.0 * math.sqrt(2.0), 3.0 * math.sqrt(2.0)], rtol=1e-15)
    np.testing.assert_allclose(rec.n, [[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]], atol=0)   # facing each eye
    # the disk: centre and radius are geometry.plane_disk's; a ray down to 1 − 1e-9 of the
    # radius hits, to 1 + 1e-9 misses
    centre, radius = geometry.plane_disk(scene, plane)
    eye = np.array(scene.camera.eye)
    targets = [np.array(centre) + np.array([radius * f, 0.0, 0.0]) for f in (1 - 1e-9, 1 + 1e-9)]
    rec = tracer.closest_hit(prep, eye, unit(np.stack(targets) - eye))
    assert rec.index.tolist() == [0]
    # a ray along the plane never hits it
    assert tracer.closest_hit(prep, np.array([0.0, -1.0, 0.0]), [[1.0, 0.0, 0.0]]).index.size == 0


def test_shape_index_is_the_scenes_order():
    scene = scene_of(spheres=(Sphere("grey", (0.0, 0.0, -20.0), 1.0),),
                     planes=(Plane("grey", (0.0, -30.0, 0.0), (0.0, 1.0, 0.0)),),
                     boxes=(Box("grey", (-1, -1, -1), (1, 1, 1), (("translate", (0, 0, -10)),)),))
    prep = tracer.prepare(scene)
    o = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -15.0], [0.0, 0.0, -25.0]])
    d = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, -1.0], [0.0, -1.0, 0.0]])
    rec = tracer.closest_hit(prep, o, d)
    assert rec.shape.tolist() == [2, 0, 1]            # box_0, sphere_0, plane_0
    assert [scene.shapes()[k][0] for k in rec.shape] == ["box_0", "sphere_0", "plane_0"]
    np.testing.assert_allclose(rec.t, [9.0, 4.0, 30.0], rtol=1e-15)


# ---------------------------------------------------------------------------
# Meshes

def icosphere(subdivisions):
    """The unit icosahedron, each triangle split in four `subdivisions` times, the new
    vertices pushed out onto the unit sphere."""
    g = (1.0 + math.sqrt(5.0)) / 2.0
    v = [(-1, g, 0), (1, g, 0), (-1, -g, 0), (1, -g, 0), (0, -1, g), (0, 1, g), (0, -1, -g),
         (0, 1, -g), (g, 0, -1), (g, 0, 1), (-g, 0, -1), (-g, 0, 1)]
    v = [tuple(c / math.sqrt(1 + g * g) for c in p) for p in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(subdivisions):
        middle, faces = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in middle:
                p = [(v[a][k] + v[b][k]) / 2.0 for k in range(3)]
                r = math.sqrt(sum(c * c for c in p))
                middle[key] = len(v)
                v.append(tuple(c / r for c in p))
            return middle[key]
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            faces += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = faces
    return np.array(v), np.array(f)


def write_binary_ply(path, positions, faces, uv=None):
    head = ["ply", "format binary_little_endian 1.0", f"element vertex {len(positions)}",
            "property double x", "property double y", "property double z"]
    head += ["property double u", "property double v"] if uv is not None else []
    head += [f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    rows = np.hstack([positions, uv]) if uv is not None else positions
    body = rows.astype("<f8").tobytes() + b"".join(struct.pack("<B3i", 3, *f) for f in faces)
    path.write_bytes(("\n".join(head) + "\n").encode() + body)
    return str(path)


def test_tessellated_sphere_renders_close_to_the_analytic_sphere(tmp_path):
    """An icosphere of 20 480 flat triangles inscribed in the unit sphere, placed by
    scale 1.5 and translate: its silhouette within a pixel of the sphere's, its flat
    shading within a few percent (facets tilt the normal by up to ~0.01 rad)."""
    v, f = icosphere(5)
    path = write_binary_ply(tmp_path / "ico.ply", v, f)
    place = (("scale", (1.5, 1.5, 1.5)), ("translate", (0.2, -0.1, 0.0)))
    image = Image(width=48, height=48, background=(0.0, 0.0, 0.5))
    sphere = dataclasses.replace(scene_of(spheres=(Sphere("grey", (0.2, -0.1, 0.0), 1.5),)), image=image)
    mesh = dataclasses.replace(scene_of(meshes=(Mesh("grey", "ico.ply", path, place),)), image=image)
    a, b = reference.render(sphere), reference.render(mesh)
    hit_a, hit_b = a[..., 2] != 0.5, b[..., 2] != 0.5
    assert hit_a.sum() > 300
    assert (hit_a != hit_b).sum() <= 0.01 * hit_a.sum()               # at most edge pixels
    both = hit_a & hit_b
    assert np.abs(a[both] - b[both]).mean() < 0.004
    assert np.abs(a[both] - b[both]).max() < 0.025


def test_mesh_shadows_and_flat_normals(tmp_path):
    """One triangle over the plane y = 0 hides the light from the points below it only; its
    normal is its own geometric normal, facing the viewer."""
    tri = tmp_path / "t.obj"
    tri.write_text("v -1 0 -1\nv 1 0 -1\nv 0 0 1\nf 1 2 3\n")
    mesh = Mesh("grey", "t.obj", str(tri), (("translate", (0.0, 2.0, 0.0)),))
    prep = tracer.prepare(scene_of(meshes=(mesh,)))
    rec = tracer.closest_hit(prep, np.array([0.0, 5.0, 0.0]), [[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
    assert rec.index.tolist() == [0]
    np.testing.assert_allclose(rec.t, [3.0], rtol=1e-15)
    np.testing.assert_allclose(rec.n, [[0.0, 1.0, 0.0]], atol=0)
    blocked = tracer.occluded(prep, np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]]),
                              np.array([[0.0, 1.0, 0.0]] * 2), np.array([10.0, 10.0]))
    assert blocked.tolist() == [True, False]


def test_mesh_uv_is_the_interpolated_vertex_uv(tmp_path):
    """vt written as (x, 1 − y) on a triangle in the plane z = 0: Mitsuba's (u, 1 − v) makes
    (u, v) = (x, y) at every point of it, the interpolation being affine."""
    obj = tmp_path / "uv.obj"
    obj.write_text("v 0 0 0\nv 2 0 0\nv 0 1 0\nvt 0 1\nvt 2 1\nvt 0 0\nf 1/1 2/2 3/3\n")
    prep = tracer.prepare(scene_of(meshes=(Mesh("grey", "uv.obj", str(obj)),)))
    points = np.array([[0.2, 0.3], [1.5, 0.2], [0.1, 0.85]])
    o = np.column_stack([points, np.full(3, 4.0)])
    rec = tracer.closest_hit(prep, o, np.array([[0.0, 0.0, -1.0]] * 3))
    np.testing.assert_allclose(tracer.hit_uv(prep, rec), points, rtol=0, atol=1e-15)


def test_image_map_on_a_shape_without_uv_is_refused(tmp_path):
    mapped = Material("mapped", diffuse=ImageChannel("veins.png"))
    for shapes, what in (({"planes": (Plane("mapped"),)}, "plane_0"),
                         ({"boxes": (Box("mapped"),)}, "box_0")):
        with pytest.raises(SceneError, match=f'material "mapped" of {what} reads an image map'):
            tracer.prepare(scene_of(materials=(mapped,), **shapes))


def test_meshes_refused_past_the_scenes_triangle_limit(tmp_path, monkeypatch):
    obj = tmp_path / "two.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\n")     # 2 triangles
    monkeypatch.setattr(preparation, "MAX_MESH_TRIANGLES", 3)
    meshes = (Mesh("grey", "a.obj", str(obj)), Mesh("grey", "b.obj", str(obj)))
    with pytest.raises(SceneError, match="mesh file 'b.obj': the scene's meshes hold 4 triangles"):
        tracer.prepare(scene_of(meshes=meshes))
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nf 1 1\n")
    with pytest.raises(SceneError, match="mesh file 'c.obj': line 2: a face needs 3"):
        tracer.prepare(scene_of(meshes=(Mesh("grey", "c.obj", str(bad)),)))


# ---------------------------------------------------------------------------
# Object space

def test_object_space_marble_on_a_translated_box_is_the_world_marble_moved_back():
    shift = np.array([3.25, -1.5, 0.75])
    marble = MarbleChannel(period=1.7, distortion=2.5, octaves=4, space="object")
    material = Material("stone", diffuse=marble)
    box = Box("stone", (-1.0, -1.0, -1.0), (1.0, 1.0, 1.0), (("translate", tuple(shift)),))
    prep = tracer.prepare(scene_of(materials=(material,), boxes=(box,)))
    rng = np.random.default_rng(5)
    o = shift + rng.uniform(-0.9, 0.9, (200, 3)) * [1, 1, 0] + [0, 0, 6]
    rec = tracer.hit(prep, o, np.array([[0.0, 0.0, -1.0]] * 200))
    assert rec.index.size == 200
    world = dataclasses.replace(marble, space="world")
    np.testing.assert_allclose(rec.colors["diffuse"], marble_color(rec.p - shift, world),
                               rtol=0, atol=1e-12)
    # and it differs from the world-space marble at the same points
    assert np.abs(rec.colors["diffuse"] - marble_color(rec.p, world)).max() > 0.05


def test_object_space_of_a_sphere_is_the_unit_sphere():
    """object_to_world(sphere) = translate(c)·scale(r): the object point is (p − c)/r."""
    marble = MarbleChannel(period=1.3, distortion=2.0, octaves=3, space="object")
    sphere = Sphere("stone", (1.0, 2.0, -3.0), 2.5)
    prep = tracer.prepare(scene_of(materials=(Material("stone", diffuse=marble),),
                                   spheres=(sphere,)))
    o = np.array([[1.3, 2.4, 5.0], [0.1, 1.1, 5.0]])
    rec = tracer.hit(prep, o, np.array([[0.0, 0.0, -1.0]] * 2))
    local = (rec.p - sphere.center) / sphere.radius
    np.testing.assert_allclose(np.linalg.norm(local, axis=1), 1.0, rtol=1e-14)
    np.testing.assert_allclose(rec.colors["diffuse"],
                               marble_color(local, dataclasses.replace(marble, space="world")),
                               rtol=0, atol=1e-12)


def test_channel_color_refuses_object_space_without_object_points():
    marble = MarbleChannel(space="object")
    with pytest.raises(ValueError, match="object-space points"):
        tracer.channel_color(marble, np.zeros((2, 3)))
    np.testing.assert_array_equal(tracer.channel_color(marble, np.zeros((2, 3)) + 9.0,
                                                       object_points=np.zeros((2, 3))),
                                  marble_color(np.zeros((2, 3)), MarbleChannel()))
