"""A sweep's contact sheet: the frames with their values beside them, in one image.

A row for one setting (the paper's figure layout; a grid past :data:`ONE_ROW` values), a
grid of rows × columns for two (values along the top and the left), a grid of cells for
more; drawn with Pillow (a sheet of 64 frames in a fraction of a second). Each frame fills
its cell: scaled to the cell's width, up or down (up first by the largest whole factor,
nearest, so a small render shows its own pixels, then Lanczos for the rest), the cells shaped as the frames are (``size``, else the first
frame's header), :data:`GAP` pixels apart; each cell's values are one line under it,
shortened with "…" to the cell's width (issue 42, item 6). A failed frame is a grey cell.
The images are read without following links (mimarble/runtime/reading.py): the sheet reads
nothing but the frames.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from mimarble.runtime import files
from mimarble.runtime.reading import open_regular
from mimarble.sweeps.frames import error_text, file_name
from mimarble.sweeps.settings import Setting

#: The contact sheet's name in a sweep's folder.
CONTACT_SHEET = "contact.png"

#: The contact sheet's pixels at most (~150 MB as 8-bit RGB): past ~1 700 frames at the
#: usual 160-pixel cells, the cells shrink (not below MIN_CELL) to keep it so.
CONTACT_SHEET_PIXELS = 50_000_000
MIN_CELL = 24
#: One setting's frames stand in one row (the paper's figures) up to this many; more are
#: a grid.
ONE_ROW = 16
#: Pixels between two cells, and around the grid.
GAP = 2
#: The height of a line of text (Pillow's default font), with a pixel above and below.
LINE = 12
#: The widest a cell's frame may be for its height, and the narrowest (a 1×1000 frame's
#: cell would be a hair: its thumbnail is then fitted inside, not stretched to it).
ASPECT_RANGE = (0.25, 4.0)


@dataclasses.dataclass(frozen=True)
class SheetLayout:
    """Where everything of a sheet lies, in pixels.

    ==============  ============================================================
    ``size``        (width, height) of the sheet
    ``cells``       (x, y, width, height) of each frame's cell, in frame order
    ``labels``      (x, y, width) of each cell's one line under it (None: the
                    values stand along the top and the left, two settings)
    ``columns``     (x, y) of each column's value (two settings), else ()
    ``rows``        (x, y) of each row's value (two settings), else ()
    ==============  ============================================================
    """

    size: tuple[int, int]
    cells: tuple[tuple[int, int, int, int], ...]
    labels: tuple[tuple[int, int, int], ...] | None
    columns: tuple[tuple[int, int], ...]
    rows: tuple[tuple[int, int], ...]


def grid_shape(settings, count: int) -> tuple[int, int]:
    """(rows, columns): two settings' values, one row of at most :data:`ONE_ROW` for one,
    else the squarest grid."""
    if len(settings) == 2:
        return len(settings[0]["values"]), len(settings[1]["values"])
    if len(settings) == 1 and count <= ONE_ROW:
        return 1, count
    columns = math.ceil(math.sqrt(count))
    return math.ceil(count / columns), columns


def sheet_layout(settings, count: int, cell: int = 160, aspect: float = 1.0,
                 left: int = 0) -> SheetLayout:
    """The layout of ``count`` cells ``cell`` pixels wide and ``cell / aspect`` high (aspect:
    the frames' width over height), shrunk until the sheet holds at most
    :data:`CONTACT_SHEET_PIXELS` (not below :data:`MIN_CELL`); ``left``: the row labels'
    width, for two settings."""
    aspect = min(max(aspect, ASPECT_RANGE[0]), ASPECT_RANGE[1])
    rows, columns = grid_shape(settings, count)
    two = len(settings) == 2
    left = left + GAP if two else 0
    top = LINE + 2 * GAP + (LINE if two else 0)          # the title, the column values

    def size(width):
        height = max(1, round(width / aspect))
        return (left + GAP + columns * (width + GAP),
                top + rows * (height + (0 if two else LINE) + GAP) + GAP), height
    while cell > MIN_CELL and math.prod(size(cell)[0]) > CONTACT_SHEET_PIXELS:
        cell -= 1                        # a large sweep: smaller cells, a bounded sheet
    (width, height), cell_height = size(cell)
    row_height = cell_height + (0 if two else LINE) + GAP
    cells = tuple((left + GAP + c * (cell + GAP), top + r * row_height, cell, cell_height)
                  for r, c in (divmod(k, columns) for k in range(count)))
    labels = None if two else tuple((x, y + h, w) for x, y, w, h in cells)
    return SheetLayout((width, height), cells, labels,
                       tuple((left + GAP + c * (cell + GAP), top - LINE) for c in range(columns))
                       if two else (),
                       tuple((GAP, top + r * row_height + cell_height // 2 - LINE // 2)
                             for r in range(rows)) if two else ())


def fitted_line(draw, text: str, width: int) -> str:
    """``text`` as it fits in ``width`` pixels on one line, shortened with "…"."""
    if draw.textlength(text) <= width:
        return text
    while text and draw.textlength(text + "…") > width:
        text = text[:-1]
    return text + "…"


def _frame_aspect(cells, size) -> float:
    """The frames' width over height: ``size``'s, else the first readable frame's header."""
    from PIL import Image
    if size is not None:
        return size[0] / size[1]
    for _, image_path in cells:
        if image_path is None:
            continue
        try:
            with open_regular(image_path, follow_links=False) as f:
                width, height = Image.open(f).size      # the header only
            return width / height
        except Exception:                # unreadable: drawn as a failed cell below
            continue
    return 1.0


def draw_contact_sheet(path, title: str, settings, cells, cell: int = 160,
                       size=None) -> dict:
    """Draw the sheet to ``path`` (written whole) and return {cell number: the error} of
    the images that did not decode (or are not ``size``, (width, height), if given).

    ``settings``: [{"key", "values"}] as a sweep's index holds them; ``cells``: one
    (values by key, image path or None for a failed frame) per frame, in frame order.
    Cells are ``cell`` pixels wide (:func:`sheet_layout`), fewer for a sweep so large that
    the sheet would pass :data:`CONTACT_SHEET_PIXELS`."""
    from PIL import Image, ImageDraw

    measure = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    left = 0 if len(settings) != 2 else math.ceil(max(
        measure.textlength(_label(settings[0], v)) for v in settings[0]["values"]))
    layout = sheet_layout(settings, len(cells), cell, _frame_aspect(cells, size), left)
    undecodable = {}
    sheet = Image.new("RGB", layout.size, "white")
    draw = ImageDraw.Draw(sheet)
    draw.text((GAP + 2, GAP), fitted_line(draw, title, layout.size[0] - 2 * GAP - 2),
              fill="black")
    for k, (values, image_path) in enumerate(cells):
        x, y, w, h = layout.cells[k]
        image = None
        if image_path is not None:
            try:
                with open_regular(image_path, follow_links=False) as f:
                    image = Image.open(f)
                    if size is not None and image.size != tuple(size):
                        raise ValueError(f"{image.size[0]}×{image.size[1]} pixels, not "
                                         f"{size[0]}×{size[1]}")
                    image = image.convert("RGB")          # decodes it all, here
            except Image.DecompressionBombError:          # a frame too large to show, not bad
                image = None
            except Exception as e:       # truncated, garbled, replaced: render it again
                image = None
                undecodable[k] = e
        if image is not None:
            thumbnail = _filled(image, w, h)
            sheet.paste(thumbnail, (x + (w - thumbnail.width) // 2,
                                    y + (h - thumbnail.height) // 2))
        else:                                            # a failed frame: a grey cell
            draw.rectangle((x, y, x + w - 1, y + h - 1), fill=(200, 200, 200))
            draw.text((x + 4, y + h // 2 - LINE // 2), "failed", fill="black")
        if layout.labels is not None:    # every value, one line under the cell
            lx, ly, lw = layout.labels[k]
            text = ", ".join(_label(setting, values[setting["key"]]) for setting in settings)
            draw.text((lx, ly), fitted_line(draw, text, lw), fill="black")
    if len(settings) == 2:               # the values along the top and the left
        width = layout.cells[0][2]       # the cells' width, shrunk for a large sweep
        for (cx, cy), value in zip(layout.columns, settings[1]["values"]):
            draw.text((cx, cy), fitted_line(draw, _label(settings[1], value), width),
                      fill="black")
        for (rx, ry), value in zip(layout.rows, settings[0]["values"]):
            draw.text((rx, ry), _label(settings[0], value), fill="black")
    files.write_atomically(path, lambda tmp: sheet.save(tmp, compress_level=1))
    return undecodable


def _filled(image, width: int, height: int):
    """``image`` scaled to fill a ``width`` × ``height`` box, its aspect kept (fitted
    inside): up by the largest whole factor with nearest-neighbour (its pixels shown as
    they are) where it is at least 2, then Lanczos, up or down, for what is left."""
    from PIL import Image
    scale = min(width / image.width, height / image.height)
    if scale >= 2:
        factor = math.floor(scale)
        image = image.resize((image.width * factor, image.height * factor),
                             Image.Resampling.NEAREST)
        scale = min(width / image.width, height / image.height)
    if scale != 1:
        image = image.resize((max(1, round(image.width * scale)),
                              max(1, round(image.height * scale))), Image.Resampling.LANCZOS)
    return image


def _label(setting, value) -> str:
    return f"{_short(setting['key'])} = {_text(value)}"


def _short(key: str) -> str:
    return key.split(".", 1)[1] if key.startswith("marble.") else key


def _text(value) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def write_contact_sheet(out_dir, index: dict, cell: int = 160, size=None) -> Path:
    """``contact.png`` of the sweep in ``out_dir`` (:func:`draw_contact_sheet`). Each done
    frame's image is read from its derived name (mimarble/sweeps/frames.py, ``file_name``)
    in ``out_dir``, nothing else; one that does not decode (or is not ``size``, (width,
    height), if given) is drawn as a failed cell and marked failed in ``index``, with why,
    so that it is rendered again."""
    out_dir = Path(out_dir)
    named = [Setting(s["key"], tuple(s["values"])) for s in index["settings"]]
    cells = [(entry["values"], out_dir / file_name({"index": k, "values": entry["values"]}, named)
              if entry["status"] == "done" else None)
             for k, entry in enumerate(index["frames"])]
    path = out_dir / CONTACT_SHEET
    title = f"{Path(index['scene']).name}: " + ", ".join(s["key"] for s in index["settings"])
    undecodable = draw_contact_sheet(path, title, index["settings"], cells, cell, size)
    for k, error in undecodable.items():
        index["frames"][k].update(status="failed",
                                  error=f"its image does not decode ({error_text(error)})")
    return path
