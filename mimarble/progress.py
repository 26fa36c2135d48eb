"""Progress of long renders: a tqdm bar on stderr, or the caller's own callback."""

from __future__ import annotations

import sys

#: A bar appears only once the work has taken this long (seconds): quick renders stay quiet.
DELAY_S = 1.5


def report(progress, description: str, unit: str = "sample"):
    """``progress`` as a callable ``(done, total)``.

    True: a tqdm bar on stderr that shows itself after :data:`DELAY_S` and
    disappears when done — only when stderr is a terminal (logs and pipes get
    no carriage-return noise); a callable: itself; False or None: nothing.
    """
    if callable(progress):
        return progress
    if not progress:
        return lambda done, total: None
    from tqdm import tqdm
    bar = None

    def update(done, total):
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, initial=done, desc=description, unit=unit,
                       unit_scale=unit == "sample",
                       delay=DELAY_S, leave=False, file=sys.stderr, disable=None)
        if bar.total != total:          # edge samples add work once the first pass is done
            bar.total = total
        bar.update(done - bar.n)
        if done >= total:
            bar.close()
    return update
