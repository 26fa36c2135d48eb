"""The sweep's contact sheet layout (issue 42, item 6): the frames fill their cells, each
cell's values are one line under it, and the cells are the frames' shape."""

import numpy as np
import pytest
from PIL import Image

from mimarble.sweeps import contact_sheet as cs


def frames(folder, count, size=(40, 30)):
    """``count`` solid frames of ``size``, each its own colour; (paths, colours)."""
    paths, colours = [], []
    for k in range(count):
        colour = (20 + 20 * k, 90, 230 - 20 * k)
        path = folder / f"f{k}.png"
        Image.new("RGB", size, colour).save(path)
        paths.append(path)
        colours.append(colour)
    return paths, colours


SETTINGS3 = [{"key": "marble.period", "values": [0, 1, 2, 3, 4, 5]},
             {"key": "marble.distortion", "values": [2.5]},
             {"key": "marble.octaves", "values": [8]}]


def draw(tmp_path, settings, values, paths, size=(40, 30), cell=160):
    out = tmp_path / "contact.png"
    bad = cs.draw_contact_sheet(out, "x.scene: a title", settings, list(zip(values, paths)),
                                cell=cell, size=size)
    assert bad == {}
    return np.asarray(Image.open(out).convert("RGB"))


def test_small_frames_fill_their_cells(tmp_path):
    """40×30 frames in 160-pixel cells: each cell is 160×120, every pixel of it the frame's
    colour (scaled up, not a 40×30 stamp in a corner)."""
    paths, colours = frames(tmp_path, 6)
    values = [{"marble.period": k, "marble.distortion": 2.5, "marble.octaves": 8} for k in range(6)]
    sheet = draw(tmp_path, SETTINGS3, values, paths)
    layout = cs.sheet_layout(SETTINGS3, 6, 160, 40 / 30)
    assert sheet.shape[:2] == layout.size[::-1]
    for (x, y, w, h), colour in zip(layout.cells, colours):
        assert (w, h) == (160, 120)
        assert (sheet[y:y + h, x:x + w] == colour).all()


def test_each_cells_values_are_one_line_under_it(tmp_path):
    """Three settings: one line a cell (shortened to the cell's width), right under it;
    nothing drawn in the gaps between cells, nor in a second line."""
    paths, _ = frames(tmp_path, 6)
    values = [{"marble.period": k, "marble.distortion": 2.5, "marble.octaves": 8} for k in range(6)]
    sheet = draw(tmp_path, SETTINGS3, values, paths)
    layout = cs.sheet_layout(SETTINGS3, 6, 160, 40 / 30)
    white = np.array([255, 255, 255])
    for (x, y, w, h), (lx, ly, lw) in zip(layout.cells, layout.labels):
        assert (lx, ly, lw) == (x, y + h, w)
        band = sheet[ly:ly + cs.LINE, lx:lx + lw]
        assert (band != white).any(axis=2).sum() > 30              # the text is there
        gap = sheet[ly:ly + cs.LINE, lx + lw:lx + lw + cs.GAP]      # and stays in its cell
        assert (gap == white).all()
        below = sheet[ly + cs.LINE:ly + cs.LINE + cs.GAP, lx:lx + lw]
        assert (below == white).all()                              # one line only


def test_the_cells_are_most_of_the_sheet():
    """Gutters and labels take little: the cells are ≥ 75 % of a 3×3 sweep's sheet and of a
    row of 9, at the usual 160-pixel cells."""
    two = [{"key": "marble.period", "values": [1, 2, 3]},
           {"key": "marble.distortion", "values": [1, 2, 3]}]
    one = [{"key": "marble.period", "values": list(range(9))}]
    for settings, left in ((two, 60), (one, 0)):
        layout = cs.sheet_layout(settings, 9, 160, 1.0, left)
        cells = sum(w * h for _, _, w, h in layout.cells)
        assert cells / (layout.size[0] * layout.size[1]) >= 0.75, settings


def test_cells_do_not_overlap_and_are_the_frames_shape():
    layout = cs.sheet_layout([{"key": "marble.period", "values": list(range(20))}], 20, 100, 2.0)
    boxes = layout.cells
    assert all((w, h) == (100, 50) for _, _, w, h in boxes)
    assert len({(x, y) for x, y, _, _ in boxes}) == 20
    for i, (x, y, w, h) in enumerate(boxes):
        for (x2, y2, w2, h2) in boxes[i + 1:]:
            assert x + w <= x2 or x2 + w2 <= x or y + h + cs.LINE <= y2 or y2 + h2 <= y
    assert all(x + w <= layout.size[0] and y + h + cs.LINE <= layout.size[1]
               for x, y, w, h in boxes)


def test_large_frames_shrink_to_the_cell_and_a_failed_one_is_grey(tmp_path):
    paths, colours = frames(tmp_path, 2, size=(400, 400))
    settings = [{"key": "marble.period", "values": [1, 2]}]
    values = [{"marble.period": 1}, {"marble.period": 2}]
    sheet = draw(tmp_path, settings, values, [paths[0], None], size=(400, 400), cell=64)
    layout = cs.sheet_layout(settings, 2, 64, 1.0)
    (x, y, w, h), (x2, y2, w2, h2) = layout.cells
    assert (sheet[y:y + h, x:x + w] == colours[0]).all()
    assert (sheet[y2 + 1, x2 + 1] == (200, 200, 200)).all()


@pytest.mark.parametrize("text", ["period = 1", "a" * 300])
def test_a_label_is_shortened_to_its_width(text):
    from PIL import ImageDraw
    d = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    line = cs.fitted_line(d, text, 100)
    assert d.textlength(line) <= 100
    assert line == text if d.textlength(text) <= 100 else line.endswith("…")



def test_column_values_fit_the_cells_of_a_shrunk_sheet(tmp_path, monkeypatch):
    """Two settings in a sheet too large for the pixel budget: the cells shrink, and each
    column's value is shortened to the shrunk cell's width (not the cell asked for), so
    nothing is drawn in the gaps between the columns' values."""
    import math
    from PIL import ImageDraw
    monkeypatch.setattr(cs, "CONTACT_SHEET_PIXELS", 240 * 160)
    settings = [{"key": "marble.period", "values": [1, 2, 3]},
                {"key": "marble.distortion", "values": [1.25, 2.5, 3.75]}]
    values = [{"marble.period": p, "marble.distortion": d}
              for p in (1, 2, 3) for d in (1.25, 2.5, 3.75)]
    paths, _ = frames(tmp_path, 9)
    sheet = draw(tmp_path, settings, values, paths)
    measure = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    left = math.ceil(max(measure.textlength(cs._label(settings[0], v)) for v in (1, 2, 3)))
    layout = cs.sheet_layout(settings, 9, 160, 40 / 30, left)
    width = layout.cells[0][2]
    assert width < 60 < measure.textlength(cs._label(settings[1], 1.25))   # shrunk, too long
    for (cx, cy) in layout.columns[:-1]:
        assert (sheet[cy:cy + cs.LINE, cx + width:cx + width + cs.GAP] == 255).all()
