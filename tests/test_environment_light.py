"""The scene's ``environment`` (issue 42, item 3): the language, its file checks, path mode
against Mitsuba's own ``envmap`` scene written by hand (bit for bit), whitted mode against
the reference tracer's own loader and lookup, translucent spheres lit by it, export.

The environment images are written here from the formats' specifications
(tests/environment_files.py), read back by Mitsuba's own ``Bitmap`` as a check of the
writer, and then decoded by the reference on its own.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import mimarble
import mimarble.reference
from mimarble.cli.main import main
from mimarble.reference import environment as reference_environment
from mimarble.reference import volume
from mimarble.scene import SceneError, model, parse
from mimarble.mitsuba.translate.scene_dict import to_mitsuba

from environment_files import write_exr, write_hdr

dr, mi = mimarble.dr, mimarble.mi
T = mi.ScalarTransform4f


def sky(height=16, width=32) -> np.ndarray:
    """A sky that differs in every direction: a warm band, a blue top, stripes in u."""
    v = (np.arange(height) + 0.5)[:, None] / height
    u = (np.arange(width) + 0.5)[None, :] / width
    return np.stack([1.0 + np.sin(2 * np.pi * u) + 0 * v,
                     0.2 + 1.5 * v + 0 * u,
                     0.5 + 0.5 * np.cos(6 * np.pi * u) * (1 - v)], axis=-1).astype(np.float32)


SCENE = """
image {{ width 40 height 30 samples {samples} }}
camera {{ eye < 0 0 6 > lookat < 0 0 0 > fov 40 }}
{extra}
material "m" {{ diffuse {{ marble {{ period 1.3 tolerance 0 }} }} }}
sphere {{ radius 1.2 material "m" }}
"""


def scene_text(environment: str, samples: int = 1, extra: str = "") -> str:
    return SCENE.format(samples=samples, extra=environment + "\n" + extra)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """sky.exr (FLOAT, ZIP), half.exr (HALF, uncompressed), sky.hdr (run-length encoded),
    flat.hdr, sky.png; and the floats each holds."""
    folder = tmp_path_factory.mktemp("skies")
    image = sky()
    write_exr(folder / "sky.exr", image, zip_compression=True)
    write_exr(folder / "half.exr", image, half=True, extra_channels=("A",))
    held = {"sky.exr": image.astype(np.float64),
            "half.exr": image.astype(np.float16).astype(np.float64),
            "sky.hdr": write_hdr(folder / "sky.hdr", image),
            "flat.hdr": write_hdr(folder / "flat.hdr", image, encoded=False)}
    from PIL import Image
    png = (np.clip(image / 2.5, 0, 1) * 255).round().astype(np.uint8)
    Image.fromarray(png).save(folder / "sky.png")
    return folder, held


def load(folder, text):
    path = folder / "scene.scene"
    path.write_text(text)
    return mimarble.scene.load(str(path))


# ---------------------------------------------------------------------------
# The language

def test_file_and_colour_environments_parse(files):
    folder, _ = files
    scene = load(folder, scene_text('environment { file "sky.exr" intensity 1.5 rotate < 0 30 0 > }'))
    env = scene.environment
    assert (env.file, env.intensity, env.rotate, env.color) == ("sky.exr", 1.5, (0, 30, 0), None)
    assert env.location == str(folder / "sky.exr")
    scene = parse(scene_text("environment { color #ffffff intensity 2 }"))
    assert scene.environment.color == (1.0, 1.0, 1.0) and scene.environment.intensity == 2.0
    assert parse(scene_text("")).environment is None


@pytest.mark.parametrize("block, column, words", [
    ("environment { }", 1, "give exactly one of file and color"),
    ('environment { file "sky.exr" color < 1 1 1 > }', 30, "found both"),
    ("environment { color < 1 1 1 > rotate < 0 1 0 > }", 31, "rotate turns an environment image"),
    ("environment { color < 1 1 1 > intensity -1 }", 41, "intensity must be >= 0"),
    ('environment { file "none.exr" }', 20, "environment file 'none.exr': no such file"),
    ('environment { file "" }', 20, "file name must not be empty"),
    ("environment { color < 1 1 1 > } environment { color < 1 1 1 > }", 33,
     "duplicate 'environment' statement"),
    ("environment { colour < 1 1 1 > }", 15, "unknown keyword 'colour'"),
])
def test_bad_environments_are_refused_at_their_token(files, block, column, words):
    folder, _ = files
    with pytest.raises(SceneError) as caught:
        load(folder, block + "\n" + scene_text(""))
    assert words in str(caught.value)
    assert (caught.value.line, caught.value.column) == (1, column)


def _header_only_exr(path, width, height):
    """An OpenEXR header claiming a width×height image, and nothing after it."""
    write_exr(path, np.zeros((3, 2, 3), np.float32))
    data = bytearray(path.read_bytes())
    at = data.index(b"dataWindow\0box2i\0") + len(b"dataWindow\0box2i\0") + 4
    data[at:at + 16] = np.array([0, 0, width - 1, height - 1], "<i4").tobytes()
    path.write_bytes(bytes(data))


def _small_8_bit(path, kind):
    """A PNG of 4×2 or a JPEG of 1×5 pixels, each pixel its own colour."""
    from PIL import Image
    size = (4, 2) if kind == "PNG" else (1, 5)
    pixels = (np.arange(size[0] * size[1] * 3).reshape(size[1], size[0], 3) * 9).astype(np.uint8)
    Image.fromarray(pixels).save(path, format=kind)


@pytest.mark.parametrize("make, words", [
    (lambda p: _header_only_exr(p, 60000, 60000), "60000x60000 = 3600000000 pixels"),
    (lambda p: _header_only_exr(p, 4, 1), "at least 2x3"),
    (lambda p: p.write_bytes(p.with_name("sky.exr").read_bytes()[:-7]), "a truncated OpenEXR"),
    (lambda p: p.write_bytes(p.with_name("sky.exr").read_bytes()[:200]), "a truncated OpenEXR"),
    (lambda p: p.write_bytes(p.with_name("sky.hdr").read_bytes()[:-5]), "a truncated Radiance HDR"),
    (lambda p: p.write_bytes(p.with_name("sky.hdr").read_bytes().replace(b"rgbe", b"xyze")),
     "XYZ colours"),
    (lambda p: p.write_bytes(b"just some text, no image"), "not an environment image"),
    (lambda p: p.write_bytes(p.with_name("sky.png").read_bytes()[:-20]), "a truncated PNG"),
    # as small as the OpenEXR above, in 8 bits: Mitsuba pads it, the reference would not
    (lambda p: _small_8_bit(p, "PNG"), "an image of 4x2 pixels; an environment image is at "
                                       "least 2x3"),
    (lambda p: _small_8_bit(p, "JPEG"), "an image of 1x5 pixels; an environment image is at "
                                        "least 2x3"),
])
def test_huge_truncated_or_non_image_files_exit_2_in_one_sentence(files, make, words, capsys):
    folder, _ = files
    bad = folder / "bad.img"
    make(bad)
    scene = folder / "bad.scene"
    scene.write_text('environment { file "bad.img" }\n' + scene_text(""))
    out = folder / "bad.png"
    assert main(["render", str(scene), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{scene}:1:20: environment file 'bad.img': " in err and words in err, err
    assert "Traceback" not in err and not out.exists()


def test_an_unchanged_file_is_walked_once_and_a_rewritten_one_again(files, tmp_path,
                                                                    monkeypatch):
    """to_mitsuba checks the environment file for every scene (each sweep frame, each
    studio edit): an HDR's scanlines are walked once per version of the file, and a file
    cut since is refused."""
    from mimarble.scene import environment_header
    folder, _ = files
    walked = []
    real_walk = environment_header.walk_hdr
    monkeypatch.setattr(environment_header, "walk_hdr",
                        lambda *a, **k: walked.append(1) or real_walk(*a, **k))
    sky_file = tmp_path / "kept.hdr"
    sky_file.write_bytes((folder / "sky.hdr").read_bytes())
    scene = load(tmp_path, scene_text('environment { file "kept.hdr" }'))
    for _ in range(3):
        to_mitsuba(scene, "path")
    assert len(walked) == 1
    sky_file.write_bytes((folder / "sky.hdr").read_bytes()[:-5])
    with pytest.raises(SceneError, match="a truncated Radiance HDR"):
        to_mitsuba(scene, "path")


def test_a_huge_header_is_refused_from_a_bounded_read(files, monkeypatch):
    """60000² float RGB would be 43 GB: a file of 1 GiB (sparse) whose header claims it is
    refused from its header, the check having read at most EXR_HEADER_MOST bytes and the
    signature (every read counted), nothing in proportion to the file or the image."""
    folder, _ = files
    _header_only_exr(folder / "huge.exr", 60000, 60000)
    with open(folder / "huge.exr", "r+b") as f:
        f.truncate(1 << 30)
    from mimarble.scene import environment_header
    opened = environment_header.open_regular
    reads = []

    def counted(path):
        f = opened(path)
        read = f.read
        f.read = lambda n=-1: reads.append(len(data := read(n))) or data
        return f

    monkeypatch.setattr(environment_header, "open_regular", counted)
    problem = environment_header.environment_file_problem(str(folder / "huge.exr"))
    assert "60000x60000 = 3600000000 pixels; environments hold at most" in problem
    assert sum(reads) <= environment_header.EXR_HEADER_MOST + 8 + 10
    (folder / "huge.exr").unlink()


def test_the_model_checks_what_the_parser_checks(files):
    folder, _ = files
    with pytest.raises(ValueError, match="exactly one of file and color"):
        model.Environment()
    with pytest.raises(ValueError, match="intensity must be >= 0"):
        model.Environment(color=(1, 1, 1), intensity=-2)
    with pytest.raises(TypeError, match="environment must be an Environment"):
        model.Scene(environment="sky.exr")
    # A scene built in Python, with a file the parser never saw: refused before Mitsuba.
    bad = folder / "python.exr"
    bad.write_bytes(b"\x76\x2f\x31\x01" + b"\0" * 8)
    scene = model.Scene(environment=model.Environment(file=str(bad)))
    with pytest.raises(SceneError, match="environment file"):
        to_mitsuba(scene, "path")


# ---------------------------------------------------------------------------
# The files, as Mitsuba and the reference read them

@pytest.mark.parametrize("name", ["sky.exr", "half.exr", "sky.hdr", "flat.hdr"])
def test_the_reference_decodes_what_mitsuba_reads(files, name, llvm):
    folder, held = files
    mitsuba = np.array(mi.Bitmap(str(folder / name)).convert(
        mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, False), dtype=np.float64)
    ours = reference_environment.load_environment(folder / name)
    assert np.array_equal(mitsuba, held[name])            # the test's writer, checked
    assert np.array_equal(ours, held[name])


def test_the_lookup_follows_envmaps_convention():
    """Straight up is the top row (v = 0), −z the image's left edge (u = 0), +x a quarter
    across, +z the centre column (u = ½): envmap's direction_to_uv, u = atan2(x, −z)/2π."""
    u, v = reference_environment.direction_uv(
        np.array([[0.0, 1, 0], [0, 0, -1], [1, 0, 0], [0, 0, 1], [0, -1, 0]]))
    assert np.allclose(v, [0, 0.5, 0.5, 0.5, 1]) and np.allclose(u[1:4], [0, 0.25, 0.5])


# ---------------------------------------------------------------------------
# Path mode: Mitsuba's own envmap scene, written by hand

def hand_written(folder, spp, sky_emitter):
    """The marble sphere of SCENE as a Mitsuba user writes it: Mitsuba's plugins and
    defaults, but the clip planes, which mimarble sets to keep every shape in view
    (near: half the nearest distance, (6 − 1.2)/2; far: just past the farthest, 7.2 + 0.1 %)."""
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 4},
        "sensor": {"type": "perspective", "fov": 40, "fov_axis": "y",
                   "near_clip": 2.4, "far_clip": 7.2072,
                   "to_world": T().look_at(origin=[0, 0, 6], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 40, "height": 30, "pixel_format": "rgb",
                            "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": spp}},
        "veins": {"type": "marble", "period": 1.3, "tolerance": 0.0},
        "ball": {"type": "sphere", "radius": 1.2,
                 "bsdf": {"type": "diffuse", "reflectance": {"type": "ref", "id": "veins"}}},
        "sky": sky_emitter,
    }


@pytest.mark.parametrize("block, emitter", [
    ('environment { file "sky.exr" intensity 1.5 rotate < 10 20 30 > }',
     lambda folder: {"type": "envmap", "filename": str(folder / "sky.exr"), "scale": 1.5,
                     "to_world": T().rotate([0, 0, 1], 30) @ T().rotate([0, 1, 0], 20)
                     @ T().rotate([1, 0, 0], 10)}),
    ('environment { file "sky.hdr" }',
     lambda folder: {"type": "envmap", "filename": str(folder / "sky.hdr")}),
    ("environment { color < 0.8 0.9 1.0 > intensity 0.5 }",
     lambda folder: {"type": "constant", "radiance": {"type": "rgb", "value": [0.4, 0.45, 0.5]}}),
])
def test_path_mode_equals_mitsubas_own_scene_bit_for_bit(files, block, emitter, llvm):
    folder, _ = files
    scene = load(folder, scene_text(block, samples=4))
    ours = np.array(mi.render(mi.load_dict(to_mitsuba(scene, "path")), seed=0))
    theirs = np.array(mi.render(mi.load_dict(hand_written(folder, 4, emitter(folder))), seed=0))
    assert np.array_equal(ours, theirs)
    assert ours[0, 0].max() > 0.1          # the camera sees the sky (a corner misses the ball)
    # ... and the project's own render (in passes, summed in float64) within float32 rounding
    rendered = mimarble.render(scene, mode="path")
    assert np.abs(rendered - ours[..., :3]).max() <= 1e-5 * max(1.0, ours.max())


def test_a_wrong_rotation_is_not_bit_equal(files, llvm):
    """The comparison can fail: the same scene with the sky turned the other way."""
    folder, _ = files
    scene = load(folder, scene_text('environment { file "sky.exr" rotate < 0 30 0 > }', samples=4))
    ours = np.array(mi.render(mi.load_dict(to_mitsuba(scene, "path")), seed=0))
    wrong = {"type": "envmap", "filename": str(folder / "sky.exr"),
             "to_world": T().rotate([0, 1, 0], -30)}
    theirs = np.array(mi.render(mi.load_dict(hand_written(folder, 4, wrong)), seed=0))
    assert not np.array_equal(ours, theirs)


# ---------------------------------------------------------------------------
# Whitted mode: the background of camera rays, against the reference's own lookup

@pytest.mark.parametrize("name", ["sky.exr", "half.exr", "sky.hdr", "flat.hdr", "sky.png"])
def test_whitted_mode_agrees_with_the_reference(files, name, llvm):
    folder, _ = files
    scene = load(folder, scene_text(f'environment {{ file "{name}" intensity 1.5 rotate < 10 20 30 > }}',
                                    samples=4, extra="ambient < 0.1 0.1 0.1 >\n"
                                                     "light { position < 5 5 5 > }"))
    mitsuba = mimarble.render(scene)
    reference = mimarble.reference.render(scene)
    missed = np.abs(mitsuba - np.array(scene.image.background)).max(axis=-1) > 0.05
    assert missed.mean() > 0.3                       # much of the image is the sky
    assert np.abs(mitsuba - reference).max() < 2e-5 * reference.max()


def test_the_scalar_variant_sees_the_sky_too(files):
    """scalar_rgb (Python booleans for masks) renders what llvm_ad_rgb renders."""
    folder, _ = files
    scene = load(folder, scene_text('environment { file "sky.exr" rotate < 0 45 0 > }')
                 .replace("width 40 height 30", "width 8 height 6"))
    previous = mi.variant()
    try:
        mi.set_variant("llvm_ad_rgb")
        jit = mimarble.render(scene)
        mi.set_variant("scalar_rgb")
        scalar = mimarble.render(scene)
    finally:
        mi.set_variant(previous)
    assert np.abs(jit - scalar).max() < 1e-5 * jit.max() and jit.max() > 0.1


def test_whitted_sees_the_sky_in_the_right_place(files, llvm):
    """A sky black but for one bright texel: a camera looking straight at its direction
    sees it in the image centre (whitted and reference alike), a planted rotation not."""
    folder, _ = files
    image = np.zeros((16, 32, 3), np.float32)
    image[8, 24] = 100.0        # u = 24.5/32 → φ = 275.6°, v = 8/15 → θ = 96°
    write_exr(folder / "dot.exr", image)
    u, v = 24.5 / 32, 8 / 15
    phi, theta = 2 * np.pi * u, np.pi * v
    d = np.array([np.sin(phi) * np.sin(theta), np.cos(theta), -np.cos(phi) * np.sin(theta)])
    eye = [float(c) for c in -6 * d]
    text = ("image { width 9 height 9 }\n"
            f"camera {{ eye < {eye[0]!r} {eye[1]!r} {eye[2]!r} > lookat < 0 0 0 > fov 2 }}\n"
            'environment { file "dot.exr" }\n'
            'material "m" { diffuse { color < 1 1 1 > } }\n'
            "sphere { center < 0 40 0 > radius 1 material \"m\" }\n")
    scene = load(folder, text)
    for rendered in (mimarble.render(scene), mimarble.reference.render(scene)):
        assert np.unravel_index(rendered[..., 0].argmax(), (9, 9)) == (4, 4)
    turned = load(folder, text.replace('"dot.exr"', '"dot.exr" rotate < 0 90 0 >'))
    assert mimarble.reference.render(turned)[4, 4, 0] < 1.0


def test_a_rewritten_environment_file_is_seen(tmp_path, llvm):
    """The loaded scene is kept by its structure, which holds the environment file's facts:
    the same scene after its file changed renders the new sky."""
    write_exr(tmp_path / "sky.exr", sky())
    scene = load(tmp_path, scene_text('environment { file "sky.exr" }'))
    first = mimarble.render(scene)
    write_exr(tmp_path / "sky.exr", 2 * sky())
    second = mimarble.render(scene)
    assert np.allclose(second[0, 0], 2 * first[0, 0])


def test_the_ambient_term_stays_the_papers(files, llvm):
    """Whitted mode: the environment lights nothing; a hit is ka·A + the lights, as without it."""
    folder, _ = files
    extra = "ambient < 0.3 0.2 0.1 >\nlight { position < 5 5 5 > }"
    text = scene_text('environment { file "sky.exr" intensity 9 }', extra=extra) \
        .replace('diffuse {', 'ambient { color < 1 1 1 > } diffuse {')
    lit, plain = load(folder, text), load(folder, scene_text("", extra=extra)
                                          .replace('diffuse {', 'ambient { color < 1 1 1 > } diffuse {'))
    a, b = mimarble.render(lit), mimarble.render(plain)
    hit = np.abs(b).max(axis=-1) > 0
    assert np.array_equal(a[hit], b[hit]) and not np.array_equal(a[~hit], b[~hit])


def test_compare_agrees_in_whitted_mode(files, capsys, llvm):
    folder, _ = files
    scene = folder / "compare.scene"
    scene.write_text(scene_text('environment { file "sky.exr" rotate < 0 45 0 > }',
                                extra="light { position < 5 5 5 > }"))
    assert main(["compare", str(scene), "--json"]) == 0
    import json
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["psnr"] > 100, result


def test_the_reference_refuses_what_it_cannot_decode_in_one_sentence(files, capsys, llvm):
    """Mitsuba writes OpenEXR with PIZ: path and whitted modes read it, the reference says
    it reads NONE, ZIPS and ZIP."""
    folder, _ = files
    mi.Bitmap(sky()).write(str(folder / "piz.exr"))
    scene = folder / "piz.scene"
    scene.write_text(scene_text('environment { file "piz.exr" }'))
    assert main(["render", str(scene), "-o", str(folder / "piz.png")]) == 0
    capsys.readouterr()
    assert main(["reference", str(scene), "-o", str(folder / "piz-ref.png")]) == 2
    err = capsys.readouterr().err
    assert f"{scene}:4:20: environment file 'piz.exr': the reference tracer reads" in err
    assert "not PIZ" in err and "Traceback" not in err


# ---------------------------------------------------------------------------
# Translucent spheres in path mode: lit by the environment

def test_a_translucent_sphere_under_the_sky_alone_agrees_with_the_walk(files, llvm):
    """No light but the environment: volpath's subsurface boundary takes the sky (by
    next-event estimation, and by paths that escape), the walk by escaping paths only;
    both see it directly from the camera. Block means agree within their noise."""
    import test_translucent_reference as tr
    folder, _ = files
    base = tr.translucent_scene(ambient=(0.0, 0.0, 0.0), size=16)
    scene = model.Scene(image=base.image, camera=base.camera, materials=base.materials,
                        spheres=base.spheres,
                        environment=model.Environment(file=str(folder / "sky.exr"),
                                                      rotate=(0.0, 60.0, 0.0)))
    translated = to_mitsuba(scene, "path", spp=32)
    assert translated["integrator"]["type"] == "volpath"
    assert translated["integrator"]["hide_emitters"] is False
    loaded = mi.load_dict(translated)
    renders = np.stack([np.array(mi.render(loaded, seed=100 + k), dtype=np.float64)[..., :3]
                        for k in range(tr.SEEDS)])
    image, variance = volume.render_translucent(scene, 192, seed=3,
                                                max_depth=translated["integrator"]["max_depth"],
                                                variance=True)
    covered = tr.coverage(scene) > 0.5
    assert image[covered].mean() > 0.05 and renders.mean(axis=0)[covered].mean() > 0.05
    ratio, z, m = tr.agreement(scene, image, variance, 192, renders)
    assert ratio < 1, (z, m)
    # The agreement can fail: the walk under a sky 10 % dimmer.
    dimmer = dataclasses.replace(scene, environment=dataclasses.replace(scene.environment,
                                                                        intensity=0.9))
    image, variance = volume.render_translucent(dimmer, 192, seed=3,
                                                max_depth=translated["integrator"]["max_depth"],
                                                variance=True)
    assert tr.agreement(scene, image, variance, 192, renders)[0] > 1


# ---------------------------------------------------------------------------
# Export

@pytest.mark.parametrize("block", ['environment { file "sky.exr" intensity 1.5 rotate < 10 20 30 > }',
                                   "environment { color < 0.8 0.9 1.0 > intensity 0.5 }"])
@pytest.mark.parametrize("mode", ["whitted", "path"])
def test_export_includes_the_environment(files, block, mode, tmp_path, llvm):
    """The XML and the Python file render as the dict, bit for bit (test_export's rule:
    the XML as the dict with the transforms' inverses XML makes)."""
    from test_export import assert_both_render_as_the_dict
    folder, _ = files
    scene_dict = to_mitsuba(load(folder, scene_text(block, samples=4)), mode)
    assert scene_dict["environment"]["type"] in ("envmap", "constant")
    assert_both_render_as_the_dict(scene_dict, tmp_path)
    xml = (tmp_path / "scene.xml").read_text()
    assert '<emitter type="envmap"' in xml or '<emitter type="constant"' in xml


# ---------------------------------------------------------------------------
# Sweep keys

def test_the_environment_has_sweep_keys(files):
    from mimarble.scene.keys import KeyPathError, keys_listing, scene_keys, with_value
    from mimarble.scene.rewrite import rewrite
    folder, _ = files
    text = scene_text('environment { file "sky.exr" intensity 1.5 }')
    scene = load(folder, text)
    keys = scene_keys(scene)
    assert keys["environment.intensity"].value == 1.5
    assert keys["environment.rotate"].value == (0.0, 0.0, 0.0)
    assert "environment.rotate" in keys_listing(scene)
    turned = with_value(scene, "environment.rotate", "0 90 0")
    assert turned.environment.rotate == (0.0, 90.0, 0.0) and turned.environment.file == "sky.exr"
    assert with_value(scene, "environment.intensity", 3).environment.intensity == 3.0
    for path, value in (("environment.rotate", "0 90 0"), ("environment.intensity", "2")):
        rewritten = rewrite(text, {path: value}, source=str(folder / "scene.scene"))
        assert parse(rewritten, source=str(folder / "scene.scene")) == with_value(scene, path, value)
    with pytest.raises(KeyPathError, match="environment.intensity"):
        with_value(scene, "environment.intensity", "-1")
    colour = parse(scene_text("environment { color < 1 1 1 > }"))
    assert "environment.rotate" not in scene_keys(colour)
    with pytest.raises(KeyPathError, match="it has no rotate"):
        with_value(colour, "environment.rotate", "0 1 0")
    with pytest.raises(KeyPathError, match="the scene has no environment"):
        with_value(parse(scene_text("")), "environment.intensity", "2")


def test_a_damaged_file_that_passes_the_header_check_is_one_sentence(files, capsys, llvm):
    """A ZIP OpenEXR whose compressed bytes are damaged is whole by its header and table:
    Mitsuba's reader and the reference's decoder each refuse it in one sentence, exit 2."""
    folder, _ = files
    data = bytearray((folder / "sky.exr").read_bytes())
    data[-40:-20] = bytes(20)                     # inside the last chunk's zlib stream
    (folder / "damaged.exr").write_bytes(bytes(data))
    scene = folder / "damaged.scene"
    scene.write_text(scene_text('environment { file "damaged.exr" }'))
    for command in ("render", "reference"):
        out = folder / f"damaged-{command}.png"
        assert main([command, str(scene), "-o", str(out)]) == 2
        err = capsys.readouterr().err
        assert f"{scene}:4:20: environment file 'damaged.exr'" in err, err
        assert "Traceback" not in err and not out.exists()
        assert len([line for line in err.splitlines() if "warning" not in line]) == 3, err


@pytest.mark.parametrize("name", ["sky.exr", "half.exr", "sky.hdr"])
def test_damaged_and_cut_files_are_refused_or_read_never_an_exception(files, name, tmp_path):
    """Bytes changed at random or the file cut anywhere: the header check refuses it in a
    sentence, or passes it and the reference's decoder reads it or refuses it in a sentence
    (Unreadable) — nothing else escapes."""
    import random
    from mimarble.scene.environment_header import environment_file_problem
    folder, _ = files
    data = (folder / name).read_bytes()
    rng = random.Random(7)
    for k in range(120):
        damaged = bytearray(data)
        if k % 2:
            damaged = damaged[:rng.randrange(len(damaged))]
        else:
            for _ in range(rng.randrange(1, 6)):
                damaged[rng.randrange(len(damaged))] = rng.randrange(256)
        path = tmp_path / f"{k}{name}"
        path.write_bytes(bytes(damaged))
        problem = environment_file_problem(str(path))
        assert problem is None or (isinstance(problem, str) and "\n" not in problem)
        if problem is None:
            try:
                reference_environment.load_environment(path)
            except reference_environment.Unreadable as e:
                assert "\n" not in str(e)


def test_only_the_r_g_b_channels_must_hold_half_or_float_samples():
    """An extra UINT channel whose name is part of "RGB" ("RG", "") is not one of them."""
    import struct
    from mimarble.scene.environment_header import EnvironmentFileProblem, _exr_channels

    def channel(name: str, kind: int) -> bytes:      # name, type, pLinear + 3 reserved, x/y sampling
        return name.encode() + b"\0" + struct.pack("<iBxxxii", kind, 0, 1, 1)

    rgb = channel("B", 2) + channel("G", 2) + channel("R", 2)
    assert [name for name, _ in _exr_channels(rgb + channel("RG", 0) + b"\0", 256)] == \
        ["B", "G", "R", "RG"]
    with pytest.raises(EnvironmentFileProblem, match="channel G holds UINT"):
        _exr_channels(channel("B", 2) + channel("G", 0) + channel("R", 2) + b"\0", 256)
