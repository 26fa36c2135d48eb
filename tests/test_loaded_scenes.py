"""Scenes are loaded once and kept by structure, and what changed on disk is seen
(mimarble/mitsuba/rendering/loaded_scenes.py, scene/parser.py's parsed files)."""

import shutil

import numpy as np
import pytest
from PIL import Image

import mimarble
from mimarble import scene as scene_language

mi, dr = mimarble.mi, mimarble.dr

from mimarble.mitsuba.rendering import loaded_scenes  # noqa: E402
from mimarble.mitsuba.rendering.loaded_scenes import LOADED  # noqa: E402

SCENE = """
image    { width 16 height 12 samples 1 }
camera   { eye < 0 0 9 > lookat < 0 0 0 > up < 0 1 0 > fov 30 }
light    { position < 10 10 10 > color < 1 1 1 > }
material "m" { diffuse { marble { period PERIOD distortion 2 octaves 3 } } }
sphere { center < 0 0 0 > radius 2 material "m" }
"""


def counting_loads(monkeypatch):
    loads = []
    original = mi.load_dict
    monkeypatch.setattr(loaded_scenes.mi, "load_dict",
                        lambda d, *a, **k: (loads.append(1), original(d, *a, **k))[1])
    return loads


def fresh(text, monkeypatch, **options):
    """The image of ``text`` rendered from nothing kept: a new load, traced afresh."""
    LOADED.clear()
    with monkeypatch.context() as m:
        m.setenv("MIMARBLE_FREEZE", "0")
        image = mimarble.render(scene_language.parse(text), **options)
    LOADED.clear()
    return image


def test_a_warm_render_loads_and_translates_nothing(llvm, monkeypatch):
    scene = scene_language.parse(SCENE.replace("PERIOD", "1.3"))
    LOADED.clear()
    loads = counting_loads(monkeypatch)
    first = mimarble.render(scene)
    translated = []
    monkeypatch.setattr(loaded_scenes, "to_mitsuba",
                        lambda *a, **k: translated.append(1))   # would fail if called
    again = mimarble.render(scene)
    assert loads == [1] and translated == []
    np.testing.assert_array_equal(first, again)


def test_in_place_values_reuse_the_loaded_scene(llvm, monkeypatch):
    LOADED.clear()
    loads = counting_loads(monkeypatch)
    images = [mimarble.render(scene_language.parse(SCENE.replace("PERIOD", p)))
              for p in ("1.3", "2.1", "1.3")]
    assert loads == [1]
    np.testing.assert_array_equal(images[0], images[2])
    np.testing.assert_array_equal(images[1], fresh(SCENE.replace("PERIOD", "2.1"), monkeypatch))


def test_a_scene_file_edited_on_disk_is_seen(llvm, tmp_path, monkeypatch):
    path = tmp_path / "s.scene"
    path.write_text(SCENE.replace("PERIOD", "1.3"))
    before = mimarble.render(str(path))
    path.write_text(SCENE.replace("PERIOD", "0.6"))
    after = mimarble.render(str(path))
    assert not np.array_equal(before, after)
    np.testing.assert_array_equal(after, fresh(SCENE.replace("PERIOD", "0.6"), monkeypatch))


def veins_over_an_image(tmp_path):
    """(scene file, its text, its image map) of future-work's veins-over-image at 16², in a
    copy of the folder that a test may change."""
    folder = tmp_path / "scene"
    shutil.copytree("scenes/future-work", folder)
    path = folder / "veins-over-image.scene"
    text = path.read_text()
    text = text[:text.index("image ")] + "image { width 16 height 16 samples 1 }\n" \
        + text[text.index("\n", text.index("image ")) + 1:]
    path.write_text(text)
    return path, text, folder / "maps" / "flagstones.png"


def test_an_image_map_rewritten_on_disk_is_seen(llvm, tmp_path):
    path, text, image_map = veins_over_an_image(tmp_path)
    before = mimarble.render(str(path))
    grey = np.full((8, 8, 3), 128, dtype=np.uint8)
    Image.fromarray(grey).save(image_map)
    after = mimarble.render(str(path))
    assert not np.array_equal(before, after)
    LOADED.clear()
    np.testing.assert_array_equal(after, mimarble.render(scene_language.parse(
        text, filename=str(path))))


def test_few_scenes_are_kept_and_their_sphere_tables_go_with_them(llvm):
    from mimarble.mitsuba.plugins.sphere_hit import SphereTable
    LOADED.clear()
    SphereTable._tables.clear()
    for period in ("0.5", "0.7", "0.9"):
        scene = scene_language.parse(SCENE.replace("PERIOD", period).replace("octaves 3",
                                                                              f"octaves {period[-1]}"))
        mimarble.render(scene)
    kept = [id(s) for s, _, _ in LOADED.scenes.values()]
    assert len(kept) == loaded_scenes.SCENES
    assert all(k in kept for k in SphereTable._tables)


def test_a_sphere_table_holds_no_shape_and_a_scene_at_a_freed_id_gets_its_own(llvm):
    """JIT variants' tables hold no shape (a dropped scene's shapes leave Dr.Jit's registry,
    issue 43); what tells a new scene at a dropped one's id (Python reuses ids) is the
    held copies of the old spheres' ``to_world``: the new scene's are other variables. The
    reuse is simulated by moving the old scene's entry to the new scene's id."""
    from mimarble.mitsuba.plugins.sphere_hit import SphereTable
    def sphere_at(x):
        return mi.load_dict({"type": "scene", "s": {"type": "sphere", "center": [x, 0, 0],
                                                     "radius": 1.0}})
    old, new = sphere_at(0.0), sphere_at(5.0)
    table = SphereTable.for_trace(old)
    assert table.shapes is None
    SphereTable._tables[id(new)] = SphereTable._tables.pop(id(old))
    assert SphereTable.for_trace(new) is not table
    centre, _ = SphereTable.for_trace(new).lookup(mi.ShapePtr(new.shapes()[0]))
    assert centre.x.numpy()[0] == pytest.approx(5.0)
    SphereTable.forget(new)


def test_an_image_map_copied_over_with_its_old_modification_time_is_seen(llvm, tmp_path):
    # What cp -p, rsync -t and tar x do: the same size and modification time, new bytes.
    import os
    path, _, image_map = veins_over_an_image(tmp_path)
    Image.fromarray(np.full((8, 8, 3), 40, dtype=np.uint8)).save(image_map)
    before = mimarble.render(str(path))
    facts = os.stat(image_map)
    for level in range(41, 256):                 # another grey whose PNG is as long
        Image.fromarray(np.full((8, 8, 3), level, dtype=np.uint8)).save(image_map)
        if os.stat(image_map).st_size == facts.st_size:
            break
    assert os.stat(image_map).st_size == facts.st_size
    os.utime(image_map, ns=(facts.st_atime_ns, facts.st_mtime_ns))
    after = mimarble.render(str(path))
    assert not np.array_equal(before, after)


@pytest.mark.parametrize("freeze", ["1", "0"])
def test_a_mesh_file_rewritten_with_the_same_counts_and_bounds_is_seen(llvm, tmp_path,
                                                                      monkeypatch, freeze):
    # Issue 37 item 1: an OBJ square's triangle rewritten as the other half of the square
    # (4 vertices, 1 face, the same bounds and size), its modification time kept.
    import os
    monkeypatch.setenv("MIMARBLE_FREEZE", freeze)
    obj = tmp_path / "quad.obj"
    quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf {}\n"
    obj.write_text(quad.format("1 2 3"))
    path = tmp_path / "s.scene"
    path.write_text(SCENE.replace('sphere { center < 0 0 0 > radius 2 material "m" }',
                                  'mesh { file "quad.obj" transform { scale 3 } material "m" }')
                    .replace("PERIOD", "1.3").replace("eye < 0 0 9 >", "eye < 1.5 1.5 9 >")
                    .replace("lookat < 0 0 0 >", "lookat < 1.5 1.5 0 >"))
    before = mimarble.render(str(path))
    facts = os.stat(obj)
    obj.write_text(quad.format("1 3 4"))
    os.utime(obj, ns=(facts.st_atime_ns, facts.st_mtime_ns))
    after = mimarble.render(str(path))
    assert not np.array_equal(before, after)
    LOADED.clear()
    np.testing.assert_array_equal(after, mimarble.render(scene_language.parse(
        path.read_text(), filename=str(path))))


def test_scenes_that_differ_in_place_render_as_from_nothing_in_path_mode(llvm, monkeypatch):
    """Path mode, a roughplastic over a product of two marbles (future-work's two-pass
    marble, 16²): scenes that differ in a marble's in-place values (period, scale), rendered
    in turn through the loaded-scene cache, each give the bits of that scene rendered from
    nothing. roughplastic weighs its sampling by the expression's mean() (computed when it
    is loaded; an edit of a top-level texture tells the scene, not the BSDF); before, that
    mean was the 2^14-point sampled one at load, which depends on the period: the first
    scene's weight stayed, and the second scene's image differed from its own (≤ 1e-5)."""
    text = open("scenes/future-work/two-pass-marble.scene").read().replace(
        "width 500 height 500", "width 16 height 16")
    texts = [text, text.replace("period 1.5", "period 2.5").replace("scale 2.0", "scale 2.7")]
    LOADED.clear()
    loads = counting_loads(monkeypatch)
    images = [mimarble.render(scene_language.parse(t), mode="path", spp=4)
              for t in texts + texts[:1]]
    assert loads == [1]
    for t, image in zip(texts + texts[:1], images):
        np.testing.assert_array_equal(image, fresh(t, monkeypatch, mode="path", spp=4))


@pytest.mark.parametrize("mode", ["whitted", "path"])
def test_a_camera_orbited_and_a_light_moved_and_dimmed_reuse_the_loaded_scene(llvm, monkeypatch,
                                                                              mode):
    # The studio's orbit and light controls (issue 41): the camera's placement and a point
    # light's position and intensity are written in place; the image is a fresh load's.
    # The eye keeps its distance to the sphere: the clip planes (structure) stay.
    # A marble's default tolerance follows the scene's lighting (the error budget): a
    # tolerance of its own keeps a dimmed light from changing the marble's structure.
    text = SCENE.replace("PERIOD", "1.3").replace("octaves 3", "octaves 3 tolerance 0.001")
    moved = text.replace("eye < 0 0 9 >", "eye < 5.4 0 7.2 >").replace(
        "position < 10 10 10 > color < 1 1 1 >", "position < 8 12 9 > color < 0.6 0.6 0.6 >")
    assert moved.count("<") == text.count("<") and moved != text
    scenes = [scene_language.parse(t) for t in (text, moved, text)]
    LOADED.clear()
    loads = counting_loads(monkeypatch)
    images = [mimarble.render(s, mode=mode, spp=4) for s in scenes]
    assert loads == [1]
    np.testing.assert_array_equal(images[0], images[2])
    assert not np.array_equal(images[0], images[1])
    np.testing.assert_array_equal(images[1], fresh(moved, monkeypatch, mode=mode, spp=4))


def test_clip_planes_that_differ_past_float32_share_the_loaded_scene(llvm, monkeypatch):
    # An orbit's eye, rotated in float64, moves the clip planes in their 16th digit: the
    # sensor holds them in float32, so the loaded scene is the same one (issue 41's orbit).
    from mimarble.mitsuba.translate.scene_dict import to_mitsuba
    from mimarble.scene.keys import with_value
    from mimarble.studio.camera import orbited_eye
    scene = scene_language.parse(SCENE.replace("PERIOD", "1.3"))
    orbited = scene
    for _ in range(3):
        orbited = with_value(orbited, "camera.eye", orbited_eye(orbited.camera, 2.0, 1.0))
    near = (to_mitsuba(scene)["sensor"]["near_clip"], to_mitsuba(orbited)["sensor"]["near_clip"])
    assert near[0] != near[1] and np.float32(near[0]) == np.float32(near[1])
    LOADED.clear()
    loads = counting_loads(monkeypatch)
    mimarble.render(scene)
    image = mimarble.render(orbited)
    assert loads == [1]
    LOADED.clear()
    with monkeypatch.context() as m:
        m.setenv("MIMARBLE_FREEZE", "0")
        np.testing.assert_array_equal(image, mimarble.render(orbited))
    LOADED.clear()
