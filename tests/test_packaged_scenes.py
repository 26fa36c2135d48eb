"""The paper's scenes shipped with the package: found by name, listed, copied, the gallery's
default (mimarble/runtime/packaged_scenes.py; the built wheel itself: tests/test_packaging.py)."""

import os
from pathlib import Path

from commands import mimarble_cli  # noqa: E402

from mimarble.cli import main as cli
from mimarble.runtime import packaged_scenes

ROOT = Path(__file__).resolve().parent.parent
SMALL = """image { width 8 height 6 samples 1 }
camera { eye < 0 0 5 > lookat < 0 0 0 > up < 0 1 0 > fov 30 }
light { position < 5 5 5 > color < 1 1 1 > }
material "m" { diffuse { marble { octaves 3 } } }
sphere { center < 0 0 0 > radius 1 material "m" }
"""




def test_every_scene_of_the_checkout_is_packaged_under_a_unique_name():
    in_checkout = sorted(p.relative_to(ROOT / "scenes").as_posix()
                         for p in (ROOT / "scenes").rglob("*.scene"))
    packaged = packaged_scenes.paths()
    assert sorted(p.relative_to(packaged_scenes.FOLDER).as_posix() for p in packaged) == in_checkout
    assert len(packaged_scenes.names()) == len(packaged)          # stems unique
    assert [p.stem for p in packaged_scenes.figures()] == sorted(
        p.stem for p in (ROOT / "scenes").glob("*.scene"))


def test_a_bare_name_finds_the_packaged_scene_with_or_without_its_suffix(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    expected = str(packaged_scenes.FOLDER / "fig11a.scene")
    assert packaged_scenes.resolve("fig11a") == expected
    assert packaged_scenes.resolve("fig11a.scene") == expected
    assert packaged_scenes.resolve("veins-over-image") == str(
        packaged_scenes.FOLDER / "future-work" / "veins-over-image.scene")


def test_an_existing_file_always_wins_over_a_packaged_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ("fig11a", "fig11a.scene"):
        (tmp_path / name).write_text(SMALL)
        assert packaged_scenes.resolve(name) == name
    assert packaged_scenes.resolve("nowhere/fig11a") == "nowhere/fig11a"   # a folder part: a path


def test_render_by_name_uses_the_packaged_scene_from_any_folder(tmp_path):
    result = mimarble_cli("render", "fig11a", "--width", "16", "--height", "16",
                          "--spp", "1", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "fig11a.png").is_file()


def test_an_unknown_bare_name_is_one_sentence_naming_the_scenes_command(tmp_path):
    result = mimarble_cli("render", "fig99", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.strip() == (f"mimarble: fig99: no such file (looked for "
                                     f"{tmp_path / 'fig99'}), nor a packaged scene of that "
                                     f"name (`mimarble scenes` lists them)")


def test_scenes_lists_every_packaged_name(tmp_path):
    result = mimarble_cli("scenes", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    listed = [line.split()[0] for line in result.stdout.splitlines() if line.startswith("  ")]
    assert listed == list(packaged_scenes.names())


def test_scenes_copy_writes_the_scenes_with_their_image_maps(tmp_path):
    result = mimarble_cli("scenes", "--copy", "mine", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    copied = sorted(p.relative_to(tmp_path / "mine").as_posix()
                    for p in (tmp_path / "mine").rglob("*") if p.is_file())
    assert copied == sorted(p.relative_to(packaged_scenes.FOLDER).as_posix()
                            for p in packaged_scenes.files())
    assert "future-work/maps/flagstones.png" in copied
    assert result.stdout.strip().endswith(f"to mine{os.sep}")
    # a copied scene finds its image map beside it
    render = mimarble_cli("render", "mine/future-work/veins-over-image.scene",
                          "--width", "8", "--height", "8", "--spp", "1", "-o", "v.png", cwd=tmp_path)
    assert render.returncode == 0, render.stderr


def test_scenes_copy_never_overwrites_and_copies_nothing_then(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "fig11a.scene").write_text("mine")
    result = mimarble_cli("scenes", "--copy", "mine", cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "fig11a.scene: exists" in result.stderr
    assert [p.name for p in (tmp_path / "mine").iterdir()] == ["fig11a.scene"]
    assert (tmp_path / "mine" / "fig11a.scene").read_text() == "mine"


def test_scenes_copy_into_a_missing_parent_is_refused(tmp_path):
    result = mimarble_cli("scenes", "--copy", "no/such", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.strip() == "mimarble: no/such: folder no does not exist"


def test_default_scene_list_is_the_packaged_figures_where_there_is_no_scenes_folder(
        tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli.scene_list([]) == [str(p) for p in packaged_scenes.figures()]
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "mine.scene").write_text(SMALL)
    assert cli.scene_list([]) == [os.path.join("scenes", "mine.scene")]   # ./scenes first


def test_gallery_writes_into_gallery_where_you_stand(tmp_path):
    (tmp_path / "small.scene").write_text(SMALL)
    result = mimarble_cli("gallery", "small.scene", "--size", "8", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "gallery" / "small.png").is_file()
    assert result.stdout.splitlines()[-1] == f"wrote 1 image to gallery{os.sep}"


def test_gallery_into_a_missing_parent_is_refused_as_render_refuses_it(tmp_path):
    (tmp_path / "small.scene").write_text(SMALL)
    result = mimarble_cli("gallery", "small.scene", "-o", "no/such", cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.strip() == "mimarble: no/such: folder no does not exist"
    assert not (tmp_path / "no").exists()


def test_python_finds_a_packaged_scene_by_name_and_renders_it(llvm):
    import mimarble
    path = mimarble.runtime.packaged_scenes.find("fig11a")
    assert path == packaged_scenes.FOLDER / "fig11a.scene"
    assert mimarble.render(path, width=8, height=8, spp=1).shape == (8, 8, 3)
    assert mimarble.runtime.packaged_scenes.find("nowhere") is None


def test_python_renders_a_packaged_scene_by_name_from_any_folder(llvm, tmp_path, monkeypatch):
    import mimarble
    monkeypatch.chdir(tmp_path)                       # no fig11a.scene here
    by_name = mimarble.render("fig11a", width=8, height=8, spp=1)
    by_path = mimarble.render(packaged_scenes.find("fig11a"), width=8, height=8, spp=1)
    assert (by_name == by_path).all()


def test_a_copy_that_fails_part_way_leaves_nothing_behind(tmp_path, monkeypatch):
    import shutil
    copied = []
    real = shutil.copyfile

    def disk_full_on_the_third(source, target):
        if len(copied) == 2:
            raise OSError(28, "No space left on device")
        copied.append(source)
        return real(source, target)
    monkeypatch.setattr(shutil, "copyfile", disk_full_on_the_third)
    target = tmp_path / "mine"
    try:
        packaged_scenes.copy_to(target)
    except OSError as e:
        assert e.errno == 28
    else:
        raise AssertionError("the copy should have failed")
    assert len(copied) == 2 and not target.exists() and list(tmp_path.iterdir()) == []
