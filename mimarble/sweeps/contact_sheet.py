"""A sweep's contact sheet: the frames with their values beside them, in one image.

A row for one setting (the paper's figure layout; a grid past :data:`ONE_ROW` values), a
grid of rows × columns for two (values along the top and the left), a grid of cells each
captioned with every value for more; drawn with Pillow (a sheet of 64 frames in a
fraction of a second). A failed frame is a grey cell. The images are read without
following links (mimarble/runtime/reading.py): the sheet reads nothing but the frames.
"""

from __future__ import annotations

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
#: a grid, each cell captioned.
ONE_ROW = 16


def draw_contact_sheet(path, title: str, settings, cells, cell: int = 160,
                       size=None) -> dict:
    """Draw the sheet to ``path`` (written whole) and return {cell number: the error} of
    the images that did not decode (or are not ``size``, (width, height), if given).

    ``settings``: [{"key", "values"}] as a sweep's index holds them; ``cells``: one
    (values by key, image path or None for a failed frame) per frame, in frame order.
    Cells are ``cell`` pixels wide, fewer for a sweep so large that the sheet would pass
    :data:`CONTACT_SHEET_PIXELS`."""
    from PIL import Image, ImageDraw

    undecodable = {}
    if len(settings) == 2:
        rows, columns = len(settings[0]["values"]), len(settings[1]["values"])
    elif len(settings) == 1 and len(cells) <= ONE_ROW:
        rows, columns = 1, len(cells)
    else:
        columns = math.ceil(math.sqrt(len(cells)))
        rows = math.ceil(len(cells) / columns)
    line = 12                                            # the default font's line height
    caption = line * (1 if len(settings) <= 2 else len(settings)) + 4
    left = 0 if len(settings) != 2 else 8 * max(len(_label(settings[0], v))
                                                for v in settings[0]["values"]) + 8
    top = line + 8 + (caption if len(settings) == 2 else 0)

    def sheet_size(cell):
        row_height = cell + (caption if len(settings) != 2 else 4)
        return left + columns * cell + 8, top + rows * row_height + 4
    while cell > MIN_CELL and math.prod(sheet_size(cell)) > CONTACT_SHEET_PIXELS:
        cell -= 1                        # a large sweep: smaller cells, a bounded sheet
    row_height = cell + (caption if len(settings) != 2 else 4)
    sheet = Image.new("RGB", sheet_size(cell), "white")
    draw = ImageDraw.Draw(sheet)
    draw.text((4, 4), title, fill="black")
    for k, (values, image_path) in enumerate(cells):
        r, c = divmod(k, columns)
        x, y = left + c * cell + 4, top + r * row_height
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
            image.thumbnail((cell - 4, cell - 4))
            sheet.paste(image, (x, y))
        else:                                            # a failed frame: a grey cell
            draw.rectangle((x, y, x + cell - 5, y + cell - 5), fill=(200, 200, 200))
            draw.text((x + 6, y + cell // 2 - 6), "failed", fill="black")
        if len(settings) == 2:
            if r == 0:
                draw.text((x, y - caption), _label(settings[1], values[settings[1]["key"]]),
                          fill="black")
            if c == 0:
                draw.text((4, y + cell // 2), _label(settings[0], values[settings[0]["key"]]),
                          fill="black")
        else:
            for n, setting in enumerate(settings):
                draw.text((x, y + cell - 2 + n * line), _label(setting, values[setting["key"]]),
                          fill="black")
    files.write_atomically(path, lambda tmp: sheet.save(tmp, compress_level=1))
    return undecodable


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
