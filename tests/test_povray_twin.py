"""docs/coming-from-povray.md's twin and word table, without POV-Ray.

The twin scene parses; scripts/povray_twin.py renders the .pov file under
docs/examples/povray-twin/ (the one the doc shows); each POV-Ray word the doc's table marks
"refused: hint `K`" has its line in POVRAY_HINTS, and each "refused, no hint" word has none
(so a new hint gets the table updated).
"""

import importlib.util
import re
from pathlib import Path

from mimarble import scene
from mimarble.scene.syntax_errors import POVRAY_HINTS

ROOT = Path(__file__).resolve().parent.parent
FOLDER = ROOT / "docs" / "examples" / "povray-twin"
DOC = ROOT / "docs" / "coming-from-povray.md"


def _script():
    spec = importlib.util.spec_from_file_location("povray_twin", ROOT / "scripts" / "povray_twin.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _table_rows():
    """(POV-Ray cell, here cell, last cell) of each row of the doc's word table."""
    text = DOC.read_text()
    table = text[text.index("| POV-Ray | here | written as in POV-Ray |"):]
    rows = []
    for line in table.splitlines()[2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
        rows.append(cells)
    return rows


def test_twin_scene_parses():
    model = scene.parse((FOLDER / "marble.scene").read_text())
    assert (model.image.width, model.image.height) == (320, 240)
    assert model.camera.eye == (0.0, 0.0, 9.0)          # POV-Ray's <0, 0, -9>, z negated
    marble = model.materials["marble"].ambient
    assert marble.function == "triangle" and marble.ramp_positions == (0.0, 0.6, 0.85, 1.0)


def test_script_renders_the_pov_file_in_docs():
    twin = _script()
    assert twin.POV_FILE == FOLDER / "marble.pov" and twin.POV_FILE.is_file()
    assert twin.TWIN_FILE == FOLDER / "marble.scene"
    command = twin.povray_command(twin.POV_FILE, Path("out.png"))
    assert command[0] == "povray" and command[-1] == str(FOLDER / "marble.pov")
    assert "-A" in command and "+W320" in command and "+H240" in command
    assert twin.BACKGROUND in twin.POV_FILE.read_text()   # the silhouette's second render


def test_every_refused_word_has_its_hint():
    rows = _table_rows()
    assert len(rows) > 20
    hinted, unhinted = [], []
    for pov, _, written in rows:
        if written.startswith("refused: hint"):
            hinted += re.findall(r"`([^`]+)`", written.split("(")[0])
        elif written.startswith("refused, no hint"):
            unhinted += re.findall(r"`([^`]+)`", pov)
    assert hinted and unhinted
    assert [k for k in hinted if k not in POVRAY_HINTS] == []
    assert [w for w in unhinted if w.split()[0] in POVRAY_HINTS] == []
