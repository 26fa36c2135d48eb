"""The module map in docs/design-decisions.md names every module of the package, as the code
says it (scripts/module_map.py writes it from the docstrings)."""

import runpy
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MAP = runpy.run_path(str(ROOT / "scripts" / "module_map.py"))


def documented_section() -> str:
    text = MAP["DOCS"].read_text(encoding="utf-8")
    return text.partition(MAP["BEGIN"])[2].partition(MAP["END"])[0]


def test_every_module_of_the_package_is_in_the_map():
    section = documented_section()
    for path in sorted((ROOT / "mimarble").rglob("*.py")):
        if path.name in ("__init__.py", "__main__.py"):
            continue
        package = path.parent.relative_to(ROOT).as_posix()
        assert f"**`{package}/`**" in section, f"package {package}/ is missing from the map"
        assert f"`{path.name}` — " in section, f"{path.relative_to(ROOT)} is missing from the map"


def test_the_map_says_what_the_docstrings_say():
    assert documented_section().strip() == MAP["module_map"]().strip(), (
        "docs/design-decisions.md's module map is stale: ./go python scripts/module_map.py")


def test_a_module_without_its_line_in_the_map_is_found(tmp_path):
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text('"""The package."""\n')
    (package / "sub" / "__init__.py").write_text('"""A subpackage."""\n')
    (package / "sub" / "thing.py").write_text('"""A thing.\n\nMore."""\n')
    the_map = MAP["module_map"](package)
    assert "- **`pkg/`** — The package." in the_map
    assert "- **`pkg/sub/`** — A subpackage." in the_map
    assert "  - `thing.py` — A thing." in the_map
    (package / "sub" / "other.py").write_text('"""Another."""\n')
    assert MAP["module_map"](package) != the_map
