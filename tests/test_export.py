"""``mimarble export``: the XML (``mi.load_file``) and the Python file (``mi.load_dict`` of
its ``scene``) render as the scene dict itself does (``mi.load_dict(to_mitsuba(scene))``).

Every shipped scene is exported and rendered both ways at 16×16, one sample: the dict is
the independent side (what ``mimarble render`` renders). Values are checked against
Mitsuba's own XML parser (``mi.parser.parse_string``), not against the writer.
"""

import os
import runpy
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import mimarble
from mimarble.tools import export
from mimarble import scene as scene_language
from mimarble.mitsuba.translate.scene_dict import to_mitsuba
from mimarble.scene.edits import resized, with_image_size

from commands import ROOT, mimarble_cli

mi = mimarble.mi

SCENES = sorted((ROOT / "scenes").glob("*.scene")) + sorted((ROOT / "scenes").glob("*/*.scene"))
MAP = ROOT / "scenes" / "future-work" / "maps" / "flagstones.png"


def small(path, size=16):
    return resized(scene_language.load(path), size)


def render(scene):
    """One fixed-seed render of a loaded Mitsuba scene, as float32 NumPy."""
    return np.array(mi.render(scene, seed=0))


def with_xml_inverses(value):
    """The dict with every transform as the XML parser rebuilds it (export.xml_transform):
    the one thing XML cannot carry is a transform's inverse (export's docstring)."""
    if isinstance(value, dict):
        return {k: with_xml_inverses(v) for k, v in value.items()}
    if hasattr(value, "inverse_transpose"):
        return export.xml_transform(value)
    return value


def xml_render(scene_dict, folder):
    path = Path(folder) / "scene.xml"
    path.write_text(export.to_xml(scene_dict, folder), encoding="utf-8")
    return render(mi.load_file(str(path)))


def python_render(scene_dict, folder):
    path = Path(folder) / "scene.py"
    path.write_text(export.to_python(scene_dict, mi.variant(), folder), encoding="utf-8")
    return render(mi.load_dict(runpy.run_path(str(path))["scene"]))


def assert_both_render_as_the_dict(scene_dict, folder):
    """The XML as the dict with the inverses XML makes, the Python file as the dict itself:
    bit for bit."""
    np.testing.assert_array_equal(xml_render(scene_dict, folder),
                                  render(mi.load_dict(with_xml_inverses(scene_dict))))
    np.testing.assert_array_equal(python_render(scene_dict, folder),
                                  render(mi.load_dict(scene_dict)))


def test_there_are_scenes_in_every_folder():
    assert len(SCENES) >= 30
    assert {p.parent.name for p in SCENES} >= {"scenes", "fine-veins", "future-work"}


@pytest.mark.parametrize("path", SCENES, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_every_scene_renders_from_its_xml_and_python_as_from_its_dict(path, tmp_path):
    scene = small(path)
    translucent = any(m.subsurface for m in scene.materials.values())   # whitted refuses it
    scene_dict = to_mitsuba(scene, "path" if translucent else "whitted", 1)
    ours = render(mi.load_dict(scene_dict))
    # XML: bit for bit — the translator gives its shapes' transforms the inverses XML
    # makes (translate.shapes.mitsuba_transform), and the scenes' cameras read none.
    np.testing.assert_array_equal(xml_render(scene_dict, tmp_path), ours)
    np.testing.assert_array_equal(python_render(scene_dict, tmp_path), ours)


@pytest.mark.parametrize("name", ["fig11a", "future-work/veins-over-image",
                                  "beyond-spheres/pawns", "beyond-spheres/row-of-boxes"])
def test_path_mode_exports_render_as_the_dict(name, tmp_path):
    path = ROOT / "scenes" / f"{name}.scene"
    if not path.exists():
        pytest.skip(f"{path} is not here")
    scene_dict = to_mitsuba(small(path), "path", 1)
    assert_both_render_as_the_dict(scene_dict, tmp_path)


AREA_LIGHTS = """
image   { width 16 height 16 samples 4 background < 0.1 0.2 0.3 > }
camera  { eye < 0 -7 3 > lookat < 0 0 0 > up < 0 0 1 > fov 35 }
ambient < 0.1 0.1 0.1 >
light   { position < 4 -4 6 > color < 0.7 0.7 0.6 >
          area { axis1 < 2 0 0 > axis2 < 0 1 1 > samples 4 } }
light   { position < -5 -2 4 > color < 0.3 0.3 0.5 > area { radius 0.5 samples 4 } }
material "veined" {
  diffuse {
    mix {
      image { file "MAP" }
      marble { period 1.3 distortion 2 octaves 4
               transform { rotate < 10 20 30 > translate < 0.25 0 0 > scale 1.5 } }
      weight 0.4
    }
  }
  specular { color < 0.3 0.3 0.3 > }
}
sphere { center < 0 0 0 > radius 2 material "veined" }
"""


@pytest.mark.parametrize("mode", ["whitted", "path"])
def test_area_lights_transforms_and_a_hostile_map_name_render_alike(mode, tmp_path):
    """Rectangle and sphere lights, a rotated marble, an expression, and an image map whose
    name holds what XML and Mitsuba's $-substitution would read as markup: data here."""
    maps = tmp_path / "maps"
    maps.mkdir()
    name = "a<b&c'd $e \\$f é.png"
    shutil.copy(MAP, maps / name)
    scene_file = tmp_path / "area.scene"
    scene_file.write_text(AREA_LIGHTS.replace("MAP", f"maps/{name}"), encoding="utf-8")
    scene_dict = to_mitsuba(scene_language.load(scene_file), mode, 4)
    xml = export.to_xml(scene_dict, tmp_path)
    assert 'value="maps/a&lt;b&amp;c\'d \\$e \\\\$f é.png"' in xml       # relative, escaped
    assert_both_render_as_the_dict(scene_dict, tmp_path)


@pytest.mark.parametrize("name", ['quote".png', "new\nline.png", "tab\t.png", "amp&lt;.png",
                                  "$spp.png", "back\\$slash.png", "ünï\u2603.png"])
def test_any_file_name_reaches_mitsuba_as_it_is(name, tmp_path):
    """The file name Mitsuba's XML parser reads is the one in the dict, whatever it holds
    (what a scene file cannot say: quotes, newlines, tabs)."""
    target = tmp_path / name
    scene_dict = {"type": "scene", "t": {"type": "bitmap", "filename": str(target)}}
    for folder in (tmp_path, tmp_path / "elsewhere"):   # written relative, then absolute
        state = mi.parser.parse_string(mi.parser.ParserConfig(mi.variant()),
                                       export.to_xml(scene_dict, folder))
        read = state.nodes[1].props["filename"]
        assert (folder / read if not os.path.isabs(read) else Path(read)) == target


def test_a_character_xml_cannot_hold_is_refused_in_one_sentence():
    with pytest.raises(export.ExportError, match=r"U\+0001, which XML cannot hold"):
        export.to_xml({"type": "scene", "t": {"type": "bitmap", "filename": "a\x01.png"}})


def test_numbers_read_back_as_the_same_doubles():
    """Floats as the shortest decimal of the double, read by Mitsuba's parser (fast_float)."""
    values = [0.1 + 0.2, 1 / 3, 5e-324, 1.7976931348623157e308, -0.0, 2.0 ** -1074 * 3,
              float(np.float32(0.7)), 123456789.123456789]
    scene_dict = {"type": "scene", "integrator": {
        "type": "whitted", **{f"f{k}": v for k, v in enumerate(values)},
        "count": 2 ** 40, "flag": True, "vec": [0.1, 1 / 3, -2.5], "text": "x y"}}
    props = mi.parser.parse_string(mi.parser.ParserConfig(mi.variant()),
                                   export.to_xml(scene_dict)).nodes[1].props
    for k, v in enumerate(values):
        assert props[f"f{k}"] == v and str(props[f"f{k}"]) == str(v)
    assert props["count"] == 2 ** 40 and props["flag"] is True and props["text"] == "x y"
    assert list(props["vec"]) == [0.1, 1 / 3, -2.5]


def test_a_transform_keeps_its_float32_entries_exactly():
    rows = [[0.1, 0.2, 0.3, 1e-7], [1 / 3, 2.0, 0.0, -5.5], [0.0, 0.0, 7.0, 1e20], [0, 0, 0, 1]]
    transform = mi.ScalarTransform4f(rows)
    scene_dict = {"type": "scene", "t": {"type": "marble", "to_world": transform}}
    props = mi.parser.parse_string(mi.parser.ParserConfig(mi.variant()),
                                   export.to_xml(scene_dict)).nodes[1].props
    read = np.array(props["to_world"].matrix)
    np.testing.assert_array_equal(read, np.array(transform.matrix, dtype=np.float64))


def test_a_map_in_the_xml_folder_is_relative_and_moves_with_it(tmp_path):
    folder = tmp_path / "export"
    (folder / "maps").mkdir(parents=True)
    shutil.copy(MAP, folder / "maps" / "stone.png")
    text = AREA_LIGHTS.replace("MAP", "maps/stone.png")
    (folder / "s.scene").write_text(text)
    scene_dict = to_mitsuba(resized(scene_language.load(folder / "s.scene"), 8), "whitted", 1)
    (folder / "s.xml").write_text(export.to_xml(scene_dict, folder))
    moved = tmp_path / "moved"
    shutil.move(folder, moved)
    assert 'value="maps/stone.png"' in (moved / "s.xml").read_text()
    ours = render(mi.load_dict(with_xml_inverses(to_mitsuba(
        resized(scene_language.load(moved / "s.scene"), 8), "whitted", 1))))
    np.testing.assert_array_equal(render(mi.load_file(str(moved / "s.xml"))), ours)


def test_a_map_outside_the_xml_folder_is_absolute(tmp_path):
    scene_dict = {"type": "scene", "t": {"type": "bitmap", "filename": str(MAP)}}
    assert f'value="{MAP}"' in export.to_xml(scene_dict, tmp_path)


def test_top_level_objects_keep_their_ids_and_shared_textures_are_referenced():
    scene_dict = to_mitsuba(small(ROOT / "scenes" / "fig11a.scene"), "whitted", 1)
    xml = export.to_xml(scene_dict)
    assert '<texture type="marble" id="texture_0" name="texture_0">' in xml
    assert xml.count('<ref name="ambient" id="texture_0"/>') == 1
    assert xml.count('<ref name="diffuse" id="texture_0"/>') == 1
    loaded = mi.load_string(xml)
    assert [s.id() for s in loaded.shapes()] == ["sphere_0"]


def test_what_neither_file_can_hold_is_refused_in_one_sentence():
    with pytest.raises(export.ExportError, match="no XML or Python literal form"):
        export.to_xml({"type": "scene", "t": {"type": "bitmap", "data": object()}})
    with pytest.raises(export.ExportError, match="no XML or Python literal form"):
        export.to_python({"type": "scene", "b": {"type": "bitmap", "bitmap": mi.Bitmap(
            np.zeros((2, 2, 3), dtype=np.float32))}}, mi.variant())
    with pytest.raises(export.ExportError, match="neither mimarble nor Mitsuba knows it"):
        export.to_xml({"type": "scene", "x": {"type": "no_such_plugin"}})


def test_a_failed_export_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    out = tmp_path / "scene.xml"
    out.write_text("old")
    from mimarble.mitsuba.translate import scene_dict as translate
    monkeypatch.setattr(translate, "to_mitsuba", lambda *a, **k: {
        "type": "scene", "t": {"type": "bitmap", "filename": "bad\x02"}})
    with pytest.raises(export.ExportError):
        export.export(small(ROOT / "scenes" / "fig11a.scene"), out)
    assert out.read_text() == "old" and os.listdir(tmp_path) == ["scene.xml"]


# ---------------------------------------------------------------------------
# The command

def test_the_command_writes_xml_that_renders_as_mimarble_does(tmp_path):
    out = tmp_path / "fig.xml"
    result = mimarble_cli("export", ROOT / "scenes" / "fig11a.scene", "-o", out,
                          "--width", "12", "--height", "8", "--spp", "4")
    assert result.returncode == 0, result.stderr
    assert f"{out}: Mitsuba XML" in result.stdout and "4 spp, 12x8" in result.stdout
    scene = with_image_size(scene_language.load(ROOT / "scenes" / "fig11a.scene"), 12, 8)
    np.testing.assert_array_equal(render(mi.load_file(str(out))),
                                  render(mi.load_dict(to_mitsuba(scene, "whitted", 4))))


def test_a_scene_of_a_box_alone_is_not_called_empty(tmp_path):
    scene = tmp_path / "box.scene"
    scene.write_text('image { width 8 height 8 }\nlight { position < 5 5 5 > }\n'
                     'material "m" { diffuse { color < 1 0 0 > } }\nbox { material "m" }\n')
    result = mimarble_cli("export", scene, "-o", tmp_path / "box.xml")
    assert result.returncode == 0, result.stderr
    assert "no shapes" not in result.stderr and "warning" not in result.stderr
    assert '<shape type="cube" id="box_0"' in (tmp_path / "box.xml").read_text()


def test_the_python_file_runs_as_a_script_and_renders_the_scene(tmp_path):
    out = tmp_path / "fig.py"
    result = mimarble_cli("export", "fig11a", "-o", out, "--python", "--mode", "path",
                          "--spp", "2", "--width", "8", "--height", "8")
    assert result.returncode == 0, result.stderr
    env = dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb",
               PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    run = subprocess.run([sys.executable, str(out), str(tmp_path / "fig.exr")], env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    image = np.array(mi.Bitmap(str(tmp_path / "fig.exr")))
    scene_dict = runpy.run_path(str(out))["scene"]
    np.testing.assert_array_equal(image, render(mi.load_dict(scene_dict)))


@pytest.mark.parametrize("args, words", [
    (["-o", "{tmp}/x.txt"], "unsupported export format '.txt'; use .xml"),
    (["-o", "{tmp}/x.xml", "--python"], "unsupported export format '.xml'; use .py"),
    (["-o", "{tmp}/no/x.xml"], "does not exist"),
    (["-o", "{tmp}"], "is a folder"),
    (["-o", "{tmp}/x.xml", "--spp", "3"], "perfect square"),
])
def test_usage_errors_are_one_line_and_exit_2(args, words, tmp_path):
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    result = mimarble_cli("export", ROOT / "scenes" / "fig11a.scene", *args)
    assert result.returncode == 2 and words in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert not (tmp_path / "x.xml").exists()


def test_an_unreadable_scene_is_one_line_and_exit_2(tmp_path):
    result = mimarble_cli("export", tmp_path / "missing.scene", "-o", tmp_path / "x.xml")
    assert result.returncode == 2 and "missing.scene" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_an_unwritable_output_is_one_line_and_exit_2(tmp_path):
    folder = tmp_path / "read-only"
    folder.mkdir()
    folder.chmod(0o500)
    if os.access(folder, os.W_OK):          # root writes there: /proc takes no new files
        folder = Path("/proc")
        if not folder.is_dir():
            pytest.skip("no folder here refuses this user a new file")
    try:
        result = mimarble_cli("export", "fig11a", "-o", folder / "x.xml")
    finally:
        (tmp_path / "read-only").chmod(0o700)
    assert result.returncode == 2 and "could not write it" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


# ---------------------------------------------------------------------------
# Issue 38: names Mitsuba reads as its own, and files that shadow what a script imports

NAMED = """
image { width 8 height 8 } camera { eye < 0 0 6 > } light { position < 4 4 4 > }
texture "NAME" { marble { period 1.3 distortion 2 octaves 4 } }
material "m" { diffuse { texture "NAME" } }
sphere { material "m" }
"""


@pytest.mark.parametrize("name", ["id", "type", "id!", " id ", "id_2"])
def test_a_texture_named_as_a_load_dict_key_renders_as_the_reference_and_exports(name, tmp_path):
    """``id`` and ``type`` are the keys ``mi.load_dict`` reads as a dict's own: a texture
    whose id would be one gets another, in the dict and in both files."""
    from mimarble import reference
    scene_file = tmp_path / "named.scene"
    scene_file.write_text(NAMED.replace("NAME", name), encoding="utf-8")
    scene = scene_language.load(scene_file)
    np.testing.assert_allclose(mimarble.render(scene), reference.render(scene), atol=1e-4)
    scene_dict = to_mitsuba(scene)
    assert not any(isinstance(scene_dict.get(k), dict) for k in ("id", "type"))
    assert_both_render_as_the_dict(scene_dict, tmp_path)


def test_a_plugin_under_a_key_load_dict_reads_as_its_own_is_refused_by_both_writers():
    for key in ("id", "type"):
        scene_dict = {"type": "scene", key: {"type": "marble"}} if key == "id" else \
            {key: {"type": "marble"}}
        for write in (export.to_xml, lambda d: export.to_python(d, mi.variant())):
            with pytest.raises((export.ExportError, TypeError), match="scene dict|its own"):
                write(scene_dict)


@pytest.mark.parametrize("stem", ["mimarble", "mitsuba", "drjit", "numpy"])
def test_export_refuses_a_python_file_that_would_shadow_what_it_imports(stem, tmp_path):
    result = mimarble_cli("export", "fig11a", "--python", "-o", f"{stem}.py", cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert f"imported in place of the {stem} module" in result.stderr
    with pytest.raises(export.ExportError, match="imported in place"):
        export.export(small(ROOT / "scenes" / "fig11a.scene", 4), tmp_path / f"{stem}.py",
                      python=True)
    assert os.listdir(tmp_path) == []


def test_an_xml_or_another_python_name_is_not_taken_for_a_shadowing_one(tmp_path):
    """Only a Python file named as a module the script imports shadows it."""
    scene = small(ROOT / "scenes" / "fig11a.scene", 4)
    for name, python in (("mimarble.xml", False), ("mimarble_scene.py", True),
                         ("Mitsuba.py", True)):
        export.export(scene, tmp_path / name, python=python)
    assert sorted(os.listdir(tmp_path)) == ["Mitsuba.py", "mimarble.xml", "mimarble_scene.py"]
