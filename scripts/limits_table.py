"""docs/scene-language.md's table of limits, written from the records in
mimarble/scene/limits.py (each limit's value and reason is written there only).

    ./go python scripts/limits_table.py          # rewrites the table between its two markers
    ./go python scripts/limits_table.py --check  # exit 1 if the table is not what the records say

tests/test_limits_table.py runs the check, so a limit changed in the code without the docs
following fails the suite. The markers are replaced as scripts/module_map.py replaces its own.
"""

from __future__ import annotations

import sys
from pathlib import Path

from mimarble.scene.limits import markdown_table

sys.path.insert(0, str(Path(__file__).resolve().parent))
from module_map import with_section, write_or_check  # noqa: E402  (a script beside this one)

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs" / "scene-language.md"
BEGIN = "<!-- limits table: written by scripts/limits_table.py from mimarble/scene/limits.py; do not edit -->"
END = "<!-- end of the limits table -->"


def with_table(text: str, table: str) -> str:
    """``text`` with the part between the markers replaced by ``table``."""
    return with_section(text, table, BEGIN, END)


def main(argv) -> int:
    return write_or_check(DOCS, with_table(DOCS.read_text(encoding="utf-8"), markdown_table()), argv,
                          "the limits table")


if __name__ == "__main__":
    sys.exit(main(sys.argv))
