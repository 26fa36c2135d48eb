"""docs/python.md's plugin tables, written from where each plugin's parameters are declared.

    ./go python scripts/python_reference.py          # rewrites the tables between their markers
    ./go python scripts/python_reference.py --check  # exit 1 if they are not what the sources say

The ``marble`` texture's table is written from the parameter table (mimarble/parameters.py:
name, kind, default, role, rule); every other plugin's from the ``.. list-table::`` of its
module's docstring (mimarble/mitsuba/plugins/*.py, read with ``ast``: nothing is imported).
tests/test_python_reference.py runs the check, so a parameter changed in the code without
the page following fails the suite.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from module_map import with_section, write_or_check  # noqa: E402  (a script beside this one)

from mimarble.parameters import COLOURS, POSITIONS, PARAMETERS  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs" / "python.md"
PLUGINS = ROOT / "mimarble" / "mitsuba" / "plugins"
BEGIN = "<!-- plugin tables: written by scripts/python_reference.py; do not edit -->"
END = "<!-- end of the plugin tables -->"
#: The plugins in the page's order: (Mitsuba type name, kind, module file).
ORDER = (("marble", "texture", None),
         ("channel_expression", "texture", "channel_expression.py"),
         ("channel_material", "bsdf", "material.py"),
         ("whitted", "integrator", "whitted.py"),
         ("stratified_area", "emitter", "area_light.py"),
         ("marble_medium", "medium", "marble_medium.py"),
         ("subsurface_boundary", "bsdf", "subsurface_boundary.py"),
         ("subsurface_preview", "bsdf", "subsurface_preview.py"),
         ("roulette_isotropic", "phase", "roulette_phase.py"))


def markdown_inline(text: str) -> str:
    """reStructuredText's inline forms in Markdown: ````x```` → `x`, ``:func:`~a.b``` → `b`,
    ``:math:`x``` → x; pipes escaped (a table cell)."""
    text = re.sub(r":\w+:`~?([^`]*?)`", lambda m: "`" + m.group(1).rsplit(".", 1)[-1] + "`"
                  if m.group(0).startswith((":func", ":class", ":meth", ":mod", ":data"))
                  else m.group(1), text)
    text = text.replace("``", "`")
    return text.replace("|", "\\|")


def list_table_rows(doc: str) -> list[list[str]]:
    """The rows of the first ``.. list-table::`` in ``doc`` (header first), each a list of
    cells, each cell's lines joined by spaces."""
    lines = doc.split(".. list-table::", 1)[1].splitlines()[1:]
    rows: list[list[str]] = []
    for line in lines:
        stripped = line.strip()
        if not stripped or stripped.startswith(":"):
            if rows and not stripped:       # a blank line inside the table ends nothing
                continue
            continue
        if not line.startswith("   "):      # back at the docstring's margin: the table ended
            break
        if stripped.startswith("* - "):
            rows.append([stripped[4:]])
        elif stripped.startswith("- "):
            rows[-1].append(stripped[2:])
        else:
            rows[-1][-1] += " " + stripped
    return rows


def plugin_table(file: str) -> str:
    """A plugin's parameter table, from its module docstring's list-table."""
    doc = ast.get_docstring(ast.parse((PLUGINS / file).read_text(encoding="utf-8")))
    if ".. list-table::" not in doc:
        return "No parameters.\n"
    header, *rows = list_table_rows(doc)
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(markdown_inline(c) for c in row) + " |" for row in rows]
    return "\n".join(out) + "\n"


def marble_table() -> str:
    """The marble texture's table, one row a row of the parameter table, then the keys the
    plugin reads itself (``to_world``, ``preset``)."""
    out = ["| key | type (default) | in `mi.traverse` | value |", "|---|---|---|---|"]
    for p in PARAMETERS:
        default = "the Fig. 5 ramp" if p.kind == COLOURS else \
            "evenly spaced" if p.kind == POSITIONS else \
            str(p.default).lower() if isinstance(p.default, bool) else \
            f"{p.default:g}" if isinstance(p.default, float) else \
            "the scene's" if p.default is None else str(p.default)
        kind = "string" if p.kind in (COLOURS, POSITIONS, "choice") else \
            "int" if p.kind == "integer" else "bool" if p.kind == "boolean" else "float"
        traversed = "differentiable" if p.in_place else "yes (not differentiable)" \
            if p.traversed else "no (structural)"
        requirement = p.requirement[0].upper() + p.requirement[1:]
        out.append(f"| `{p.name}` | {kind} ({default}) | {traversed} | "
                   f"{markdown_inline(requirement)}. |")
    out.append("| `to_world` | transform (identity) | yes | Places the pattern: the marble is "
               "evaluated at to_world⁻¹ · p. |")
    out.append("| `preset` | string (none) | no | A preset of the marble library "
               "([presets.md](presets.md)); its values replace the defaults, the keys "
               "given override them. |")
    return "\n".join(out) + "\n"


def tables() -> str:
    """Every plugin's section: a heading, its kind, its table."""
    parts = []
    for name, kind, file in ORDER:
        table = marble_table() if file is None else plugin_table(file)
        parts.append(f"### `{name}` ({kind})\n\n{table}")
    return "\n".join(parts)


def main(argv) -> int:
    new = with_section(DOCS.read_text(encoding="utf-8"), tables(), BEGIN, END)
    return write_or_check(DOCS, new, argv, "the plugin tables")


if __name__ == "__main__":
    sys.exit(main(sys.argv))
