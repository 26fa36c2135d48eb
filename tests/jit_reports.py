"""Dr.Jit's own reports of invalid memory accesses, caught per test.

With ``JitFlag.Debug`` Dr.Jit bounds-checks every gather, scatter and
symbolic call: an out-of-range lane is masked (it reads 0) and a line such as
``drjit.gather(): out-of-bounds read from position 2147483649 in an array of
size 8`` is logged, through Python's ``sys.stderr`` when Dr.Jit's Python log
callback is active, else by native code straight to file descriptor 2 (both
are watched). Without the
flag nothing is checked, and the same access reads garbage on AVX-512 CPUs and
kills the process on AVX2 ones. ``./go test --jit-debug`` turns the checks on
for the whole run (conftest.py), and every test is run inside
:func:`stderr_reports`, failing if such a line appeared.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile

# Every message drjit-core's bounds check can print (jitc_var_check_bounds).
REPORT = re.compile(r"^.*(?:out-of-bounds (?:packet )?(?:read|write)|"
                    r"Attempted to invoke callable with index).*$", re.MULTILINE)


def _sync(dr) -> None:
    """Wait for asynchronous kernels, whose reports come when they finish."""
    with contextlib.suppress(Exception):
        dr.sync_all_devices()
    with contextlib.suppress(Exception):
        dr.sync_thread()


class Captured:
    text = ""

    def reports(self) -> list[str]:
        return REPORT.findall(self.text)


class _Tee:
    """A ``sys.stderr`` that keeps a copy of what is written and passes it on."""

    def __init__(self, stream, echo: bool):
        self.stream, self.echo, self.parts = stream, echo, []

    def write(self, text):
        self.parts.append(text)
        return self.stream.write(text) if self.echo else len(text)

    def __getattr__(self, name):
        return getattr(self.stream, name)


@contextlib.contextmanager
def stderr_reports(dr, echo: bool = True):
    """Capture what is written to ``sys.stderr`` and to file descriptor 2 while the block runs.

    The text is passed on as well (``echo``), so pytest's own capture still shows it.
    """
    captured = Captured()
    sys.stderr.flush()
    saved_fd, saved_stream = os.dup(2), sys.stderr
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        tee = sys.stderr = _Tee(saved_stream, echo)
        try:
            yield captured
        finally:
            _sync(dr)
            sys.stderr = saved_stream
            saved_stream.flush()
            os.dup2(saved_fd, 2)
            os.close(saved_fd)
            sink.seek(0)
            native = sink.read().decode("utf-8", errors="replace")
            if echo and native:
                os.write(2, native.encode("utf-8"))
            captured.text = "".join(tee.parts) + native
