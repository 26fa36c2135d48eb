"""The marble library (issue 42, item 2): presets as data, checked by the parameter table,
resolved in the scene language and the ``marble`` plugin into plain parameters; every preset
renders and agrees with the reference tracer; ``mimarble presets``; the gallery page."""

import runpy
from pathlib import Path

import numpy as np
import pytest

import mimarble
from mimarble import presets
from mimarble.parameters import hex_colour
from mimarble.scene import SceneError, parse
from commands import mimarble_cli, one_sentence

ROOT = Path(__file__).resolve().parent.parent
GALLERY = runpy.run_path(str(ROOT / "scripts" / "preset_gallery.py"))

REAL_STONES = ("carrara", "calacatta", "nero_marquina", "verde", "onyx", "rosso_levanto",
               "travertine")
#: POV-Ray 3.7's distribution/include/textures.inc, copied by hand: each marble's
#: turbulence and color_map ([key rgb]) as the file declares them.
POVRAY = {
    "white_marble": ("White_Marble", 1.0, [(0.0, (0.9, 0.9, 0.9)), (0.8, (0.5, 0.5, 0.5)),
                                           (1.0, (0.2, 0.2, 0.2))]),
    "red_marble": ("Red_Marble", 1.0, [(0.0, (0.8, 0.8, 0.6)), (0.8, (0.8, 0.4, 0.4)),
                                       (1.0, (0.8, 0.2, 0.2))]),
    "blood_marble": ("Blood_Marble", 2.3, [(0.0, (0, 0, 0)), (0.8, (0.0, 0.6, 0.6)),
                                           (0.9, (0.6, 0.0, 0.0)), (1.0, (0, 0, 0))]),
    "jade": ("Jade", 1.8, [(0.0, (0.1, 0.6, 0.1)), (0.8, (0.0, 0.3, 0.0)),
                           (0.8, (0.1, 0.6, 0.1)), (1.0, (0.0, 0.2, 0.0))]),
}


def marble_of(text: str, name: str = "t.scene"):
    """The marble channel of a one-material scene whose diffuse channel is ``text``."""
    scene = parse(f'material "m" {{ diffuse {{ {text} }} }}\nsphere {{ material "m" }}\n', name)
    return scene.materials["m"].diffuse


# ---------------------------------------------------------------------------
# The library

def test_the_library_holds_the_real_stones_and_povrays_marbles():
    library = presets.presets()
    assert set(REAL_STONES) | set(POVRAY) <= set(library)
    for name, p in library.items():
        assert p.title and p.about and p.colours, name
        assert (p.povray is not None) == (name in POVRAY), name
        assert "ramp" in p.values, name


@pytest.mark.parametrize("name", sorted(POVRAY))
def test_povray_marbles_keep_textures_inc_maps_and_the_documented_translation(name):
    """Against POV-Ray's file (copied above, not read from the library): the colour map's
    keys and linear colours exactly; marble = triangle wave, distortion = turbulence / 2
    (docs/coming-from-povray.md), POV-Ray's default octaves 6, omega 0.5, lambda 2."""
    povray_name, turbulence, colour_map = POVRAY[name]
    p = presets.preset(name)
    assert p.povray == povray_name
    assert p.values["ramp_positions"] == tuple(k for k, _ in colour_map)
    assert p.values["ramp"] == tuple(tuple(float(c) for c in rgb) for _, rgb in colour_map)
    assert p.values["function"] == "triangle"
    assert p.values["distortion"] == pytest.approx(turbulence / 2, rel=1e-12)
    assert p.values["octaves"] == 6
    assert p.values.get("gain", 0.5) == 0.5 and p.values.get("lacunarity", 2.0) == 2.0


def test_real_stones_colours_are_the_hex_values_their_sources_line_names():
    """Each real stone's `colours` line quotes the hex colours its ramp holds (so the
    page says where each comes from): every ramp colour is one of them."""
    for name in REAL_STONES:
        p = presets.preset(name)
        written = [item.split()[-1] for item in p.written["ramp"].split(",")]
        for code in written:
            assert code.startswith("#"), (name, code)
        quoted = [code for code in written if code in p.colours]
        assert quoted, name
        assert p.values["ramp"] == tuple(hex_colour(c) for c in written), name


BROKEN = [
    ('[x]\ntitle = "X"\nabout = "a"\ncolours = "c"\nperiod = "wide"\n',
     "presets.toml: [x]: period must be a finite number, found 'wide'"),
    ('[x]\ntitle = "X"\nabout = "a"\ncolours = "c"\noctaves = 99\n',
     "presets.toml: [x]: octaves must be in 0..64"),
    ('[x]\ntitle = "X"\nabout = "a"\ncolours = "c"\nfilter = "bandlimit"\n',
     "presets.toml: [x]: 'filter' is a rendering choice"),
    ('[x]\ntitle = "X"\nabout = "a"\ncolours = "c"\nperiodd = 2\n',
     "presets.toml: [x]: 'periodd' is not a key of a preset"),
    ('[x]\ntitle = "X"\ncolours = "c"\n', "presets.toml: [x]: no 'about'"),
    ('[x]\ntitle = "X"\nabout = "a"\ncolours = "c"\nramp = "0 #ffffff, 0.5 #zzzzzz"\n',
     "presets.toml: [x]: "),
    ('[x]\ntitle = "X"\nabout = "a"\ncolours = "c"\nramp = "0.5 1 1 1, 0.2 0 0 0"\n',
     "presets.toml: [x]: "),
    ('[Bad-Name]\ntitle = "X"\nabout = "a"\ncolours = "c"\n', "presets.toml: [Bad-Name]: "),
    ('[x\n', "presets.toml: not valid TOML"),
]


@pytest.mark.parametrize("text, start", BROKEN)
def test_a_broken_entry_is_one_sentence_naming_it(text, start):
    with pytest.raises(presets.PresetError) as e:
        presets.read_presets(text)
    assert str(e.value).startswith(start), str(e.value)
    assert "\n" not in str(e.value)


def test_an_unknown_preset_names_the_closest():
    assert presets.unknown_preset_sentence("carara") == \
        "no preset 'carara'; did you mean 'carrara'? (`mimarble presets` lists them)"
    assert "did you mean 'white_marble'?" in presets.unknown_preset_sentence("White_Marble")
    far = presets.unknown_preset_sentence("qqqq")
    assert "did you mean" not in far and "carrara" in far and "jade" in far


# ---------------------------------------------------------------------------
# The scene language

def test_a_preset_then_overrides_in_the_language():
    base = marble_of('marble { preset "carrara" }')
    p = presets.preset("carrara").values
    assert (base.scale, base.period, base.distortion, base.octaves) == \
        (p["scale"], p["period"], p["distortion"], p["octaves"])
    assert base.ramp == p["ramp"] and base.ramp_positions == p["ramp_positions"]
    assert base.function == "abs_sine" and base.filter == "none"      # rows it leaves out
    over = marble_of('marble { preset "carrara" period 1.5 turbulence true }')
    assert over.period == 1.5 and over.turbulence is True and over.scale == p["scale"]


def test_a_ramp_given_replaces_the_presets_ramp_with_its_positions():
    m = marble_of('marble { preset "jade" ramp { < 1 1 1 > < 0 0 0 > } }')
    assert m.ramp == ((1.0, 1.0, 1.0), (0.0, 0.0, 0.0)) and m.ramp_positions is None
    m = marble_of('marble { preset "jade" ramp { 0 < 1 1 1 > 0.3 < 0 0 0 > } }')
    assert m.ramp_positions == (0.0, 0.3) and m.function == "triangle"


@pytest.mark.parametrize("name", sorted(presets.presets()))
def test_each_presets_written_values_are_the_preset(name):
    """`mimarble presets NAME` and the page print the values as a marble block: that
    block, parsed, is the preset (the name and the values are one marble)."""
    written = marble_of(f"marble {{ {presets.block_text(presets.preset(name))} }}")
    assert written == marble_of(f'marble {{ preset "{name}" }}')


@pytest.mark.parametrize("text, col, start", [
    ('marble { period 2 preset "carrara" }', 44, "'preset' comes first in a marble block"),
    ('marble { preset "carara" }', 42, "no preset 'carara'; did you mean 'carrara'?"),
    ('marble { preset "" }', 42, "no preset ''"),
    ('marble { preset "jade" preset "onyx" }', 49, "duplicate 'preset'"),
    ('marble { preset "jade" octaves 99 }', 57, "octaves must be in 0..64"),
    ('marble { preset carrara }', 42, "expected a quoted preset name like \"carrara\" after "
                                      "'preset', found"),
])
def test_preset_mistakes_are_positioned(text, col, start):
    with pytest.raises(SceneError) as e:
        marble_of(text)
    first = str(e.value).splitlines()[0]
    assert first.startswith(f"t.scene:1:{col}: {start}"), first


# ---------------------------------------------------------------------------
# The plugin

def test_the_plugins_preset_equals_its_values_and_takes_overrides():
    mi = mimarble.mi
    from mimarble.parameters import BY_NAME
    values = presets.preset("calacatta").values
    plain = {"type": "marble", **{k: BY_NAME[k].property_value(v) for k, v in values.items()}}
    a = mi.traverse(mi.load_dict({"type": "marble", "preset": "calacatta"}))
    b = mi.traverse(mi.load_dict(plain))
    assert set(a.keys()) == set(b.keys())
    for key in a.keys():
        assert np.array_equal(np.asarray(a[key]), np.asarray(b[key])), key
    c = mi.traverse(mi.load_dict({"type": "marble", "preset": "calacatta", "period": 2.5,
                                  "ramp": "#ffffff, #000000"}))
    assert np.asarray(c["period"]).item() == 2.5
    assert "ramp_positions" not in c.keys()          # the preset's positions went with its ramp
    assert np.asarray(c["scale"]).item() == pytest.approx(values["scale"])


def test_the_plugins_unknown_preset_names_the_closest():
    mi = mimarble.mi
    with pytest.raises(Exception, match=r"marble: no preset 'carara'; did you mean 'carrara'\?"):
        mi.load_dict({"type": "marble", "preset": "carara"})


# ---------------------------------------------------------------------------
# Rendering: every preset, and the reference tracer's agreement

@pytest.mark.parametrize("name", sorted(presets.presets()))
def test_every_preset_renders_and_agrees_with_the_reference(name):
    """Each preset on the gallery's sphere (24², 1 sample a pixel) in whitted mode against
    the float64 reference tracer: PSNR ≥ 100 dB (issue 42's target), and the sphere is
    not one flat colour (the marble is there)."""
    from mimarble.tools.compare import compare_with_reference
    scene = parse(GALLERY["scene_text"](name, "sphere", size=24, samples=1), f"{name}.scene")
    metrics, ours, _ = compare_with_reference(scene, spp=1)
    assert metrics["psnr"] >= 100, (name, metrics["psnr"])
    assert np.isfinite(ours).all()
    sphere = ours[np.abs(ours - ours[0, 0]).sum(axis=2) > 1e-6]    # not the background
    assert len(sphere) > 100 and np.ptp(sphere, axis=0).max() > 0.02, name


# ---------------------------------------------------------------------------
# The command and the page

def test_mimarble_presets_lists_them_without_loading_drjit():
    from tests.test_startup import heavy, imported_by
    result, names = imported_by("presets")
    assert result.returncode == 0, result.stderr
    for name in presets.presets():
        assert f"  {name} " in result.stdout
    assert heavy(names) == []
    one = mimarble_cli("presets", "jade")
    assert one.returncode == 0 and "Jade_Map" in one.stdout and "function triangle" in one.stdout


def test_mimarble_presets_refuses_an_unknown_name_in_one_sentence():
    line = one_sentence(mimarble_cli("presets", "carara"))
    assert line == "mimarble: no preset 'carara'; did you mean 'carrara'? " \
                   "(`mimarble presets` lists them)"


def test_the_gallery_page_is_current_and_has_every_image():
    assert GALLERY["main"](["preset_gallery.py", "--check"]) == 0, \
        "docs/presets.md is stale: ./go python scripts/preset_gallery.py --page"
    for name in presets.presets():
        assert (ROOT / "docs" / "presets" / f"{name}.png").is_file(), name
