"""Hostile and careless scene input (issue 23): the limits, stated once and enforced at the
edge; special files; truncated and oversized image maps; numbers that vanish in single
precision; long lines; and the model's constructors, which check what the parser checks.

Each case is one sentence — a SceneError at FILE:LINE:COL where there is a line, a
ValueError or TypeError from Python — within bounded time and memory. The files are the
tests' own: PNG and JPEG headers written by hand (a 40000×40000 "image" of a hundred
bytes), small images written by Pillow, a FIFO, /dev/zero.
"""

from __future__ import annotations

import dataclasses
import io
import os
import re
import signal
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image as PILImage

import mimarble
from mimarble import parameters as marble_parameters
from mimarble import scene as S
from mimarble.reference import image_map
from mimarble.scene import SceneError, parse
from mimarble.scene.errors import SHOWN_WIDTH
from mimarble.scene.image_header import image_file_sentence
from mimarble.scene.limits import (MAX_CHANNEL_DEPTH, MAX_IMAGE_MAP_PIXELS, MAX_LIGHTS,
                                   MAX_SCENE_BYTES, MAX_SPHERES)

ROOT = Path(__file__).resolve().parent.parent
GOOD_MATERIAL = 'material "m" { diffuse { color < 1 1 1 > } }\n'


def refusal(text, filename="h.scene") -> SceneError:
    with pytest.raises(SceneError) as info:
        parse(text, filename)
    return info.value


def quickly(call, seconds: int = 120):
    """``call()``, which must return (or raise) rather than block: a guard that fails a
    test which would otherwise hang (a FIFO read), not a speed target (timings belong in
    benchmarks), so its limit is generous."""
    def blocked(signum, frame):
        raise TimeoutError(f"still running after {seconds} s: it blocks")
    previous = signal.signal(signal.SIGALRM, blocked)
    signal.alarm(seconds)
    try:
        return call()
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


# ---------------------------------------------------------------------------
# Image files, by hand

def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png_header(width, height, depth=8, end=True) -> bytes:
    """A PNG that claims width × height pixels: IHDR, an empty IDAT, IEND."""
    ihdr = struct.pack(">IIBBBBB", width, height, depth, 2, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", zlib.compress(b""))
    return data + (_chunk(b"IEND", b"") if end else b"")


def jpeg_header(width, height, precision=8) -> bytes:
    """A JPEG that claims width × height pixels: SOI, APP0 (JFIF), a comment, SOF0, EOI."""
    def segment(marker, payload):
        return bytes([0xFF, marker]) + struct.pack(">H", len(payload) + 2) + payload
    return (b"\xff\xd8" + segment(0xE0, b"JFIF\0\x01\x01\0\0\x01\0\x01\0\0")
            + segment(0xFE, b"made by hand") + b"\xff"       # a fill byte before the SOF
            + segment(0xC0, struct.pack(">BHHB", precision, height, width, 1) + b"\x01\x11\x00")
            + b"\xff\xd9")


def real_image(path: Path) -> Path:
    """A small real image (Pillow), PNG or JPEG by its suffix."""
    pixels = np.random.default_rng(1).integers(0, 256, (16, 32, 3), dtype=np.uint8)
    PILImage.fromarray(pixels, "RGB").save(path)
    return path


def map_scene(tmp_path: Path, file: str) -> Path:
    """A scene whose diffuse channel is the image map ``file``, at line 2, column 26."""
    scene = tmp_path / "s.scene"
    scene.write_text(f'material "m" {{\n  diffuse {{ image {{ file "{file}" }} }}\n}}\n'
                     'sphere { material "m" }\nimage { width 8 height 8 }\n'
                     'light { position < 5 5 5 > }\n')
    return scene


def python_scene(path) -> S.Scene:
    """A scene built in Python around the image map at ``path`` (the parser never saw it)."""
    return S.Scene(image=S.Image(8, 8), lights=(S.Light((5, 5, 5)),),
                   materials={"m": S.Material("m", diffuse=S.ImageChannel(str(path)))},
                   spheres=(S.Sphere("m"),))


def refused_at_its_file_string(scene: Path) -> SceneError:
    with pytest.raises(SceneError) as info:
        S.load(scene)
    e = info.value
    assert (e.line, e.column) == (2, 26), str(e)
    return e


# ---------------------------------------------------------------------------
# 1. Limits

def test_the_limits_are_stated_once():
    """One record each (tests/test_limits_table.py checks the docs' table is written from them)."""
    assert (S.LIMITS["max_scene_bytes"], S.LIMITS["max_image_map_pixels"],
            S.LIMITS["max_channel_depth"], S.LIMITS["max_lights"], S.LIMITS["max_spheres"]) \
        == (MAX_SCENE_BYTES, MAX_IMAGE_MAP_PIXELS, MAX_CHANNEL_DEPTH, MAX_LIGHTS, MAX_SPHERES)


def test_a_scene_file_over_the_size_limit_is_refused_from_its_size(tmp_path):
    big = tmp_path / "big.scene"
    with open(big, "wb") as f:
        f.truncate(MAX_SCENE_BYTES + 1)          # sparse: nothing is written, nothing read
    with pytest.raises(SceneError) as info:
        quickly(lambda: S.load(big))
    assert str(info.value) == (f"{big}: the scene is larger than 4 MiB ({MAX_SCENE_BYTES} "
                               f"bytes), the most a scene file holds (docs/scene-language.md, "
                               f"Limits)")


def test_a_scene_at_the_size_limit_parses_and_text_past_it_is_refused(tmp_path):
    text = "//" + "x" * (MAX_SCENE_BYTES - 3) + "\n"
    at_limit = tmp_path / "at.scene"
    at_limit.write_text(text)
    assert S.load(at_limit) == S.Scene()
    for past in (text + " ", (text + " ").encode(), "//" + "é" * (MAX_SCENE_BYTES // 2)):
        e = refusal(past)
        assert e.line is None and "larger than 4 MiB" in e.message


def test_dev_zero_as_a_scene_is_refused_at_once():
    with pytest.raises(SceneError, match="^/dev/zero: cannot read scene file: it is a "
                                         "character device, not a regular file$"):
        quickly(lambda: S.load("/dev/zero"))


def test_render_of_dev_zero_is_exit_2_in_one_sentence(tmp_path):
    out = tmp_path / "out.png"
    result = subprocess.run([sys.executable, "-m", "mimarble", "render", "/dev/zero", "-o", str(out)],
                            cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stderr
    assert "character device" in result.stderr and "Traceback" not in result.stderr
    assert not out.exists()


@pytest.mark.parametrize("make, kind", [(png_header, "PNG"), (jpeg_header, "JPEG")])
def test_an_image_map_over_the_pixel_limit_is_refused_at_its_file_string(tmp_path, make, kind):
    suffix = ".png" if kind == "PNG" else ".jpg"
    (tmp_path / f"bomb{suffix}").write_bytes(make(40000, 40000))
    e = refused_at_its_file_string(map_scene(tmp_path, f"bomb{suffix}"))
    assert e.message == (f"image file 'bomb{suffix}': a {kind} of 40000x40000 = 1600000000 "
                         f"pixels; image maps hold at most 67108864 (8192x8192) pixels")
    # At the limit the header passes (nothing is decoded while parsing); one row more does not.
    (tmp_path / f"bomb{suffix}").write_bytes(make(8192, 8192))
    S.load(map_scene(tmp_path, f"bomb{suffix}"))
    (tmp_path / f"bomb{suffix}").write_bytes(make(8192, 8193))
    assert "8192x8193" in refused_at_its_file_string(map_scene(tmp_path, f"bomb{suffix}")).message


def test_the_reference_refuses_an_oversized_map_in_the_parser_s_words(tmp_path):
    from mimarble import reference
    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(png_header(40000, 40000))
    with pytest.raises(ValueError, match="image maps hold at most 67108864"):
        image_map.load_image(bomb)
    with pytest.raises(SceneError) as info:           # a scene built in Python: not parsed
        reference.render(python_scene(bomb))
    assert info.value.message == image_file_sentence(str(bomb), str(bomb))
    assert "40000x40000" in info.value.message


def test_the_reference_loader_checks_the_size_pillow_read(tmp_path, monkeypatch):
    """Should the file change between the header check and Pillow's open, the size Pillow
    read is checked before a pixel is decoded (9000² is past ours, within Pillow's)."""
    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(png_header(9000, 9000))
    monkeypatch.setattr(image_map, "image_file_problem", lambda path: None)
    image_map.clear_cache()
    with pytest.raises(ValueError, match=r"a PNG of 9000x9000 = 81000000 pixels; image maps "
                                         r"hold at most 67108864"):
        quickly(lambda: image_map.load_image(bomb))
    image_map.clear_cache()


def test_the_mitsuba_path_checks_headers_before_decoding(llvm, tmp_path):
    """Every Mitsuba path goes through to_mitsuba, which checks a Python scene's maps."""
    bomb = tmp_path / "bomb.jpg"
    bomb.write_bytes(jpeg_header(40000, 40000))
    with pytest.raises(SceneError) as info:
        quickly(lambda: mimarble.to_mitsuba(python_scene(bomb)))
    assert info.value.message == image_file_sentence(str(bomb), str(bomb))


def nested(depth: int, expression="add") -> str:
    """A material whose diffuse channel nests ``depth`` levels: depth − 1 expressions
    around a colour."""
    inner = "color < 1 1 1 >"
    for _ in range(depth - 1):
        inner = f"{expression} {{ {inner} color < 0 0 0 > }}" if expression != "mix" else \
            f"mix {{ color < 0 0 0 > color < 1 1 1 > weight {inner} }}"
    return f'material "m" {{ diffuse {{ {inner} }} }}'


@pytest.mark.parametrize("expression", ["add", "mix"])
def test_a_channel_nested_to_the_limit_renders_as_its_reference(llvm, expression):
    """At the depth limit the replay's inputs are nested deeper than Dr.Jit's traversal
    goes (a RecursionError inside dr.freeze): the pass is traced instead, same image."""
    import mimarble
    from mimarble.tools.compare import image_metrics
    text = ("image { width 8 height 8 samples 1 } camera { eye < 0 0 9 > } "
            "light { position < 5 5 5 > } " + nested(MAX_CHANNEL_DEPTH, expression)
            + ' sphere { material "m" radius 2 }')
    scene = parse(text)
    metrics = image_metrics(mimarble.render(scene), mimarble.reference.render(scene))
    assert metrics["psnr"] > 100, metrics


@pytest.mark.parametrize("expression", ["add", "multiply", "mix"])
def test_channels_nest_64_deep_and_no_deeper(expression):
    parse(nested(MAX_CHANNEL_DEPTH, expression))
    text = nested(MAX_CHANNEL_DEPTH + 1, expression)
    e = refusal(text)
    assert e.message == "channels nested too deep: at most 64 levels (this one is at level 65)"
    # At the channel that goes too deep: the 65th channel keyword on the way in.
    words = [m.start() for m in re.finditer(r"\b(add|multiply|mix|color)\b", text)]
    path = [i for i in words if text.startswith(expression, i)][:MAX_CHANNEL_DEPTH]
    after = [i for i in words if i > path[-1]]
    assert (e.line, e.column) == (1, after[0] + 1)     # the 64th expression's first operand


def test_a_channel_nested_thousands_deep_is_refused_at_once():
    depth = 100_000                                    # 2.3 MB: within the size limit
    text = ('material "m" { diffuse { ' + "add { " * depth + "color < 1 1 1 >"
            + " color < 0 0 0 > }" * depth + " } }")
    e = quickly(lambda: refusal(text))
    assert "nested too deep" in e.message and e.column == len('material "m" { diffuse { ') + 64 * 6 + 1


def test_python_built_channels_nest_64_deep_and_no_deeper():
    channel = S.ColorChannel((1, 1, 1))
    for _ in range(MAX_CHANNEL_DEPTH - 1):
        channel = S.Multiply((channel, S.ColorChannel((0.5, 0.5, 0.5))))
    assert S.model.depth(channel) == MAX_CHANNEL_DEPTH
    with pytest.raises(ValueError, match=r"^channels nested too deep: at most 64 levels"):
        S.Add((S.ColorChannel((0, 0, 0)), channel))
    with pytest.raises(ValueError, match="nested too deep"):
        S.Mix(S.ColorChannel((0, 0, 0)), S.ColorChannel((1, 1, 1)), channel)
    with pytest.raises(ValueError, match="nested too deep"):
        S.Mix(channel, S.ColorChannel((1, 1, 1)), 0.5)
    assert S.model.depth(S.Mix(S.ColorChannel((0, 0, 0)), S.ColorChannel((1, 1, 1)), 0.5)) == 2


def lights(count: int) -> str:
    return "".join(f"light {{ position < {k} 1 2 > }}\n" for k in range(count))


def test_lights_past_the_limit_are_refused_at_the_first_too_many():
    assert len(parse(lights(MAX_LIGHTS)).lights) == MAX_LIGHTS
    # What follows the 1025th light is not even parsed: its syntax error is never reached.
    e = refusal(lights(MAX_LIGHTS + 1) + "}}} nonsense")
    assert (e.line, e.column) == (MAX_LIGHTS + 1, 1)
    assert e.message.startswith("too many lights: a scene holds at most 1024 (the whitted "
                                "integrator unrolls its loop over the lights")


def test_spheres_past_the_limit_are_refused_at_the_first_too_many():
    spheres = 'sphere { material "m" }\n' * (MAX_SPHERES + 1)
    e = quickly(lambda: refusal(GOOD_MATERIAL + spheres + "}}} nonsense"))
    assert (e.line, e.column) == (MAX_SPHERES + 2, 1)
    assert e.message.startswith("too many spheres: a scene holds at most 10000")


def test_python_built_scenes_are_held_to_the_same_counts():
    with pytest.raises(ValueError, match="^too many lights: a scene holds at most 1024"):
        S.Scene(lights=[S.Light((0, 0, 0))] * (MAX_LIGHTS + 1))
    material = {"m": S.Material("m")}
    S.Scene(materials=material, spheres=[S.Sphere("m")] * MAX_SPHERES)
    with pytest.raises(ValueError, match="^too many spheres: a scene holds at most 10000"):
        S.Scene(materials=material, spheres=[S.Sphere("m")] * (MAX_SPHERES + 1))


# ---------------------------------------------------------------------------
# 2. Special files

@pytest.mark.timeout(30)
def test_a_fifo_as_the_scene_file_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.scene"
    os.mkfifo(fifo)
    with pytest.raises(SceneError, match="cannot read scene file: it is a FIFO \\(named pipe\\), "
                                         "not a regular file$"):
        quickly(lambda: S.load(fifo))


@pytest.mark.timeout(30)
@pytest.mark.parametrize("special", ["fifo", "/dev/zero"])
def test_a_fifo_or_a_device_as_an_image_map_is_refused_without_blocking(tmp_path, special):
    if special == "fifo":
        special = str(tmp_path / "pipe.png")
        os.mkfifo(special)
    kind = "a FIFO (named pipe)" if special.endswith("pipe.png") else "a character device"
    e = quickly(lambda: refused_at_its_file_string(map_scene(tmp_path, special)))
    assert e.message == f"image file '{special}': it is {kind}, not a regular file ({special})"
    with pytest.raises(ValueError, match="not a regular file"):
        quickly(lambda: image_map.load_image(special))


@pytest.mark.timeout(30)
def test_an_error_quoting_a_scene_file_that_became_a_fifo_does_not_block(tmp_path):
    fifo = tmp_path / "was.scene"
    os.mkfifo(fifo)
    e = quickly(lambda: SceneError.in_file(str(fifo), S.Pos(1, 1), "a message"))
    assert e.source_line is None and str(e) == f"{fifo}:1:1: a message"


# ---------------------------------------------------------------------------
# 3. Truncated images: refused by the header check, so by both renderers alike

@pytest.mark.parametrize("suffix, kind, end", [
    (".jpg", "JPEG", "its end marker (EOI, FF D9)"), (".png", "PNG", "its IEND chunk")])
def test_a_truncated_image_map_is_refused_at_its_file_string(tmp_path, suffix, kind, end):
    whole = real_image(tmp_path / f"whole{suffix}").read_bytes()
    (tmp_path / f"cut{suffix}").write_bytes(whole[:len(whole) // 2])
    e = refused_at_its_file_string(map_scene(tmp_path, f"cut{suffix}"))
    assert e.message == f"image file 'cut{suffix}' cannot be decoded: a truncated {kind}: it " \
                        f"does not end with {end}"
    (tmp_path / f"padded{suffix}").write_bytes(whole + b"\0" * 100)   # zero padding is fine
    S.load(map_scene(tmp_path, f"padded{suffix}"))
    S.load(map_scene(tmp_path, f"whole{suffix}"))


def test_a_hand_made_jpeg_header_is_walked_to_its_frame(tmp_path):
    (tmp_path / "deep.jpg").write_bytes(jpeg_header(64, 32, precision=12))
    e = refused_at_its_file_string(map_scene(tmp_path, "deep.jpg"))
    assert e.message == "image file 'deep.jpg': a 12-bit JPEG; image maps are 8-bit PNG or JPEG"
    (tmp_path / "none.jpg").write_bytes(b"\xff\xd8\xff\xe0\x00\x10JFIF")   # ends in APP0
    assert "truncated JPEG" in refused_at_its_file_string(map_scene(tmp_path, "none.jpg")).message


def test_the_reference_refuses_a_truncated_map_in_the_parser_s_words(tmp_path):
    from mimarble import reference
    whole = real_image(tmp_path / "whole.jpg").read_bytes()
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(whole[:len(whole) // 2])
    with pytest.raises(SceneError) as info:
        reference.render(python_scene(cut))
    assert info.value.message == f"image file '{cut}' cannot be decoded: a truncated JPEG: " \
                                 f"it does not end with its end marker (EOI, FF D9)"


def test_the_mitsuba_path_refuses_a_truncated_map_in_the_parser_s_words(llvm, tmp_path):
    from mimarble.mitsuba.rendering.render import check_images
    whole = real_image(tmp_path / "whole.jpg").read_bytes()
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(whole[:len(whole) // 2])
    with pytest.raises(SceneError) as info:
        mimarble.to_mitsuba(python_scene(cut))
    assert info.value.message == image_file_sentence(str(cut), str(cut))
    check_images(python_scene(tmp_path / "whole.jpg"))          # a whole one decodes


# ---------------------------------------------------------------------------
# 4. Numbers that are zero in single precision

def test_a_scale_that_is_zero_in_single_precision_is_refused_by_the_parser():
    e = refusal(f'material "m" {{ diffuse {{ marble {{ scale 1e-40 }} }} }}')
    assert e.message == "scale must be > 0 in single precision (the renderer's), found 1e-40"
    assert e.column == len('material "m" { diffuse { marble { scale ') + 1
    parse('material "m" { diffuse { marble { scale 2e-38 } } }')        # a normal float32
    parse('material "m" { diffuse { marble { tolerance 1e-40 } } }')    # ≥ 0 either way
    assert "tolerance must be ≥ 0" in refusal(
        'material "m" { diffuse { marble { tolerance -1e-40 } } }').message


def test_the_parameter_table_rounds_to_single_precision_for_every_caller():
    from mimarble.scene.edits import KeyPathError, with_value
    scale = marble_parameters.BY_NAME["scale"]
    with pytest.raises(marble_parameters.ParameterError, match="single precision"):
        scale.check(1e-40)
    with pytest.raises(marble_parameters.ParameterError, match="scale must be > 0"):
        marble_parameters.MarbleParameters.from_properties({"scale": 1e-39})
    scene = S.Scene(materials={"m": S.Material("m", diffuse=S.MarbleChannel())})
    with pytest.raises(KeyPathError, match="^marble.scale: scale must be > 0 in single precision"):
        with_value(scene, "marble.scale", 1e-40)
    assert scale.check(1e30) == 1e30 and scale.check(3e38) == 3e38    # the value kept as given
    assert marble_parameters.single_precision(1e-40) == 0.0
    assert marble_parameters.single_precision(0.1) == float(np.float32(0.1))
    assert marble_parameters.single_precision(1e39) == 1e39            # past float32: itself


def test_the_plugin_refuses_a_scale_that_is_zero_in_single_precision(llvm):
    import mimarble
    with pytest.raises(Exception, match="scale must be > 0 in single precision"):
        mimarble.mi.load_dict({"type": "marble", "scale": 1e-40})


# ---------------------------------------------------------------------------
# 5. Long lines

def test_an_error_on_a_long_line_shows_a_window_with_the_caret_in_place():
    comment = "/* " + "x" * 1_000_000 + " */"
    text = f"{comment} camera {{ eyes < 1 2 3 > }}"
    e = quickly(lambda: refusal(text))
    head, shown, caret = str(e).split("\n")
    assert head == f"h.scene:1:{len(comment) + 11}: unknown keyword 'eyes' in 'camera' block; " \
                   f"allowed: 'eye', 'lookat', 'up' or 'fov'"
    assert len(shown) <= SHOWN_WIDTH + 6 and shown.startswith("...x")
    assert shown[len(caret) - 1:].startswith("eyes") and caret.strip() == "^"
    # The start of a long line: cut at its end only.
    e = refusal("camera { eyes < 1 2 3 > } " + comment)
    shown, caret = str(e).split("\n")[1:]
    assert shown.endswith("x...") and len(shown) == SHOWN_WIDTH + 3 and len(caret) == 10


def test_a_4_mb_word_is_not_echoed():
    e = quickly(lambda: refusal("x" * 4_000_000))
    assert len(str(e)) < 1000 and e.message.startswith("unknown statement 'xxx")
    names = "".join(f'material "m{k}" {{ }}\n' for k in range(50))
    e = refusal(names + 'sphere { material "' + "n" * 100_000 + '" }')
    assert len(e.message) < 1000 and e.message.endswith('"m9" and 40 more)')


# ---------------------------------------------------------------------------
# 6. The model's constructors check what the parser checks, in the same words

SAME_SENTENCE = [
    ("camera { fov 200 }", lambda: S.Camera(fov=200), "fov must be in (0, 180) degrees, found 200"),
    ("camera { fov 0 }", lambda: S.Camera(fov=0), "fov must be in (0, 180) degrees, found 0"),
    ("camera { eye < 1 2 3 > lookat < 1 2 3 > }", lambda: S.Camera(eye=(1, 2, 3), lookat=(1, 2, 3)),
     "camera eye and lookat must be different points"),
    ("camera { up < 0 0 2 > }", lambda: S.Camera(up=(0, 0, 2)),
     "camera 'up' must not be zero or parallel to the view direction (lookat - eye)"),
    ("camera { up < 0 0 0 > }", lambda: S.Camera(up=(0, 0, 0)),
     "camera 'up' must not be zero or parallel to the view direction (lookat - eye)"),
    ('sphere { radius -1 material "m" }\n' + GOOD_MATERIAL, lambda: S.Sphere("m", radius=-1),
     "radius must be > 0, found -1"),
    ("image { width 30000 }", lambda: S.Image(width=30000), "width must be in 1..16384, found 30000"),
    ("image { height 0 }", lambda: S.Image(height=0), "height must be in 1..16384, found 0"),
    ("image { width 2.5 }", lambda: S.Image(width=2.5), "width must be an integer, found 2.5"),
    ("image { samples 0 }", lambda: S.Image(samples=0), "samples must be in 1..268435456, found 0"),
    ("image { width 16384 height 16384 samples 2 }", lambda: S.Image(16384, 16384, 2),
     "image too large: width*height*samples = 536870912 exceeds 2^28 = 268435456"),
    ("image { background < 0 -1 0 > }", lambda: S.Image(background=(0, -1, 0)),
     "background: colour components must be >= 0, found -1"),
    ("light { position < 1 2 3 > color < -1 0 0 > }", lambda: S.Light((1, 2, 3), (-1, 0, 0)),
     "light color: colour components must be >= 0, found -1"),
    ("light { position < 1 2 > }", lambda: S.Light((1, 2)), "position needs 3 numbers, found 2"),
    ("ambient < 1 2 >", lambda: S.Scene(ambient=(1, 2)),
     "ambient (a colour < r g b >) needs 3 numbers, found 2"),
    ('material "m" { shininess 0 }', lambda: S.Material("m", shininess=0),
     "shininess must be > 0, found 0"),
    ('material "" { }', lambda: S.Material(""), "a material name must not be empty"),
    ('sphere { material "nope" }\n' + GOOD_MATERIAL,
     lambda: S.Scene(materials={"m": S.Material("m")}, spheres=(S.Sphere("nope"),)),
     'unknown material "nope" (defined: "m")'),
]


@pytest.mark.parametrize("text, build, sentence", SAME_SENTENCE)
def test_the_model_refuses_what_the_parser_refuses_in_the_same_words(text, build, sentence):
    assert refusal(text).message == sentence
    with pytest.raises(ValueError) as info:
        build()
    assert str(info.value) == sentence


@pytest.mark.parametrize("build, error, words", [
    (lambda: S.Camera(fov=float("nan")), ValueError, "fov: number nan is not finite"),
    (lambda: S.Camera(eye=(0, 0, float("inf"))), ValueError, "eye: number inf is not finite"),
    (lambda: S.Sphere("m", center=(float("inf"), 0, 0)), ValueError, "center: number inf is not finite"),
    (lambda: S.Sphere("m", radius=float("nan")), ValueError, "radius: number nan is not finite"),
    (lambda: S.Light((float("nan"), 0, 0)), ValueError, "position: number nan is not finite"),
    (lambda: S.Light((1e39, 0, 0)), ValueError,
     "position: number 1e+39 is too large: the renderer is single precision, "
     "|x| <= 3.4028234663852886e+38"),
    (lambda: S.Image(width="big"), TypeError, "width must be an integer, found 'big'"),
    (lambda: S.Image(samples=True), TypeError, "samples must be an integer, found True"),
    (lambda: S.Light(5), TypeError, "position must be 3 numbers, found 5"),
    (lambda: S.Sphere(3), TypeError, "a sphere's material is a material's name, found 3"),
    (lambda: S.Material("m", diffuse=(1, 0, 0)), TypeError,
     'diffuse of material "m" must be a channel or None, found (1, 0, 0)'),
    (lambda: S.Scene(lights=[(1, 2, 3)]), TypeError, "lights must hold Light objects, found (1, 2, 3)"),
    (lambda: S.Scene(image=(8, 8)), TypeError, "image must be an Image, found (8, 8)"),
    (lambda: S.Scene(materials={"a": S.Material("b")}), ValueError,
     'materials: the name "a" holds material "b"'),
])
def test_the_model_refuses_what_the_parser_cannot_be_given(build, error, words):
    with pytest.raises(error) as info:
        build()
    assert str(info.value) == words


def test_a_python_built_scene_of_30000_squared_pixels_is_refused():
    with pytest.raises(ValueError, match="^width must be in 1..16384, found 30000$"):
        S.Scene(image=S.Image(30000, 30000))
    with pytest.raises(ValueError, match="^image too large"):
        dataclasses.replace(S.Image(), width=16384, height=16384, samples=4)


def test_the_model_stores_what_it_was_given_as_the_parser_would():
    camera = S.Camera(eye=[0, 0, 5], up=np.array([0, 1, 0]))
    assert camera.eye == (0.0, 0.0, 5.0) and type(camera.eye) is tuple
    assert all(type(c) is float for c in camera.up + camera.eye)
    assert camera == parse("camera { eye < 0 0 5 > }").camera
    assert S.Image(np.int64(64), 32.0).width == 64 and type(S.Image(64, 32.0).height) is int


def test_odd_but_valid_models_are_still_accepted():
    """What the parser accepts, the constructors accept: extreme geometry and numbers."""
    S.Sphere("g", center=(0, -1e7 - 1, 0), radius=1e7)
    S.Sphere("m", radius=0.004)
    S.Camera(eye=(0, 0, 2e18), lookat=(0, 0, 0), fov=179.9)
    S.Light((3.4e38, 0, 0), (3.4e38, 0, 0))
    S.Image(16384, 16384, 1)
    S.Mix(S.ColorChannel((0, 0, 0)), S.ColorChannel((1, 1, 1)), -1e30)
    assert dataclasses.replace(S.MarbleChannel(), scale=1e-6).scale == 1e-6   # the table's
