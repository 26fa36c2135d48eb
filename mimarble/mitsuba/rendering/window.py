"""The pixels a render traces: the whole image, or a crop's window and a ring around it."""

from __future__ import annotations

import numpy as np

from .passes import Target


class Window:
    """The pixels a render traces: ``x0, y0`` and ``width`` × ``height`` of a ``columns``
    wide image; ``inner``: the rows and columns of the asked-for window within them."""

    def __init__(self, columns: int, x0: int, y0: int, width: int, height: int, inner):
        self.columns, self.x0, self.y0, self.width, self.height = columns, x0, y0, width, height
        self.inner = inner
        self.whole = inner is None

    @classmethod
    def of(cls, target: Target, crop, ring: int) -> "Window":
        """The whole image of ``target`` (``crop`` None), or the window ``crop`` and a
        ``ring`` of pixels around it, within the image."""
        if crop is None:
            return cls(target.width, 0, 0, target.width, target.height, None)
        x0, y0, x1, y1 = crop
        tx0, ty0 = max(x0 - ring, 0), max(y0 - ring, 0)
        tx1, ty1 = min(x1 + ring, target.width), min(y1 + ring, target.height)
        return cls(target.width, tx0, ty0, tx1 - tx0, ty1 - ty0,
                   (slice(y0 - ty0, y1 - ty0), slice(x0 - tx0, x1 - tx0)))

    @property
    def pixels(self) -> np.ndarray | None:
        """The traced pixels' indices in the whole image, row by row (None: all of them)."""
        if self.whole:
            return None
        rows = np.arange(self.y0, self.y0 + self.height, dtype=np.uint32)[:, None]
        columns = np.arange(self.x0, self.x0 + self.width, dtype=np.uint32)[None, :]
        return (rows * np.uint32(self.columns) + columns).ravel()

    def local(self, pixels):
        """Whole-image pixel indices (a slice or an array) → indices into the traced pixels."""
        if self.whole:
            return pixels
        pixels = np.asarray(pixels, dtype=np.int64)
        return (pixels // self.columns - self.y0) * self.width + pixels % self.columns - self.x0

    def global_(self, local: np.ndarray) -> np.ndarray:
        """Indices into the traced pixels → the whole image's (uint32)."""
        if self.whole:
            return local
        local = np.asarray(local, dtype=np.int64)
        return ((local // self.width + self.y0) * self.columns
                + local % self.width + self.x0).astype(np.uint32)

    def contains(self, local: np.ndarray) -> np.ndarray:
        """Which of the traced pixels ``local`` lie in the asked-for window (bool)."""
        if self.whole:
            return np.ones(len(local), dtype=bool)
        rows, columns = np.divmod(np.asarray(local, dtype=np.int64), self.width)
        (r, c) = self.inner
        return (rows >= r.start) & (rows < r.stop) & (columns >= c.start) & (columns < c.stop)

    def window_of(self, image: np.ndarray) -> np.ndarray:
        """The asked-for window of the traced (height, width, 3) image."""
        return image if self.whole else np.ascontiguousarray(image[self.inner])
