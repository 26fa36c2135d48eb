"""Saving edits into a scene's text (mimarble/scene/rewrite.py): only the edited values'
text changes, the result parses to the scene ``with_value`` makes, and a file is saved
whole or not at all, never over a file changed on disk."""

import difflib
import os
import stat
from pathlib import Path

import pytest

from mimarble.scene import parse
from mimarble.scene.keys import KeyPathError, scene_keys, with_value
from mimarble.scene.rewrite import SaveRefused, read_scene_text, rewrite, save_atomic

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = sorted(ROOT.glob("scenes/**/*.scene")) + sorted(ROOT.glob("mimarble/scenes/**/*.scene"))


def words(text: str) -> list[str]:
    """The text's words: split at white space, '<' and '>' standing alone."""
    return text.replace("<", " < ").replace(">", " > ").split()


def word_changes(old: str, new: str) -> list[tuple[list, list]]:
    """What changed: (old words, new words) of each line changed (the change widened to
    whole words) or inserted."""
    a, b = old.splitlines(), new.splitlines()
    out = []
    for op, i1, i2, j1, j2 in difflib.SequenceMatcher(None, a, b, autojunk=False).get_opcodes():
        if op == "insert":
            out.append(([], words("\n".join(b[j1:j2]))))
        elif op != "equal":
            assert op == "replace" and i2 - i1 == j2 - j1, (op, a[i1:i2], b[j1:j2])
            for x, y in zip(a[i1:i2], b[j1:j2]):
                start = len(os.path.commonprefix([x, y]))
                end = len(os.path.commonprefix([x[start:][::-1], y[start:][::-1]]))
                while start and not x[start - 1].isspace() and x[start - 1] not in "<>":
                    start -= 1
                while end and not x[len(x) - end].isspace() and x[len(x) - end] not in "<>":
                    end -= 1
                out.append((words(x[start:len(x) - end]), words(y[start:len(y) - end])))
    return out


def edits_of(scene) -> list[tuple[str, object, list]]:
    """One edit per key family the scene has — (key, new value, the new words expected):
    a number of the first marble group and of the first texture, ramp stop 0, the camera's
    fov and eye, light 0's intensity and position, the image's samples."""
    keys = scene_keys(scene)
    out = []
    for key in keys.values():
        if key.parameter.name == "period" and (not out or key.group.startswith("texture")):
            if key.group.startswith("material"):
                continue
            out.append((key.path, key.value + 0.25, [repr(key.value + 0.25)]))
        if len([o for o in out if o[0].endswith("period")]) == 2:
            break
    stop = next((k for k in keys.values() if k.stop == 0), None)
    if stop is not None:
        out.append((stop.path, "0.25 0.5 0.75", ["0.25", "0.5", "0.75"]))
    out += [("camera.fov", 17.5, ["17.5"]), ("camera.eye", "0.5 1.5 20", ["0.5", "1.5", "20"])]
    if scene.lights:
        out += [("light.0.intensity", 0.75, ["0.75"] * 3),
                ("light.0.position", (3, 4.5, 5), ["3", "4.5", "5"])]
    out.append(("image.samples", 9, ["9"]))
    return out


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_shipped_scene_saves_one_value_per_key_family_and_nothing_else(path):
    text = read_scene_text(path)
    scene = parse(text, str(path))
    assert rewrite(text, {}, source=str(path)) == text
    assert "\r\n" not in text or rewrite(text, {"camera.fov": 20}).count("\r\n") == \
        text.count("\r\n")
    for key, value, new_words in edits_of(scene):
        new = rewrite(text, {key: value}, str(path), source=str(path))
        assert parse(new, str(path)) == with_value(scene, key, value), key
        old_value, count = scene_keys(scene)[key].value, scene_keys(scene)[key].count
        changes = word_changes(text, new)
        assert changes, key
        name = key.split(".")[-1] if key.split(".")[-2] != "ramp" else "ramp"
        for was, now in changes:
            if not was:                  # a default, written into its block with its name
                assert name in now and set(new_words) <= set(now), (key, now)
                continue
            assert set(now) <= set(new_words) | {"<", ">"}, (key, was, now)
            assert all(w in "<>" or w.startswith("#") or float(w) == float(w) for w in was)
            if isinstance(old_value, float) and count == 1 and key != "light.0.intensity":
                assert all(float(w) == old_value for w in was), (key, was)


def test_a_value_the_file_does_not_state_is_written_into_its_block():
    text = ('material "m" {\r\n\tdiffuse {\r\n\t\tmarble {\r\n\t\t\tperiod 2 // stripes\r\n'
            '\t\t}\r\n\t}\r\n}\r\nlight { position < 1 2 3 > }\r\nsphere { material "m" }')
    new = rewrite(text, {"m.scale": 3, "light.0.intensity": 2, "camera.fov": 40,
                         "m.ramp.1": "#ffffff"})
    assert new == ('material "m" {\r\n\tdiffuse {\r\n\t\tmarble {\r\n\t\t\tperiod 2 // stripes'
                   '\r\n\t\t\tscale 3\r\n\t\t\tramp { < 1 0 0 > #ffffff < 1 0.25 0 > '
                   '< 1 0.375 0 > < 1 0.5 0 > < 1 0.625 0 > < 1 0.75 0 > < 1 0.875 0 > }\r\n'
                   '\t\t}\r\n\t}\r\n}\r\nlight { position < 1 2 3 > color < 2 2 2 > }\r\n'
                   'sphere { material "m" }\r\ncamera { fov 40 }\r\n')
    scene = parse(text)
    for key, value in (("m.scale", 3), ("light.0.intensity", 2), ("camera.fov", 40),
                       ("m.ramp.1", "#ffffff")):
        scene = with_value(scene, key, value)
    assert parse(new) == scene


def test_hostile_text_is_kept_byte_for_byte():
    text = ("\ufeff// ünïcødé ✓ comment\n"
            'material "石" { diffuse { marble { /* a { brace } in a comment */ period\t1.5\n'
            "   /* nested /* comment */ */ distortion 2 ramp {\n"
            "      < 1 1 1 >   // white\n"
            "      0.5 0.5 0.5\n".replace("0.5 0.5 0.5", "< 0.5 0.5 0.5 >") +
            "   } } } }\r\n"
            'sphere { material "石" }   \t\n')
    new = rewrite(text, {"石.period": 2, "石.ramp.1": "0.25 0.25 0.25"})
    assert new == text.replace("period\t1.5", "period\t2").replace(
        "< 0.5 0.5 0.5 >", "< 0.25 0.25 0.25 >")
    assert new.startswith("\ufeff")


def test_ramps_keep_their_layout():
    text = ('material "m" { diffuse { marble { ramp {\n'
            '        0   < 1 1 1 >\n'
            '        0.5 #808080\n'
            '        1   < 0 0 0 >\n'
            '    } } } }\nsphere { material "m" }\n')
    assert rewrite(text, {"m.ramp.1": "0.6 #909090"}) == \
        text.replace("0.5 #808080", "0.6 #909090")
    # a stop whose value is as it was keeps its text (< 0 0 0 > is 0 0 0)
    assert rewrite(text, {"m.ramp": "0 #fefefe, 0.5 #808080, 1 0 0 0"}) == \
        text.replace("< 1 1 1 >", "#fefefe")
    unplaced = rewrite(text, {"m.ramp": "#ffffff, #808080, 0 0 0"})       # positions gone
    assert unplaced == text.replace("0   < 1 1 1 >", "< 1 1 1 >").replace(
        "0.5 #808080", "#808080").replace("1   < 0 0 0 >", "< 0 0 0 >")
    assert parse(unplaced) == with_value(parse(text), "m.ramp", "#ffffff, #808080, 0 0 0")
    three_to_two = rewrite(text, {"m.ramp": "#ffffff, #000000"})
    assert three_to_two == text.replace(
        "0   < 1 1 1 >\n        0.5 #808080\n        1   < 0 0 0 >",
        "#ffffff\n        #000000")
    assert parse(three_to_two) == with_value(parse(text), "m.ramp", "#ffffff, #000000")


def test_a_key_over_several_marbles_rewrites_each_and_a_shared_texture_once():
    text = ('texture "t" { marble { period 1 } }\n'
            'material "a" { diffuse { texture "t" } ambient { marble { period 1 } } }\n'
            'material "b" { diffuse { texture "t" } }\n'
            'sphere { material "a" } sphere { material "b" }\n')
    assert rewrite(text, {"marble.period": 3}) == text.replace("period 1", "period 3")
    assert rewrite(text, {"t.period": 3}) == text.replace("marble { period 1 } }\nmaterial",
                                                          "marble { period 3 } }\nmaterial")
    assert rewrite(text, {"a.ambient.period": 3}).count("period 3") == 1
    with pytest.raises(KeyPathError, match='^a.diffuse.period: .*texture "t".* edit t.period'):
        rewrite(text, {"a.diffuse.period": 3})


def test_bad_edits_are_refused_in_one_sentence():
    text = 'material "m" { diffuse { marble { } } } sphere { material "m" }'
    for key, value, words in (("m.scale", 0, "scale must be > 0"), ("m.perid", 1, "unknown key"),
                              ("camera.fov", "wide", "is not a number")):
        with pytest.raises(KeyPathError, match=f"^{key}: .*{words}"):
            rewrite(text, {key: value})
    with pytest.raises(KeyPathError, match="^m.ramp: a value of 80000 characters; a value is at "
                                           "most 65536$"):
        rewrite(text, {"m.ramp": "#ffffff," * 10000})
    with pytest.raises(KeyPathError, match="^1025 edits at once; a save writes at most 1024$"):
        rewrite(text, {f"m.k{n}": 1 for n in range(1025)})


def test_save_is_atomic_and_refuses_a_file_changed_on_disk(tmp_path):
    path = tmp_path / "s.scene"
    path.write_bytes(b"camera { fov 30 }\r\n")
    os.chmod(path, 0o640)
    loaded = read_scene_text(path)
    assert loaded == "camera { fov 30 }\r\n"
    save_atomic(path, rewrite(loaded, {"camera.fov": 45}), loaded)
    assert path.read_bytes() == b"camera { fov 45 }\r\n"
    assert stat.S_IMODE(path.stat().st_mode) == 0o640
    with pytest.raises(SaveRefused, match="changed on disk since it was loaded; reload it"):
        save_atomic(path, "camera { fov 50 }\n", loaded)          # loaded before the save
    assert path.read_bytes() == b"camera { fov 45 }\r\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.scene"]   # no temporary left
    save_atomic(tmp_path / "new.scene", "camera { fov 50 }\n", None)   # "Save as"
    assert (tmp_path / "new.scene").read_text() == "camera { fov 50 }\n"


def test_a_preset_marble_gets_the_preset_values_it_did_not_write():
    """A value a preset gives is not in the block: an edit writes it after the preset (which
    comes first); a stop of the preset's ramp writes the preset's ramp with that stop."""
    text = 'material "m" { diffuse { marble { preset "carrara" period 1.5 } } }\n' \
           'sphere { material "m" }\n'
    scene = parse(text)
    for key, value in (("m.scale", 3), ("m.ramp.1", "#ffffff"), ("m.ramp", "#ffffff, #000000")):
        new = rewrite(text, {key: value})
        assert new.startswith('material "m" { diffuse { marble { preset "carrara" period 1.5 ')
        assert parse(new) == with_value(scene, key, value), key
