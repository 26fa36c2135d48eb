"""docs/scene-language.md's table of limits is generated from mimarble/scene/limits.py's
records (scripts/limits_table.py), so each limit's value and reason is written once."""

import runpy
from pathlib import Path

from mimarble.scene import limits

ROOT = Path(__file__).resolve().parent.parent
TABLE = runpy.run_path(str(ROOT / "scripts" / "limits_table.py"))


def documented_table() -> str:
    text = TABLE["DOCS"].read_text(encoding="utf-8")
    return text.partition(TABLE["BEGIN"])[2].partition(TABLE["END"])[0]


def test_the_docs_limits_table_is_generated_from_the_records():
    assert documented_table().strip() == limits.markdown_table(), (
        "docs/scene-language.md's limits table is stale: ./go python scripts/limits_table.py")


def test_every_limit_by_name_has_its_record_or_its_table():
    """Each key of LIMITS is documented: by its record, or (the image's size, the marble's
    own) by the table that holds it."""
    table_owned = {"image_size", "octaves", "ramp_colours"}
    assert set(limits.LIMITS) - table_owned == set(limits.BY_KEY)
    for key, record in limits.BY_KEY.items():
        assert limits.LIMITS[key] == record.value, key


def test_the_image_keys_table_shows_the_image_size():
    low, high = limits.IMAGE_SIZE
    docs = TABLE["DOCS"].read_text(encoding="utf-8")
    for key in ("width", "height"):
        assert f"| `{key}` | int | 500 | {low}..{high} |" in docs, key


def test_a_changed_record_changes_the_table():
    record = limits.RECORDS[0]
    changed = limits.Limit(record.key, record.what, record.value, "5 MiB", record.reason)
    assert changed.markdown_row() != record.markdown_row()
    assert TABLE["with_table"](f"a\n{TABLE['BEGIN']}\nold\n{TABLE['END']}\nb", "new") == \
        f"a\n{TABLE['BEGIN']}\nnew\n{TABLE['END']}\nb"
