"""A crop window: part of an image rendered, with the full render's pixels there.

``(x0, y0, x1, y1)`` are pixel indices from the top-left corner, counted from 0,
with ``x1`` and ``y1`` exclusive, as Python slices are: the window is
``full[y0:y1, x0:x1]``, (y1 − y0) × (x1 − x0) pixels. POV-Ray's ``+SC a +EC b
+SR c +ER d`` (columns and rows from 1, both ends included) is ``(a − 1, c − 1, b, d)``.

Standard library only: the command line checks ``--crop`` before Dr.Jit and Mitsuba
load (mimarble/__init__.py). Rendering a window: mimarble/mitsuba/rendering/render.py.
"""

from __future__ import annotations

import operator

#: How the four numbers read, for the help and the error messages.
CONVENTION = "pixel indices from 0 at the top-left corner, the ends exclusive as in a Python slice"


def crop_problem(crop, width: int, height: int) -> str | None:
    """What is wrong with ``crop`` as a window of a ``width`` × ``height`` image, in one
    sentence without a subject (the caller names it), or None: it must be four integers
    ``(x0, y0, x1, y1)`` with 0 ≤ x0 < x1 ≤ width and 0 ≤ y0 < y1 ≤ height."""
    values = as_integers(crop)
    if values is None:
        return f"must be four integers (x0, y0, x1, y1), found {crop!r:.60}"
    x0, y0, x1, y1 = values
    size = f"the {width}x{height} image"
    if x0 < 0 or y0 < 0:
        return f"starts outside {size}: x0 and y0 must be at least 0 ({CONVENTION})"
    if x1 > width or y1 > height:
        return (f"ends outside {size}: x1 must be at most {width} and y1 at most {height} "
                f"({CONVENTION})")
    if x1 <= x0 or y1 <= y0:
        return (f"is empty: x1 must be greater than x0 and y1 greater than y0 "
                f"({CONVENTION})")
    return None


def as_integers(crop) -> tuple[int, int, int, int] | None:
    """``crop`` as four Python ints (NumPy's integers too, not bools), else None."""
    try:
        values = tuple(crop)
    except TypeError:
        return None
    if len(values) != 4 or any(isinstance(v, bool) or not hasattr(v, "__index__")
                               for v in values):
        return None
    return tuple(operator.index(v) for v in values)


def crop_words(crop) -> str:
    """``7 5 29 21``: the window as the command line takes it."""
    return " ".join(str(v) for v in crop)
