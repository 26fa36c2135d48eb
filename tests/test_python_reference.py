"""docs/python.md (issue 42, items 5 and 7): its plugin tables are written from the code, and
every example on the page runs."""

import os
import re
import runpy
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "python.md"
SCRIPT = runpy.run_path(str(ROOT / "scripts" / "python_reference.py"))

#: Runs each block it is given, in order, each in a fresh namespace, and says which failed.
RUNNER = r"""
import sys, traceback
blocks = sys.argv[1].split("\n#----- next block -----\n")
for k, block in enumerate(blocks):
    try:
        exec(compile(block, f"docs/python.md block {k + 1}", "exec"), {"__name__": "__main__"})
    except BaseException:
        traceback.print_exc()
        print(f"BLOCK {k + 1} FAILED", file=sys.stderr)
        sys.exit(1)
print(f"{len(blocks)} blocks ran")
"""


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```$", text, re.S | re.M)


def test_the_plugin_tables_are_written_from_the_code():
    assert SCRIPT["main"](["python_reference.py", "--check"]) == 0, \
        "docs/python.md's plugin tables are stale: ./go python scripts/python_reference.py"


def test_the_marble_table_has_every_row_of_the_parameter_table():
    from mimarble.parameters import PARAMETERS
    table = SCRIPT["marble_table"]()
    keys = re.findall(r"^\| `(\w+)` \|", table, re.M)
    assert keys == [p.name for p in PARAMETERS] + ["to_world", "preset"]


def test_the_page_covers_what_the_issue_asks():
    text = PAGE.read_text(encoding="utf-8")
    for plugin in ("marble", "channel_expression", "channel_material", "whitted",
                   "stratified_area", "marble_medium", "subsurface_boundary",
                   "subsurface_preview", "roulette_isotropic"):
        assert f"### `{plugin}`" in text, plugin
    for words in ("fov_axis", "Color3f", "TensorXf", "dr.freeze", "heterogeneous",
                  "ramp_positions", "#rrggbb"):
        assert words in text, words


def test_every_example_on_the_page_runs(tmp_path):
    blocks = python_blocks(PAGE.read_text(encoding="utf-8"))
    assert len(blocks) >= 8
    env = dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb",
               PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    result = subprocess.run([sys.executable, "-c", RUNNER,
                             "\n#----- next block -----\n".join(blocks)],
                            cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    sys.stderr.write(result.stderr)
    assert result.returncode == 0, result.stderr[-3000:]
    assert f"{len(blocks)} blocks ran" in result.stdout
    assert (tmp_path / "carrara.png").is_file()
