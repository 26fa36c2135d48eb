"""The ``./go`` script: its usage, and a set-up that is quiet unless something is wrong."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_help_lists_the_go_commands_then_mimarbles(flag):
    result = subprocess.run(["bash", str(ROOT / "go"), flag], capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stderr
    out = result.stdout
    for words in ("./go test", "./go python", "./go COMMAND", "--jit-debug"):
        assert words in out
    assert out.index("./go test") < out.index("usage: mimarble")   # go's usage, then mimarble's
    commands = out.split("usage: mimarble", 1)[1]
    assert "render" in commands and "scenes" in commands and "gallery" in commands


def test_setup_hides_the_editable_banner_and_no_other_warning(tmp_path):
    """The filter ./go puts on its editable install, on an editable install of a copy."""
    setting = re.search(r'PYTHONWARNINGS="([^"]+)"', (ROOT / "go").read_text()).group(1)
    assert setting == "ignore:Editable installation"      # by message, not a whole category
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, src / name)
    shutil.copytree(ROOT / "mimarble", src / "mimarble", symlinks=True,
                    ignore=shutil.ignore_patterns("__pycache__"))
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True,
                   timeout=300)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PIP_REQUIRE_VIRTUALENV")}
    env["PYTHONWARNINGS"] = setting
    # This environment's pip and setuptools, run by the new venv's interpreter.
    site = subprocess.run([sys.executable, "-c", "import pip, os; "
                           "print(os.path.dirname(os.path.dirname(pip.__file__)))"],
                          capture_output=True, text=True, check=True).stdout.strip()
    env["PYTHONPATH"] = site
    install = [str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "--no-deps",
               "--no-build-isolation", "--no-index", "--ignore-installed", "-e", str(src)]
    unfiltered = dict(env)
    del unfiltered["PYTHONWARNINGS"]
    banner = subprocess.run(install, capture_output=True, text=True, env=unfiltered, timeout=600)
    assert banner.returncode == 0, banner.stderr
    assert "Editable installation" in banner.stdout + banner.stderr   # there to be hidden
    result = subprocess.run(install, capture_output=True, text=True, env=env, timeout=600)
    assert result.returncode == 0, result.stderr
    assert "Editable installation" not in result.stdout + result.stderr
    assert "careful" not in result.stdout + result.stderr
    # Any other word of the build backend still shows: the license file gone.
    (src / "LICENSE").unlink()
    broken = subprocess.run(install, capture_output=True, text=True, env=env, timeout=600)
    assert "LICENSE" in broken.stdout + broken.stderr
