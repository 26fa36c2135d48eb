"""Careless and hostile input to the Python API, the renderers and the files they write
(issue 23): one sentence, no traceback of ours, nothing left half written or outside."""

import os
import re
import subprocess
import sys

import numpy as np
import pytest

import mimarble
from mimarble.runtime import files
from mimarble import scene as S
from mimarble.tools.compare import image_metrics
from mimarble.mitsuba.rendering.render import render_in_passes

dr, mi = mimarble.dr, mimarble.mi
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def tiny(diffuse=S.MarbleChannel(octaves=4), light=(1.0, 1.0, 1.0)):
    return S.Scene(image=S.Image(8, 8), camera=S.Camera(eye=(0, 0, 6)),
                   lights=(S.Light((4, 4, 4), light),),
                   materials={"m": S.Material("m", diffuse=diffuse)}, spheres=(S.Sphere("m"),))


@pytest.mark.parametrize("call, words", [
    (lambda: mimarble.render(123), "123 is not a scene"),
    (lambda: mimarble.render(None), "None is not a scene"),
    (lambda: mimarble.render(tiny(), spp=True), "spp=True must be a whole number"),
    (lambda: mimarble.render(tiny(), spp=2 ** 40), "more than the"),
    (lambda: mimarble.render(tiny(), tolerance="x"), "tolerance='x' must be a finite number"),
    (lambda: mimarble.render(tiny(), mode="paths"), "mode='paths' must be one of"),
])
def test_bad_arguments_are_one_sentence(llvm, call, words):
    with pytest.raises((TypeError, ValueError), match=words):
        call()


def test_an_infinite_error_has_a_psnr_of_minus_infinity():
    image = np.zeros((2, 2, 3), np.float32)
    infinite = np.full((2, 2, 3), np.inf, np.float32)
    metrics = image_metrics(infinite, image)
    assert metrics["rmse"] == np.inf and metrics["psnr"] == -np.inf


def mimarble_cli(*args):
    return subprocess.run([sys.executable, "-m", "mimarble", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True)


@pytest.fixture
def scene_file(tmp_path):
    path = tmp_path / "s.scene"
    path.write_text('image { width 8 height 8 } camera { eye < 0 0 6 > } '
                    'light { position < 4 4 4 > } material "m" { diffuse { color < 1 0 0 > } } '
                    'sphere { material "m" }')
    return path


def test_an_output_name_too_long_is_a_sentence(scene_file, tmp_path):
    result = mimarble_cli("render", scene_file, "-o", tmp_path / ("x" * 300 + ".png"))
    assert result.returncode == 2 and "File name too long" in result.stderr
    assert "Traceback" not in result.stderr


def test_an_output_that_is_a_symbolic_link_is_refused(scene_file, tmp_path):
    elsewhere = tmp_path / "elsewhere.png"
    elsewhere.write_bytes(b"keep")
    link = tmp_path / "out.png"
    link.symlink_to(elsewhere)
    result = mimarble_cli("render", scene_file, "-o", link)
    assert result.returncode == 2 and "symbolic link" in result.stderr
    assert link.is_symlink() and elsewhere.read_bytes() == b"keep"


def test_temporary_files_of_killed_writers_are_removed(tmp_path):
    finished = subprocess.Popen([sys.executable, "-c", "pass"])
    finished.wait()                                   # its pid runs no more
    stale = tmp_path / f".image.mimarble-{finished.pid}-x1y2.png"
    ours = tmp_path / f".image.mimarble-{os.getpid()}-x1y2.png"
    unrelated = tmp_path / ".image.x1y2.png"
    for path in (stale, ours, unrelated):
        path.write_bytes(b"")
    files.write_atomically(tmp_path / "image.png", lambda tmp: open(tmp, "wb").write(b"png"))
    assert not stale.exists() and ours.exists() and unrelated.exists()
    assert (tmp_path / "image.png").read_bytes() == b"png"


def test_traverse_edits_are_checked_like_properties(variant):
    texture = mi.load_dict({"type": "marble", "octaves": 5})
    params = mi.traverse(texture)
    params["octaves"] = 2.5                            # not truncated to 2: refused
    with pytest.raises(Exception, match="octaves must be an integer in 0..64, found 2.5"):
        params.update()
    assert texture.octaves == 5
    if dr.is_jit_v(mi.Float):                          # a ramp longer than the language's
        params["ramp"] = mi.Color3f(np.full((3, 1000), 0.5, np.float32))
        with pytest.raises(Exception, match="ramp has 1000 colours; it holds 1..256"):
            params.update()
        assert texture.ramp.size == 8


def test_expressions_render_in_the_multithreaded_scalar_variant(variant):
    """Mitsuba's scalar variant shades samples on several threads: the shared evaluations
    of a material are each thread's own."""
    channel = S.Multiply((S.MarbleChannel(octaves=3), S.Add((S.ColorChannel((0.5, 0.2, 0.1)),
                                                             S.MarbleChannel(period=2.0)))))
    image = mimarble.render(tiny(channel), spp=4)
    assert np.isfinite(image).all() and image.max() > 0


def render_operations(octaves, marbles=1):
    channel = S.Multiply(tuple(S.MarbleChannel(octaves=octaves, period=1.0 + k)
                               for k in range(marbles))) if marbles > 1 else \
        S.MarbleChannel(octaves=octaves)
    loaded = mi.load_dict(mimarble.to_mitsuba(tiny(channel), spp=1))
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        render_in_passes(loaded, 1)
        kernels = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    return max(k["operation_count"] for k in kernels)


def test_a_kernel_holds_one_noise_evaluation_per_marble(llvm):
    """The octaves are a loop, not unrolled code: LLVM compiles a long straight-line
    kernel in more than linear time (docs/benchmarks.md, "Compile time")."""
    assert render_operations(8) == render_operations(4)
    one, four, eight = (render_operations(4, n) for n in (1, 4, 8))
    assert abs((eight - four) - 4 * (four - one) / 3) < 0.05 * (eight - four)   # linear


def test_colours_past_one_and_python_built_negative_ones_render_as_the_reference(llvm):
    """The language's colours have no upper bound (Mitsuba's reflectances must be in
    [0, 1] unless unbounded), and a Python-built signed term of an add is taken too."""
    from mimarble import reference
    for diffuse in (S.ColorChannel((2.0, 0.5, 0.0)),
                    S.Add((S.ColorChannel((0.9, 0.9, 0.9)), S.ColorChannel((-0.5, 0.0, 0.0))))):
        scene = tiny(diffuse)
        np.testing.assert_allclose(mimarble.render(scene), reference.render(scene), atol=1e-5)


# ---------------------------------------------------------------------------
# Issue 38: one rule for numbers (NumPy's are the Python numbers they hold); scene names

@pytest.mark.parametrize("numpy_arguments, python_arguments", [
    (dict(spp=np.int64(4)), dict(spp=4)),
    (dict(spp=np.uint8(1), seed=np.int32(7), mode="path"), dict(spp=1, seed=7, mode="path")),
    (dict(width=np.int16(12), height=np.float64(10.0)), dict(width=12, height=10)),
    (dict(tolerance=np.float32(0.25)), dict(tolerance=float(np.float32(0.25)))),
    (dict(edge_spp=np.int64(4)), dict(edge_spp=4)),
    (dict(adaptive=np.float64(0.01), max_spp=np.int64(16)), dict(adaptive=0.01, max_spp=16)),
    (dict(spp=np.array(4)), dict(spp=4)),
])
def test_render_takes_numpy_numbers_as_the_python_numbers_they_hold(llvm, numpy_arguments,
                                                                    python_arguments):
    np.testing.assert_array_equal(mimarble.render(tiny(), **numpy_arguments),
                                  mimarble.render(tiny(), **python_arguments))


def test_the_reference_takes_a_numpy_spp_as_the_python_number(llvm):
    from mimarble import reference
    np.testing.assert_array_equal(reference.render(tiny(), spp=np.int64(4)),
                                  reference.render(tiny(), spp=4))


@pytest.mark.parametrize("arguments, words", [
    (dict(spp=np.bool_(True)), "spp=True must be a whole number"),
    (dict(spp=np.float64(4.0)), "spp=4.0 must be a whole number"),
    (dict(width=np.bool_(True)), "width must be an integer, found True"),
    (dict(seed=np.float32(1.5)), "seed=1.5"),
    (dict(tolerance=np.float64("nan")), "tolerance=nan must be a finite number"),
])
def test_numpy_numbers_a_python_number_would_not_pass_are_refused_alike(llvm, arguments, words):
    with pytest.raises((TypeError, ValueError), match=re.escape(words)):
        mimarble.render(tiny(), **arguments)


@pytest.mark.parametrize("name, words", [
    ("", "'': cannot read scene file: the name is empty"),
    ("a\0b", "'a\\x00b': cannot read scene file: the name holds a NUL character"),
])
def test_an_empty_or_nul_scene_name_is_one_clear_sentence(llvm, tmp_path, name, words):
    from mimarble import reference
    from mimarble.sweeps import run as sweeps
    for call in (mimarble.render, reference.render, S.load,
                 lambda n: sweeps.sweep(n, {"marble.period": [1]}, tmp_path / "out")):
        with pytest.raises(S.SceneError) as caught:
            call(name)
        assert str(caught.value).startswith(words)


def test_the_command_line_says_an_empty_scene_name_in_one_sentence(tmp_path):
    for command in ("render", "reference", "export", "sweep", "bake", "compare"):
        extra = {"sweep": ["--set", "marble.period=1", "-o", "out"],
                 "bake": ["--shape", "sphere_0", "-o", "b.png"]}.get(command, [])
        result = subprocess.run([sys.executable, "-m", "mimarble", command, "", *extra],
                                cwd=tmp_path, capture_output=True, text=True,
                                env=dict(os.environ, PYTHONPATH=ROOT))
        assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
        assert len(result.stderr.strip().splitlines()) == 1
        assert "''" in result.stderr and "empty" in result.stderr
    assert os.listdir(tmp_path) == []
