"""docs/design-decisions.md's module map, written from the code: every package and module of
mimarble with the first paragraph of its docstring.

    ./go python scripts/module_map.py          # rewrites the map between its two markers
    ./go python scripts/module_map.py --check  # exit 1 if the map is not what the code says

tests/test_module_map.py runs the check, so a module added, moved or removed without the
map following fails the suite. Nothing is imported: docstrings are read with ``ast``.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs" / "design-decisions.md"
BEGIN = "<!-- module map: written by scripts/module_map.py from the docstrings; do not edit -->"
END = "<!-- end of the module map -->"


def first_line(path: Path) -> str:
    """The first paragraph of a module's docstring on one line ('' when it has none)."""
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    return " ".join(doc.strip().split("\n\n")[0].split())


def module_map(package_dir: Path = ROOT / "mimarble") -> str:
    """The map as Markdown: one bullet per package, one sub-bullet per module."""
    lines = []
    packages = sorted({p.parent for p in package_dir.rglob("__init__.py")},
                      key=lambda p: p.relative_to(package_dir.parent).parts)
    for package in packages:
        name = package.relative_to(package_dir.parent).as_posix()
        lines.append(f"- **`{name}/`** — {first_line(package / '__init__.py')}")
        for module in sorted(package.glob("*.py")):
            if module.name in ("__init__.py", "__main__.py"):
                continue
            lines.append(f"  - `{module.name}` — {first_line(module)}")
    return "\n".join(lines)


def with_map(text: str, the_map: str) -> str:
    """``text`` with the part between the markers replaced by ``the_map``."""
    head, sep, rest = text.partition(BEGIN)
    if not sep or END not in rest:
        raise SystemExit(f"{DOCS}: the module map's markers are missing")
    tail = rest.partition(END)[2]
    return f"{head}{BEGIN}\n{the_map}\n{END}{tail}"


def main(argv) -> int:
    text = DOCS.read_text(encoding="utf-8")
    new = with_map(text, module_map())
    if "--check" in argv[1:]:
        if new != text:
            print(f"{DOCS.relative_to(ROOT)}: the module map is stale; "
                  "run ./go python scripts/module_map.py", file=sys.stderr)
            return 1
        return 0
    DOCS.write_text(new, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
