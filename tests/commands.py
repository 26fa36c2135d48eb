"""The ``mimarble`` command run as a user runs it: a fresh process, in a folder."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def mimarble_cli(*args, cwd=ROOT):
    """``python -m mimarble ARGS`` in ``cwd`` (the checkout importable, llvm_ad_rgb); its
    stderr is copied to this process's, where the conftest check sees Dr.Jit's bounds
    reports."""
    env = dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb",
               PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    result = subprocess.run([sys.executable, "-m", "mimarble", *map(str, args)], cwd=cwd,
                            env=env, capture_output=True, text=True, timeout=300)
    sys.stderr.write(result.stderr)
    return result


def one_sentence(result):
    """Exit 2, no traceback, one line on stderr: the sentence."""
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mimarble: "), result.stderr
    return lines[0]
