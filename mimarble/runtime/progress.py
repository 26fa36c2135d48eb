"""Progress of long work (renders, sweeps, the benchmark): a tqdm bar on stderr, or the
caller's own callback."""

from __future__ import annotations

import sys

#: A bar appears only once the work has taken this long (seconds): quick renders stay quiet.
DELAY_S = 1.5


def report(progress, description: str, unit: str = "sample"):
    """``progress`` as a callable ``(done, total, label=None)``.

    True: a tqdm bar on stderr that shows itself after :data:`DELAY_S` and
    disappears when done — only when stderr is a terminal (logs and pipes get
    no carriage-return noise); a callable: that callable, called with
    ``(done, total)``; False or None: nothing. ``label``, what is being done now
    (the benchmark's ``fig11a: plain 4 spp``), is shown after the bar.
    """
    if callable(progress):
        return lambda done, total, label=None: progress(done, total)
    if not progress:
        return lambda done, total, label=None: None
    from tqdm import tqdm
    bar = None

    def update(done, total, label=None):
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, initial=done, desc=description, unit=unit,
                       unit_scale=unit == "sample",
                       delay=DELAY_S, leave=False, file=sys.stderr, disable=None)
        if bar.total != total:          # edge samples add work once the first pass is done
            bar.total = total
        if label is not None:
            bar.set_postfix_str(label, refresh=False)
        bar.update(done - bar.n)
        if done >= total:
            bar.close()
    return update
