"""Hand-computed pixels of tiny scenes, rendered by the reference tracer (mimarble.reference)."""

import dataclasses
import math

import numpy as np
import pytest

from mimarble import scene as sc
from mimarble import reference
from mimarble.reference import intersection, tracer

T15 = math.tan(math.radians(15.0))
KA, KD, KS = (0.3, 0.5, 0.7), (0.2, 0.6, 0.4), (0.25, 0.1, 0.05)
A, I = (0.2, 0.4, 0.1), (0.9, 0.8, 1.1)
BG = (0.01, 0.02, 0.03)


def scene_text(size=5, spp=1, light="< 0 0 5 >", extra="", material=None, ambient=A):
    material = material or (f"ambient {{ color < {KA[0]} {KA[1]} {KA[2]} > }} "
                            f"diffuse {{ color < {KD[0]} {KD[1]} {KD[2]} > }} "
                            f"specular {{ color < {KS[0]} {KS[1]} {KS[2]} > }} shininess 8")
    return f"""
        image  {{ width {size} height {size} samples {spp} background < {BG[0]} {BG[1]} {BG[2]} > }}
        camera {{ eye < 0 0 5 > lookat < 0 0 0 > up < 0 1 0 > fov 30 }}
        ambient < {ambient[0]} {ambient[1]} {ambient[2]} >
        light  {{ position {light} color < {I[0]} {I[1]} {I[2]} > }}
        material "m" {{ {material} }}
        sphere {{ center < 0 0 0 > radius 1 material "m" }}
        {extra}
    """


def phong(p, n, light, view, shininess=8.0, ambient=A, ka=KA, kd=KD, ks=KS, lit=True):
    """The shading formula for one point, in plain float math."""
    def norm(a):
        s = math.sqrt(sum(c * c for c in a))
        return [c / s for c in a]
    l = norm([light[k] - p[k] for k in range(3)])
    h = norm([l[k] + view[k] for k in range(3)])
    ndl = sum(n[k] * l[k] for k in range(3))
    ndh = sum(n[k] * h[k] for k in range(3))
    out = [ka[k] * ambient[k] for k in range(3)]
    if lit and ndl > 0:
        for k in range(3):
            out[k] += I[k] * (kd[k] * max(0.0, ndl) + ks[k] * max(0.0, ndh) ** shininess)
    return np.array(out)


def test_centre_pixel_light_at_eye():
    img = reference.render(sc.parse(scene_text()))
    # ray (0,0,-1) hits p = (0,0,1); n = l = h = (0,0,1): n.l = n.h = 1
    expected = [KA[k] * A[k] + I[k] * (KD[k] + KS[k]) for k in range(3)]
    np.testing.assert_allclose(img[2, 2], expected, rtol=0, atol=1e-14)


def test_corner_pixel_misses_to_background():
    img = reference.render(sc.parse(scene_text()))
    # corner ray ∝ (-0.8·tan15, 0.8·tan15, -1): its distance to the centre is
    # 5·sin(atan(0.8·√2·tan15)) ≈ 1.45 > 1
    assert 5 * math.sin(math.atan(0.8 * math.sqrt(2) * T15)) > 1
    for j, i in [(0, 0), (0, 4), (4, 0), (4, 4)]:
        np.testing.assert_array_equal(img[j, i], BG)


def test_off_centre_pixel_solved_analytically():
    img = reference.render(sc.parse(scene_text(light="< 3 4 6 >")))
    # pixel column 2, row 1: film (0.5, 0.3) -> d ∝ (0, 0.4·tan15, -1)
    s = 0.4 * T15
    norm = math.sqrt(1 + s * s)
    d = (0.0, s / norm, -1 / norm)
    # |e + t d|² = 1 with e = (0,0,5): t² + 2(e·d)t + 24 = 0, nearest root
    ed = 5 * d[2]
    t = -ed - math.sqrt(ed * ed - 24)
    p = (t * d[0], t * d[1], 5 + t * d[2])
    assert abs(math.hypot(*p) - 1) < 1e-14
    expected = phong(p, p, (3, 4, 6), [-c for c in d])     # n = p on the unit sphere
    np.testing.assert_allclose(img[1, 2], expected, rtol=0, atol=1e-13)
    # and the pixel below the centre, by symmetry of the same quadratic: d ∝ (0, -s, -1)
    p2 = (0.0, -p[1], p[2])
    expected2 = phong(p2, p2, (3, 4, 6), [0.0, s / norm, 1 / norm])
    np.testing.assert_allclose(img[3, 2], expected2, rtol=0, atol=1e-13)


def test_small_sphere_shadows_the_centre_pixel():
    light = "< 0 5 5 >"
    blocker = 'sphere { center < 0 2.5 3 > radius 0.3 material "m" }'   # midway from (0,0,1) to light
    lit = reference.render(sc.parse(scene_text(light=light)))
    shadowed = reference.render(sc.parse(scene_text(light=light, extra=blocker)))
    p = (0.0, 0.0, 1.0)
    expected_lit = phong(p, p, (0, 5, 5), (0, 0, 1))
    assert np.all(expected_lit - np.multiply(KA, A) > 0.05)     # the light matters there
    np.testing.assert_allclose(lit[2, 2], expected_lit, rtol=0, atol=1e-14)
    # in shadow: diffuse and specular vanish, only ka⊙A remains
    np.testing.assert_allclose(shadowed[2, 2], np.multiply(KA, A), rtol=0, atol=1e-15)


def test_shadow_hit_open_segment_any_hit():
    centers = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    radii = np.array([1.0, 1.0])
    o = np.array([[-3.0, 0, 0], [-3.0, 0, 0], [-3.0, 0, 0], [-3.0, 3, 0], [0.0, 0, 0], [-0.5, 0, 0]])
    d = np.array([[1.0, 0, 0], [1.0, 0, 0], [-1.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0]])
    t_max = np.array([10.0, 1.9, 10.0, 10.0, 0.9, 0.4])
    # ray 0: hits both; 1: stops before the first sphere (t=2); 2: spheres behind it;
    # 3: passes above both; 4: starts inside, exit at t=1 beyond t_max 0.9;
    # 5: starts inside sphere 0, exit at t=1.5 beyond t_max 0.4 -> not blocked
    expected = [True, False, False, False, False, False]
    np.testing.assert_array_equal(tracer.shadow_hit(centers, radii, o, d, t_max), expected)
    t_max2 = t_max.copy()
    t_max2[4] = 1.1
    assert tracer.shadow_hit(centers, radii, o, d, t_max2)[4]


def test_spp4_is_the_mean_of_the_four_stratum_centre_rays():
    s = sc.parse(scene_text(size=5, spp=4, light="< 3 4 6 >"))
    img = reference.render(s)
    j, i = 1, 1                                 # a pixel on the sphere's edge
    vals = []
    for b in range(2):
        for a in range(2):
            x = (i + (a + 0.5) / 2) / 5
            y = (j + (b + 0.5) / 2) / 5
            o, d = tracer.camera_rays(s, [x], [y])
            vals.append(tracer.trace(s, o, d)[0])
    vals = np.array(vals)
    assert np.ptp(vals[:, 0]) > 0.01            # the four samples really differ
    np.testing.assert_allclose(img[j, i], vals.mean(axis=0), rtol=0, atol=1e-15)
    # spp 1 of the same scene is the pixel-centre ray
    o, d = tracer.camera_rays(s, [(i + 0.5) / 5], [(j + 0.5) / 5])
    np.testing.assert_allclose(reference.render(s, spp=1)[j, i], tracer.trace(s, o, d)[0], rtol=0, atol=0)


def test_spp_must_be_a_perfect_square():
    s = sc.parse(scene_text(size=3))
    for bad in (2, 3, 0, 8):
        with pytest.raises(ValueError):
            reference.render(s, spp=bad)
    assert reference.render(s, spp=9).shape == (3, 3, 3)


def test_camera_corner_direction_matches_mitsuba_convention():
    s = sc.parse("image { width 4 height 2 } camera { eye < 0 0 10 > lookat < 0 0 0 > up < 0 1 0 > fov 40 }")
    _, d = tracer.camera_rays(s, [0.0, 1.0, 0.5], [0.0, 1.0, 0.5])
    th = math.tan(math.radians(20))
    for k, (sx, sy) in enumerate([(-2 * th, th), (2 * th, -th), (0.0, 0.0)]):
        e = np.array([sx, sy, -1.0])
        np.testing.assert_allclose(d[k], e / np.linalg.norm(e), rtol=0, atol=1e-15)


def test_sample_positions_grid():
    x, y = tracer.sample_positions(4, 3, 2, 5, 6)      # pixel 5 = column 1, row 1
    np.testing.assert_allclose(x, [1.25 / 4, 1.75 / 4, 1.25 / 4, 1.75 / 4])
    np.testing.assert_allclose(y, [1.25 / 3, 1.25 / 3, 1.75 / 3, 1.75 / 3])


def test_two_lights_add():
    two = scene_text(light="< 3 4 6 >", ambient=(0, 0, 0)).replace(
        "light", f"light {{ position < -4 1 5 > color < {I[0]} {I[1]} {I[2]} > }} light", 1)
    a = reference.render(sc.parse(scene_text(light="< 3 4 6 >", ambient=(0, 0, 0))))
    b = reference.render(sc.parse(scene_text(light="< -4 1 5 >", ambient=(0, 0, 0))))
    both = reference.render(sc.parse(two))
    hit = np.any(a != np.array(BG), axis=-1)
    assert hit.sum() >= 5
    np.testing.assert_allclose(both[hit], a[hit] + b[hit], rtol=0, atol=1e-14)
    assert np.all(both[hit].sum(-1) > a[hit].sum(-1) - 1e-15)


def test_absent_channels_contribute_nothing():
    img = reference.render(sc.parse(scene_text(material="shininess 4")))
    np.testing.assert_array_equal(img[2, 2], [0.0, 0.0, 0.0])      # a hit, but no channels
    np.testing.assert_array_equal(img[0, 0], BG)
    # diffuse only: centre = I⊙kd exactly (no specular, no ambient)
    img = reference.render(sc.parse(scene_text(material="diffuse { color < 0.2 0.6 0.4 > }")))
    np.testing.assert_allclose(img[2, 2], np.multiply(I, KD), rtol=0, atol=1e-15)


def test_material_with_only_an_ambient_channel():
    img = reference.render(sc.parse(scene_text(material="ambient { color < 0.3 0.5 0.7 > }",
                                               light="< 3 4 6 >")))
    hit = np.any(img != np.array(BG), axis=-1)
    assert hit.sum() >= 5
    np.testing.assert_allclose(img[hit], np.tile(np.multiply(KA, A), (hit.sum(), 1)), rtol=0, atol=1e-15)


def test_hit_record_passes_back_the_marble_colour():
    text = scene_text(material="diffuse { marble { scale 1.3 period 1.1 distortion 2 octaves 6 } }")
    s = sc.parse(text)
    o, d = tracer.camera_rays(s, np.linspace(0.35, 0.65, 7), np.full(7, 0.45))
    rec = tracer.hit(tracer.prepare(s), o, d)
    assert rec.index.size == 7
    np.testing.assert_allclose(np.linalg.norm(rec.p, axis=1), 1.0, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(rec.colors["diffuse"],
                                  reference.marble_color(rec.p, s.materials["m"].diffuse))
    assert rec.colors["ambient"] is None and rec.colors["specular"] is None


def test_marble_pixel_is_marble_colour_times_lighting():
    m = "diffuse { marble { scale 1.3 period 1.1 distortion 2 octaves 6 } } shininess 8"
    s = sc.parse(scene_text(material=m, ambient=(0, 0, 0)))
    img = reference.render(s)
    kd = reference.marble_color(np.array([[0.0, 0.0, 1.0]]), s.materials["m"].diffuse)[0]
    np.testing.assert_allclose(img[2, 2], np.multiply(I, kd), rtol=0, atol=1e-14)


def test_equal_marble_channels_are_evaluated_once():
    s = sc.load("scenes/fig11a.scene")
    prep = tracer.prepare(s)
    assert len(prep.channels) == 2            # one marble (ambient = diffuse) + the specular colour
    m = prep.materials[0]
    assert m.ambient == m.diffuse and m.ambient.pos != m.diffuse.pos


def test_non_square_image_and_chunking_agree():
    s = sc.parse(scene_text(size=7, light="< 3 4 6 >"))
    s = dataclasses.replace(s, image=dataclasses.replace(s.image, width=9, height=5, samples=4))
    full = tracer.render(s)
    tiny_chunks = tracer.render(s, chunk_rays=3)     # one pixel per batch
    assert full.shape == (5, 9, 3)
    np.testing.assert_array_equal(full, tiny_chunks)


def test_eye_inside_sphere_sees_its_inside_lit_two_sided():
    # eye at the centre of a big sphere, light inside too: the inner wall is lit (two-sided normal)
    s = sc.parse("""
        image { width 3 height 3 } camera { eye < 0 0 0 > lookat < 0 0 -1 > up < 0 1 0 > fov 30 }
        light { position < 0 0 0 > color < 1 1 1 > }
        material "m" { diffuse { color < 0.5 0.5 0.5 > } }
        sphere { center < 0 0 0 > radius 10 material "m" }
    """)
    np.testing.assert_allclose(reference.render(s)[1, 1], [0.5, 0.5, 0.5], rtol=0, atol=1e-14)


def test_shadow_hit_stops_testing_blocked_rays(monkeypatch):
    tested = []
    real = intersection.sphere_roots

    def counting(o, d, c, r):
        tested.append(len(d))
        return real(o, d, c, r)

    monkeypatch.setattr(intersection, "sphere_roots", counting)
    centers = np.array([[0.0, 0, 0], [3.0, 0, 0], [6.0, 0, 0]])
    o = np.array([[-3.0, 0, 0], [-3.0, 0, 0], [-3.0, 5, 0]])
    d = np.array([[1.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0]])
    blocked = tracer.shadow_hit(centers, np.ones(3), o, d, np.full(3, 100.0))
    np.testing.assert_array_equal(blocked, [True, True, False])
    assert tested == [3, 1, 1]     # two rays blocked by the first sphere; only the third goes on
