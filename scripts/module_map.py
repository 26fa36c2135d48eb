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


def with_section(text: str, body: str, begin: str, end: str) -> str:
    """``text`` with the part between the markers ``begin`` and ``end`` replaced by ``body``."""
    head, sep, rest = text.partition(begin)
    if not sep or end not in rest:
        raise SystemExit(f"the markers {begin!r} and {end!r} are missing")
    tail = rest.partition(end)[2]
    return f"{head}{begin}\n{body}\n{end}{tail}"


def with_map(text: str, the_map: str) -> str:
    """``text`` with the part between the module map's markers replaced by ``the_map``."""
    return with_section(text, the_map, BEGIN, END)


def write_or_check(docs: Path, new: str, argv, what: str) -> int:
    """Write ``new`` to ``docs``; with ``--check`` in ``argv``, exit status 1 if it differs."""
    if "--check" in argv[1:]:
        if new != docs.read_text(encoding="utf-8"):
            print(f"{docs.relative_to(ROOT)}: {what} is stale; run ./go python {argv[0]}", file=sys.stderr)
            return 1
        return 0
    docs.write_text(new, encoding="utf-8")
    return 0


def main(argv) -> int:
    return write_or_check(DOCS, with_map(DOCS.read_text(encoding="utf-8"), module_map()), argv,
                          "the module map")


if __name__ == "__main__":
    sys.exit(main(sys.argv))
