"""docs/scene-language.md's table of limits, written from the records in
mimarble/scene/limits.py (each limit's value and reason is written there only).

    ./go python scripts/limits_table.py          # rewrites the table between its two markers
    ./go python scripts/limits_table.py --check  # exit 1 if the table is not what the records say

tests/test_limits_table.py runs the check, so a limit changed in the code without the docs
following fails the suite.
"""

from __future__ import annotations

import sys
from pathlib import Path

from mimarble.scene.limits import markdown_table

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs" / "scene-language.md"
BEGIN = "<!-- limits table: written by scripts/limits_table.py from mimarble/scene/limits.py; do not edit -->"
END = "<!-- end of the limits table -->"


def with_table(text: str, table: str) -> str:
    """``text`` with the part between the markers replaced by ``table``."""
    head, sep, rest = text.partition(BEGIN)
    if not sep or END not in rest:
        raise SystemExit(f"{DOCS}: the limits table's markers are missing")
    tail = rest.partition(END)[2]
    return f"{head}{BEGIN}\n{table}\n{END}{tail}"


def main(argv) -> int:
    text = DOCS.read_text(encoding="utf-8")
    new = with_table(text, markdown_table())
    if "--check" in argv[1:]:
        if new != text:
            print(f"{DOCS.relative_to(ROOT)}: the limits table is stale; "
                  "run ./go python scripts/limits_table.py", file=sys.stderr)
            return 1
        return 0
    DOCS.write_text(new, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
