"""The reference tracer is independent of the Mitsuba path: checked on its source, with ast."""

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
REFERENCE = sorted((ROOT / "mimarble" / "reference").glob("*.py"))
FORBIDDEN = ("mitsuba", "drjit", "mimarble.texture", "mimarble.mitsuba",
             "mimarble.runtime.environment", "mimarble.cli")
ALLOWED_THIRD_PARTY = ("numpy", "PIL")   # PIL: image maps decoded by Pillow
ALLOWED_PROJECT = ("mimarble.scene", "mimarble.reference", "mimarble.meshes",
                   "mimarble.runtime.progress", "mimarble.runtime.reading", "mimarble.contract")


def imported_modules(path, package):
    """Every module an import statement in ``path`` names (relative imports resolved;
    ``from X import Y`` also yields ``X.Y``, since Y may be a submodule)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            out.append(mod)
            out += [f"{mod}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", "")) in (
                "__import__", "import_module"):
            out.append("<dynamic import>")
    return out


def _forbidden(mod):
    return mod == "<dynamic import>" or any(mod == f or mod.startswith(f + ".") for f in FORBIDDEN)


def test_reference_package_has_its_modules():
    names = {p.name for p in REFERENCE}
    assert {"__init__.py", "noise.py", "marble.py", "tracer.py"} <= names


@pytest.mark.parametrize("path", REFERENCE, ids=lambda p: p.name)
def test_reference_module_imports_nothing_of_the_mitsuba_path(path):
    mods = imported_modules(path, "mimarble.reference")
    assert mods, "no imports found: the parse is broken"
    bad = [m for m in mods if _forbidden(m)]
    assert not bad, f"{path.name} imports {bad}"


@pytest.mark.parametrize("path", REFERENCE, ids=lambda p: p.name)
def test_reference_module_imports_only_numpy_stdlib_and_scene(path):
    for m in imported_modules(path, "mimarble.reference"):
        if m == "mimarble":          # "from mimarble import X": X is checked as mimarble.X
            continue
        top = m.split(".")[0]
        ok = (top in sys.stdlib_module_names or top in ALLOWED_THIRD_PARTY or top == "__future__"
              or any(m == a or m.startswith(a + ".") for a in ALLOWED_PROJECT))
        assert ok, f"{path.name} imports {m}"


def test_compare_module_has_no_mitsuba_import():
    mods = imported_modules(ROOT / "mimarble" / "tools" / "compare.py", "mimarble.tools")
    assert not [m for m in mods if _forbidden(m)]


def test_checker_catches_forbidden_imports(tmp_path):
    # the checker itself must see through relative and from-imports
    f = tmp_path / "x.py"
    f.write_text("from ..texture import noise\nfrom mimarble import mitsuba\nimport drjit as dr\n")
    mods = imported_modules(f, "mimarble.reference")
    assert {"mimarble.texture.noise", "mimarble.mitsuba", "drjit"} <= set(mods)
    assert all(_forbidden(m) for m in ("mimarble.texture.noise", "mimarble.mitsuba", "drjit"))
