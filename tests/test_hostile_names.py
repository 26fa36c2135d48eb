"""Names under hostile and careless input (issue 38): a user's string echoed in a message
is shown, never sent to the terminal; an output name is written under, or refused in one
sentence by, every writer alike; ``scenes --copy`` never follows a link inside its folder."""

import os
import unicodedata

import pytest
from commands import mimarble_cli, one_sentence  # noqa: E402

from mimarble.runtime import packaged_scenes
from mimarble.runtime.files import output_name_problem
from mimarble.scene import SceneError
from mimarble.scene.errors import printable

SCENE = ('image { width 8 height 8 } camera { eye < 0 0 6 > } light { position < 4 4 4 > } '
         'material "m" { diffuse { color < 1 0 0 > } } sphere { material "m" }\n')
#: A name whose bytes are not UTF-8 (b"o\xff.png"), as Python holds it (PEP 383).
NOT_UTF8 = os.fsdecode(b"o\xff.png")




def acting(text: str) -> list:
    """The characters of ``text`` a terminal acts on rather than shows (controls, bidi
    overrides, lone surrogates), by Unicode's categories (but the newlines of a message)."""
    return [c for c in text if c != "\n" and (unicodedata.category(c) in ("Cc", "Cs", "Zl", "Zp")
                                               or c in "\u202e\u2066")]


# ---------------------------------------------------------------------------
# Every user string printed in a message is made printable

@pytest.mark.parametrize("raw, shown", [
    ("\x1b]0;title\x07", "\\x1b]0;title\\x07"),             # OSC: sets the window's title
    ("\x1b[31mred\x1b[0m", "\\x1b[31mred\\x1b[0m"),          # CSI: colours
    ("\x9b31m\x9d0;t\x9c", "\\x9b31m\\x9d0;t\\x9c"),         # the C1 forms of CSI, OSC, ST
    ("a\x85b\x7fc", "a\\x85b\\x7fc"),                       # NEL, DEL
    ("line\nbreak\ttab\rcr", "line\\nbreak\\ttab\\rcr"),
    ("abc\u202edcba", "abc\\u202edcba"),                    # right-to-left override
    ("x\u2028y", "x\\u2028y"),                              # line separator
    (NOT_UTF8, "o\\xff.png"),                               # a byte that is not UTF-8
])
def test_escape_codes_and_controls_are_shown_escaped(raw, shown):
    assert printable(raw) == shown
    assert not acting(printable(raw))


@pytest.mark.parametrize("name", ["marbre-été.scene", "大理石.png", "мрамор", "ζ-α β",
                                  "👩\u200d🔬 lab", "नमस्ते", "\u0645\u0631\u0645\u0631"])
def test_a_unicode_name_prints_as_it_is(name):
    assert printable(name) == name


def test_a_scene_error_shows_its_file_string_escaped_with_the_caret_in_place(tmp_path):
    path = tmp_path / "esc.scene"
    path.write_text('material "m" {\n\tdiffuse { image { file "\x1b]0;x\x07\x1b[31m.png" } }\n}\n'
                    'sphere { material "m" }\n')
    with pytest.raises(SceneError) as caught:
        from mimarble import scene
        scene.load(path)
    text = str(caught.value)
    assert not acting(text)
    head, line, caret = text.splitlines()[:3]
    assert "\\x1b]0;x\\x07\\x1b[31m.png" in head
    assert line[len(caret) - 1] == '"' and caret.strip() == "^"   # under the opening quote


def test_the_caret_stays_under_its_column_after_escaped_characters(tmp_path):
    path = tmp_path / "c.scene"
    path.write_text('material "m\x1b[1m\x9b" { diffuse { color < 1 0 0 > } }\tsphere { '
                    'material "zz" }\n')
    with pytest.raises(SceneError) as caught:
        from mimarble import scene
        scene.load(path)
    head, line, caret = str(caught.value).splitlines()[:3]
    assert 'unknown material "zz"' in head and '"m\\x1b[1m\\x9b"' in head
    assert line[len(caret) - 1:].startswith('"zz"')


def test_the_command_line_shows_a_scene_s_escape_codes_escaped(tmp_path):
    scene = tmp_path / "esc.scene"
    scene.write_text(SCENE.replace('diffuse { color < 1 0 0 > }',
                                   'diffuse { image { file "\x1b]0;PWNED\x07\x9b31m.png" } }'))
    result = mimarble_cli("render", scene, "-o", tmp_path / "out.png", cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert not acting(result.stderr) and "\\x1b]0;PWNED\\x07\\x9b31m.png" in result.stderr
    assert not (tmp_path / "out.png").exists()


@pytest.mark.parametrize("command", [
    ["render", "SCENE", "-o", "OUT"], ["export", "SCENE", "-o", "OUT"],
    ["sweep", "SCENE", "--set", "marble.period=1", "-o", "OUT"],
])
def test_an_output_name_s_escape_codes_are_shown_escaped(tmp_path, command):
    (tmp_path / "s.scene").write_text(SCENE)
    out = tmp_path / "no such\x1b[2J" / "\x1b]0;t\x07.png"
    args = [str(tmp_path / "s.scene") if a == "SCENE" else str(out) if a == "OUT" else a
            for a in command]
    sentence = one_sentence(mimarble_cli(*args, cwd=tmp_path))
    assert not acting(sentence) and "\\x1b[2J" in sentence


def test_a_warning_shows_the_scene_s_name_escaped(tmp_path):
    scene = tmp_path / "\x1b[31mempty.scene"
    scene.write_text("image { width 4 height 4 }\n")
    result = mimarble_cli("render", scene, "-o", "out.png", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "no shapes" in result.stderr and "\\x1b[31mempty.scene" in result.stderr
    assert not acting(result.stderr + result.stdout)


# ---------------------------------------------------------------------------
# Output names: empty and non-UTF-8 names refused by every writer alike

#: Every writer of the command line, with {out} where its output name goes.
WRITERS = {
    "render": ["render", "s.scene", "-o", "{out}"],
    "reference": ["reference", "s.scene", "-o", "{out}"],
    "export": ["export", "s.scene", "-o", "{out}"],
    "export --python": ["export", "s.scene", "--python", "-o", "{out}"],
    "bake": ["bake", "s.scene", "--shape", "sphere_0", "-o", "{out}"],
    "sweep": ["sweep", "s.scene", "--set", "marble.period=1", "-o", "{out}"],
    "gallery": ["gallery", "s.scene", "-o", "{out}"],
    "scenes --copy": ["scenes", "--copy", "{out}"],
    "compare --diff": ["compare", "s.scene", "--diff", "{out}"],
    "bench --json": ["bench", "s.scene", "--json", "{out}"],
    "stress --json": ["stress", "--json", "{out}"],
}


def run_writer(tmp_path, writer, out):
    (tmp_path / "s.scene").write_text(SCENE.replace('diffuse { color < 1 0 0 > }',
                                                    'diffuse { marble { octaves 2 } }'))
    before = sorted(os.listdir(tmp_path))
    result = mimarble_cli(*[a.replace("{out}", out) for a in WRITERS[writer]], cwd=tmp_path)
    assert sorted(os.listdir(tmp_path)) == before          # nothing written, here or there
    return result


@pytest.mark.parametrize("writer", WRITERS)
def test_an_empty_output_name_is_refused_by_every_writer(tmp_path, writer):
    sentence = one_sentence(run_writer(tmp_path, writer, ""))
    assert "'': an empty name" in sentence


@pytest.mark.parametrize("writer", WRITERS)
def test_an_output_name_that_is_not_utf8_is_refused_by_every_writer(tmp_path, writer):
    name = NOT_UTF8 if writer != "export" else os.fsdecode(b"o\xff.xml")
    sentence = one_sentence(run_writer(tmp_path, writer, name))
    assert "not UTF-8 (the byte \\xff at character 2)" in sentence


@pytest.mark.parametrize("name", [os.fsdecode(b"s\xe9.scene"), os.fsdecode(b"\xc3(.scene")])
def test_a_default_output_name_made_from_a_non_utf8_scene_name_is_refused(tmp_path, name):
    (tmp_path / name).write_text(SCENE)
    for command in ("render", "export"):
        sentence = one_sentence(mimarble_cli(command, name, cwd=tmp_path))
        assert "not UTF-8" in sentence and "give -o NAME" in sentence
    assert os.listdir(tmp_path) == [name]


@pytest.mark.parametrize("name, words", [
    ("", "an empty name"), ("a\0b.png", "NUL"), (NOT_UTF8, "not UTF-8"),
    (os.fsdecode(b"dir\x80/x.png"), "the byte \\x80 at character 4"),
    ("été.png", None), ("a b.png", None), (b"bytes.png", None), (b"o\xfe.png", "\\xfe"),
])
def test_the_output_name_rule(name, words):
    problem = output_name_problem(name)
    assert (problem is None) if words is None else (words in problem)


def test_the_image_writer_refuses_a_name_that_is_not_utf8_in_one_sentence(llvm, tmp_path):
    import numpy as np

    import mimarble
    for suffix in (".png", ".exr", ".jpg"):
        name = tmp_path / os.fsdecode(b"o\xff" + suffix.encode())
        with pytest.raises(ValueError, match="not UTF-8"):
            mimarble.write_image(name, np.zeros((2, 2, 3), np.float32))
    assert os.listdir(tmp_path) == []


# ---------------------------------------------------------------------------
# scenes --copy: never through a link inside the folder

def first_subfolder() -> str:
    """A subfolder the packaged copy writes into (future-work, …)."""
    return next(p.relative_to(packaged_scenes.FOLDER).parts[0] for p in packaged_scenes.files()
                if len(p.relative_to(packaged_scenes.FOLDER).parts) > 1)


@pytest.mark.parametrize("target", ["a folder outside", "nothing"])
def test_scenes_copy_never_follows_a_link_planted_inside_the_folder(tmp_path, target):
    outside = tmp_path / "outside"
    outside.mkdir()
    mine = tmp_path / "mine"
    mine.mkdir()
    link = mine / first_subfolder()
    link.symlink_to(outside if target == "a folder outside" else tmp_path / "missing")
    sentence = one_sentence(mimarble_cli("scenes", "--copy", "mine", cwd=tmp_path))
    assert "is a symbolic link" in sentence and "never follows a link" in sentence
    assert os.listdir(outside) == [] and os.listdir(mine) == [link.name]
    assert not (tmp_path / "missing").exists()


def test_scenes_copy_into_a_dangling_link_is_one_sentence(tmp_path):
    (tmp_path / "mine").symlink_to(tmp_path / "gone")
    sentence = one_sentence(mimarble_cli("scenes", "--copy", "mine", cwd=tmp_path))
    assert "symbolic link" in sentence and "does not exist" in sentence
    assert sorted(os.listdir(tmp_path)) == ["mine"]


def test_copy_to_refuses_a_link_planted_while_it_copies(tmp_path, monkeypatch):
    """A subfolder replaced by a link after the first check is seen before a file is
    written into it, and the copy is undone."""
    outside = tmp_path / "outside"
    outside.mkdir()
    mine = tmp_path / "mine"
    sub = first_subfolder()
    real_write = packaged_scenes.write_atomically
    planted = []

    def write_then_plant(path, write):
        real_write(path, write)
        if not planted and not (mine / sub).exists():
            (mine / sub).symlink_to(outside)
            planted.append(True)
    monkeypatch.setattr(packaged_scenes, "write_atomically", write_then_plant)
    with pytest.raises(packaged_scenes.CopyRefused, match="symbolic link"):
        packaged_scenes.copy_to(mine)
    assert os.listdir(outside) == []
    assert not mine.exists() or os.listdir(mine) == [sub]


def test_the_gallery_refuses_a_scene_whose_name_makes_no_image_name_before_any_image(tmp_path):
    (tmp_path / "a.scene").write_text(SCENE)
    name = os.fsdecode(b"g\xff.scene")
    (tmp_path / name).write_text(SCENE)
    sentence = one_sentence(mimarble_cli("gallery", "a.scene", name, "-o", "out", cwd=tmp_path))
    assert "g\\xff.scene: the gallery names each image after its scene file" in sentence
    assert sorted(os.listdir(tmp_path)) == sorted(["a.scene", name])


def test_an_unrecognised_argument_is_echoed_escaped(tmp_path):
    result = mimarble_cli("render", "fig11a", "\x1b]0;t\x07extra", cwd=tmp_path)
    assert result.returncode == 2 and "unrecognized arguments: \\x1b]0;t\\x07extra" in result.stderr
    assert not acting(result.stderr)


@pytest.mark.parametrize("name", ["", "a\0b.png"])
def test_the_image_writer_refuses_an_empty_or_nul_name(llvm, tmp_path, monkeypatch, name):
    import numpy as np

    import mimarble
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match="empty name|NUL"):
        mimarble.write_image(name, np.zeros((2, 2, 3), np.float32))
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("name", ["", os.fsdecode(b"d\xff")])
def test_the_python_writers_refuse_the_names_the_command_line_refuses(llvm, tmp_path,
                                                                      monkeypatch, name):
    from mimarble.tools import export
    from mimarble import scene as S
    monkeypatch.chdir(tmp_path)
    with pytest.raises(packaged_scenes.CopyRefused, match="empty name|not UTF-8"):
        packaged_scenes.copy_to(name)
    scene = S.Scene(image=S.Image(4, 4), spheres=(S.Sphere("m"),),
                    materials={"m": S.Material("m", diffuse=S.ColorChannel((1, 0, 0)))})
    for python in (False, True):
        with pytest.raises(export.ExportError, match="empty name|not UTF-8"):
            export.export(scene, name + (".py" if python and name else ""), python=python)
    assert os.listdir(tmp_path) == []
