"""Modules that moved in the second layout still import by their old names, for one release:
the same module object, with a DeprecationWarning naming the new place."""

import importlib
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from mimarble.runtime.moved import KEPT, MOVED

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("old", sorted(MOVED))
def test_an_old_name_imports_the_module_at_its_new_place(old):
    new = MOVED[old]
    assert (ROOT / (new.replace(".", "/") + ".py")).is_file() or \
        (ROOT / new.replace(".", "/") / "__init__.py").is_file(), f"{new} does not exist"
    assert not (ROOT / (old.replace(".", "/") + ".py")).exists(), f"{old} was not moved"
    assert importlib.import_module(old) is importlib.import_module(new)


def test_the_old_name_warns_once_with_the_new_path():
    code = ("import warnings, mimarble\n"
            "warnings.simplefilter('error', DeprecationWarning)\n"
            "try:\n"
            "    import mimarble.marble_parameters\n"
            "except DeprecationWarning as w:\n"
            "    print(w)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, timeout=120)
    assert out.stdout.strip() == ("mimarble.marble_parameters moved to mimarble.parameters; "
                                  "the old name goes in the next release"), out.stderr


@pytest.mark.parametrize("old", sorted(KEPT))
def test_names_of_the_public_interface_import_without_a_warning(old):
    code = ("import warnings, mimarble\n"
            "warnings.simplefilter('error', DeprecationWarning)\n"
            f"import {old}\n"
            f"print({old}.__name__)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == MOVED[old]


def test_a_monkeypatch_through_the_old_name_reaches_the_new_module(monkeypatch):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        old = importlib.import_module("mimarble.scene_edits")
    new = importlib.import_module("mimarble.scene.edits")
    monkeypatch.setattr(old, "_probe_attribute", 1, raising=False)
    assert new._probe_attribute == 1
