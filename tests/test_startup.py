"""Start-up (issue 17): the command answers help and mistakes before Dr.Jit and Mitsuba load.

The times themselves are benchmark figures (``mimarble bench``, docs/benchmarks.md);
these tests check the properties that make them: what is imported, and that the
lazy start changes nothing a user of the package or of the command can see.
"""

import os
import subprocess
import sys

import numpy as np
import pytest

import mimarble
from mimarble.runtime import environment

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HEAVY = ("drjit", "mitsuba", "numpy")


def imported_by(*args, module="mimarble"):
    """Run ``python -X importtime -m MODULE ARGS``; the names of the modules it imported."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [ROOT, os.environ.get("PYTHONPATH")])))
    result = subprocess.run([sys.executable, "-X", "importtime", "-m", module, *map(str, args)],
                            cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    names = {line.rsplit("|", 1)[1].strip() for line in result.stderr.splitlines()
             if line.startswith("import time:") and "|" in line}
    return result, names


def heavy(names):
    return sorted(n for n in names if n.split(".")[0] in HEAVY)


def test_help_imports_neither_drjit_nor_mitsuba():
    result, names = imported_by("--help")
    assert result.returncode == 0 and "render" in result.stdout
    assert "mimarble.cli" in names                     # the check sees the imports at all
    assert heavy(names) == []
    # Nor the scene language: its package brings Lark and the cached parser (~40 ms).
    assert {"lark", "mimarble.scene"} & names == set()


def test_a_malformed_scene_is_reported_before_drjit_loads(tmp_path):
    bad = tmp_path / "bad.scene"
    bad.write_text("camera {\n  foo\n")
    result, names = imported_by("render", bad, "-o", tmp_path / "out.png")
    assert result.returncode == 2
    assert f"{bad}:2:3:" in result.stderr
    assert heavy(names) == []
    assert not (tmp_path / "out.png").exists()


def test_a_malformed_scene_imports_only_what_its_answer_needs(tmp_path):
    """Issue 39: the answer's process builds only the render command's options, reads no
    mesh file's header, nor the baker (only `bake`'s options need it), and imports neither
    extra nor importlib's abstract classes (which bring importlib.resources), nor the
    scene model and its builder (text that fails to parse builds no model)."""
    bad = tmp_path / "bad.scene"
    bad.write_text("scene {\n")
    result, names = imported_by("render", bad, "-o", tmp_path / "out.png")
    assert result.returncode == 2 and f"{bad}:1:1:" in result.stderr
    assert {"lark", "mimarble.scene.parser"} <= names             # the check sees them
    unneeded = {"mimarble.meshes.facts", "mimarble.meshes.ply_body", "mimarble.tools.bake",
                "importlib.abc", "importlib.resources",
                "matplotlib", "dask", "distributed", "PIL", "tqdm",
                "mimarble.scene.model", "mimarble.scene.builder"}
    assert names & unneeded == set()


def test_only_the_command_run_gets_its_options():
    """The parser of a malformed scene's run knows every command (``--help`` lists them,
    an unknown one is refused) but only the one it runs has options."""
    from mimarble.cli.arguments import build_parser, command_named
    assert command_named(["--variant", "bake", "render", "x.scene"]) == "render"
    assert command_named(["--help"]) is None and command_named(["nosuch"]) is None
    full, lean = build_parser(), build_parser("render")
    assert lean.format_help() == full.format_help()
    argv = ["render", "x.scene", "--width", "8", "--filter", "prefilter", "-o", "m.png"]
    assert vars(lean.parse_args(argv)) == vars(full.parse_args(argv))
    with pytest.raises(SystemExit):
        lean.parse_args(["bake", "x.scene", "--size", "8"])   # bake has no options here


def test_a_usage_error_is_reported_before_drjit_loads(tmp_path):
    scene = tmp_path / "ok.scene"
    scene.write_text("sphere { material \"m\" }\nmaterial \"m\" { diffuse { color < 1 0 0 > } }\n")
    result, names = imported_by("render", scene, "-o", tmp_path / "no-such-folder" / "x.png")
    assert result.returncode == 2 and "does not exist" in result.stderr
    assert heavy(names) == []


def test_a_render_loads_them(tmp_path):
    scene = tmp_path / "ok.scene"
    scene.write_text("image { width 8 height 8 }\nlight { position < 5 5 5 > }\n"
                     "sphere { material \"m\" }\nmaterial \"m\" { diffuse { color < 1 0 0 > } }\n")
    result, names = imported_by("render", scene, "-o", tmp_path / "x.png")
    assert result.returncode == 0, result.stderr
    assert {"drjit", "mitsuba"} <= names and (tmp_path / "x.png").exists()


def test_importing_the_package_still_registers_the_plugins():
    """``import mimarble`` outside the command: a variant set and ``marble`` usable at once."""
    code = ("import mimarble, mitsuba as mi; "
            "print(mi.variant(), type(mi.load_dict({'type': 'marble'})).__name__)")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [ROOT, os.environ.get("PYTHONPATH")])))
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    variant, plugin = result.stdout.split()
    assert variant.endswith("_rgb") and "Marble" in plugin


@pytest.mark.parametrize("orig_argv, argv0, expected", [
    (["python", "-m", "mimarble", "render"], "-m", True),
    (["python", "-X", "importtime", "-m", "mimarble"], "-m", True),
    (["python", "-mmimarble"], "-m", True),
    (["python", "-m", "mimarble.cli"], "-m", True),
    (["python", "/venv/bin/mimarble", "--help"], "/venv/bin/mimarble", True),
    (["python", "-m", "pytest", "-m", "mimarble"], "-m", False),
    (["python", "-c", "import mimarble", "-m", "mimarble"], "-c", False),
    (["python", "script.py", "mimarble"], "script.py", False),
    (["python"], "", False),
])
def test_the_command_process_is_recognised(monkeypatch, orig_argv, argv0, expected):
    monkeypatch.setattr(sys, "orig_argv", orig_argv, raising=False)
    monkeypatch.setattr(sys, "argv", [argv0])
    assert mimarble._is_the_command_process() is expected


def test_the_package_names_come_from_start():
    """The lazily provided names are the real objects (here the package has started)."""
    assert mimarble.render.__module__ == "mimarble.mitsuba.rendering.render"
    assert mimarble.mi.variant() is not None and mimarble.dr.__name__ == "drjit"
    with pytest.raises(AttributeError):
        mimarble.no_such_name


def test_skipping_mitsubas_ad_integrators_leaves_rendering_whole(tmp_path):
    """In a fresh process: the skip, then a variant; Mitsuba's C++ integrators and
    mimarble's load, the Python AD ones are absent; a second variant brings them back."""
    code = f"""
import sys
sys.path.insert(0, {ROOT!r})
sys.orig_argv = [sys.executable, "-m", "mimarble"]    # as in the command's process
from mimarble.runtime import environment
assert environment.skip_mitsuba_ad_integrators()
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
import mimarble
mimarble.start()
mi.load_dict({{"type": "path"}}); mi.load_dict({{"type": "whitted"}})
try:
    mi.load_dict({{"type": "prb"}})
    print("prb present")
except Exception:
    print("prb absent")
mi.set_variant("llvm_ad_mono")
mi.load_dict({{"type": "prb"}})
print("prb back")
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split("\n")[:2] == ["prb absent", "prb back"]


@pytest.mark.parametrize("argv, prb", [(["bench"], True), (["bench", "--no-targets"], False),
                                       (["render", "x.scene"], False)])
def test_only_the_benchmarks_targets_build_mitsubas_ad_integrators(argv, prb):
    """The targets time an Adam step of notebook 02 through ``prb``: the bench command's
    process has it, other commands' processes skip it (fresh processes)."""
    code = f"""
import sys
sys.path.insert(0, {ROOT!r})
sys.orig_argv = [sys.executable, "-m", "mimarble"]    # as in the command's process
from mimarble.cli import main as cli
args = cli.build_parser().parse_args({argv!r})
args.variant = "llvm_ad_rgb"
cli.start_mitsuba(args)
import mitsuba as mi
try:
    mi.load_dict({{"type": "prb"}})
    print("prb present")
except Exception:
    print("prb absent")
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == ("prb present" if prb else "prb absent")


def test_skipping_is_refused_once_a_variant_is_set():
    assert mimarble.mi.variant() is not None
    assert environment.skip_mitsuba_ad_integrators() is False


def test_the_command_renders_what_the_package_renders(tmp_path):
    scene = tmp_path / "s.scene"
    scene.write_text(open(os.path.join(ROOT, "scenes", "fig11a.scene")).read())
    out = tmp_path / "s.exr"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [ROOT, os.environ.get("PYTHONPATH")])))
    result = subprocess.run([sys.executable, "-m", "mimarble", "render", scene, "-o", out,
                             "--width", "40", "--height", "40", "--spp", "4"], cwd=ROOT, env=env,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    import dataclasses
    model = mimarble.scene.load(scene)
    model = dataclasses.replace(model, image=dataclasses.replace(model.image, width=40, height=40))
    ours = np.array(mimarble.mi.Bitmap(str(out)), dtype=np.float32)[..., :3]
    assert np.array_equal(ours, mimarble.render(model, spp=4))


def test_the_benchmark_times_each_whole_process():
    """``mimarble bench``'s rows: each run checked for its exit status, so a broken
    command cannot pass for a fast one."""
    from mimarble.bench import report as bench_report, targets as bench
    t = bench.process_times(os.path.join(ROOT, "scenes", "fig11a.scene"), repeats=1)
    assert all(t[k] > 0 for k in ("help_s", "malformed_scene_s", "render_warm_s", "render_cold_s"))
    text = "\n".join(bench_report._process_lines(t, {"process_s": 0.8}))
    assert "--help" in text and "malformed" in text and "POV-Ray" in text
    with pytest.raises(RuntimeError, match="exit status 2"):
        bench._process_seconds(["render", "no-such.scene"], 1)
