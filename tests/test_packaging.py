"""A built wheel, installed into a fresh environment with no checkout at hand, renders the
paper's scenes by name and lists them: what a plain ``pip install .`` gives a user.

The wheel is built from a copy of the sources (not in the checkout, whose build/ folder
could hold stale files), with this environment's setuptools (no download); it is installed
with ``--no-deps`` into a venv that sees this environment's site-packages through a
``.pth`` file (Mitsuba, Dr.Jit, NumPy… not downloaded again). Such a path is appended
after the venv's own site-packages, and the editable install's finder there is not run
(only a site folder's .pth files are), so ``import mimarble`` is the wheel's.
"""

import os
import shutil
import site
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(venv folder, wheel path): the wheel built and installed once for this module."""
    base = tmp_path_factory.mktemp("wheel")
    src = base / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, src / name)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(ROOT / "mimarble", src / "mimarble", symlinks=True, ignore=ignore)
    shutil.copytree(ROOT / "scenes", src / "scenes", ignore=ignore)   # where mimarble/scenes points
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps",
                            "--no-build-isolation", "--no-index", "-w", str(base / "dist"),
                            str(src)], capture_output=True, text=True, env=env, timeout=600)
    assert built.returncode == 0, built.stderr
    (wheel,) = (base / "dist").glob("mimarble-*.whl")
    venv = base / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True,
                   timeout=300)
    python = venv / "bin" / "python"
    purelib = subprocess.run([str(python), "-c", "import sysconfig; "
                              "print(sysconfig.get_paths()['purelib'])"], capture_output=True,
                             text=True, check=True, env=env).stdout.strip()
    ours = [p for p in site.getsitepackages() if os.path.isdir(p)]
    Path(purelib, "zz-test-dependencies.pth").write_text("\n".join(ours) + "\n")
    installed = subprocess.run([str(python), "-m", "pip", "install", "-q", "--no-deps",
                                "--no-index", "--ignore-installed", str(wheel)],
                               capture_output=True, text=True, env=env, timeout=600)
    assert installed.returncode == 0, installed.stderr
    return venv, wheel


def run_in(folder, venv, *args):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "MIMARBLE_VARIANT")}
    result = subprocess.run([str(venv / "bin" / args[0]), *map(str, args[1:])], cwd=folder,
                            env=env, capture_output=True, text=True, timeout=600)
    sys.stderr.write(result.stderr)   # where the conftest check sees Dr.Jit's bounds reports
    return result


def test_the_wheel_holds_the_scenes_their_image_maps_and_the_license(installed):
    _, wheel = installed
    names = zipfile.ZipFile(wheel).namelist()
    for scene in (ROOT / "scenes").rglob("*"):
        if scene.is_file():
            assert "mimarble/scenes/" + scene.relative_to(ROOT / "scenes").as_posix() in names
    assert "mimarble/scene/scene.lark" in names
    assert "mimarble/presets.toml" in names          # the marble library
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    metadata = zipfile.ZipFile(wheel).read(
        next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    assert "License-Expression: BSD-3-Clause" in metadata


def test_an_installed_wheel_lists_and_renders_packaged_scenes_from_an_empty_folder(
        installed, tmp_path):
    venv, _ = installed
    where = run_in(tmp_path, venv, "python", "-c", "import mimarble; print(mimarble.__file__)")
    assert where.returncode == 0, where.stderr
    assert Path(where.stdout.strip()).is_relative_to(venv)      # the wheel's, not the checkout's

    listed = run_in(tmp_path, venv, "mimarble", "scenes")
    assert listed.returncode == 0, listed.stderr
    assert "fig11a" in listed.stdout and "veins-over-image" in listed.stdout
    assert str(venv) in listed.stdout.splitlines()[0]

    rendered = run_in(tmp_path, venv, "mimarble", "render", "fig11a", "--width", "32",
                      "--height", "32", "-o", "m.png")
    assert rendered.returncode == 0, rendered.stderr
    assert (tmp_path / "m.png").stat().st_size > 0

    mapped = run_in(tmp_path, venv, "mimarble", "render", "veins-over-image", "--width", "16",
                    "--height", "16", "--spp", "1")             # its image map is shipped too
    assert mapped.returncode == 0, mapped.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.png", "veins-over-image.png"]


def test_the_package_the_citation_and_the_changelog_state_one_version():
    import re

    import mimarble
    version = re.search(r'^version = "([^"]+)"$', (ROOT / "pyproject.toml").read_text(),
                        re.M).group(1)
    assert mimarble.__version__ == version
    assert re.search(r"^version: (\S+)$", (ROOT / "CITATION.cff").read_text(), re.M).group(1) == version
    assert f"## {version}" in (ROOT / "CHANGELOG.md").read_text()
