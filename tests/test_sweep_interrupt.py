"""Ctrl-C on a sweep rendering on a Dask LocalCluster (issue 28): one line on stderr, the
workers stopped with it, and a folder a resumed sweep can trust."""

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mimarble.sweeps import index as sweep_index

ROOT = Path(__file__).resolve().parent.parent
SIZE = 16
# Far more frames than can be rendered before the interrupt lands (at least a few ms
# each on Dask): the sweep is always interrupted mid-way, never finished first.
FRAMES = 2 * 1500


def processes_of_group(group: int) -> list[str]:
    """The processes of ``group`` still running (zombies, which have exited and wait only
    for their reaper, left out), as "PID COMMAND"."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:               # gone meanwhile
            continue
        # pid (comm) state ppid pgrp …; comm may hold spaces and parentheses
        state, _, pgrp = stat[stat.rindex(")") + 2:].split()[:3]
        if int(pgrp) == group and state != "Z":
            found.append(f"{entry.name} {stat[stat.index('(') + 1:stat.rindex(')')]}")
    return found


@pytest.mark.timeout(600)     # the bounds below are generous: a loaded 2-core machine
def test_ctrl_c_on_two_workers_says_one_line_stops_them_and_leaves_whole_files(tmp_path):
    pytest.importorskip("distributed")
    if not Path("/proc/self/stat").exists():
        pytest.skip("reads the process group's members from /proc")
    out = tmp_path / "out"
    env = dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb")
    # Its own process group, as a terminal's foreground job is: Ctrl-C is SIGINT to the
    # whole group, the LocalCluster's worker processes included.
    process = subprocess.Popen(
        [sys.executable, "-m", "mimarble", "sweep", "scenes/fig11a.scene",
         "--set", f"marble.period=0.5:4:{FRAMES // 2}", "--set", "marble.distortion=1,2",
         "--width", str(SIZE), "--height", str(SIZE), "--spp", "1", "--workers", "2",
         "-o", str(out)],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True)
    try:
        deadline = time.monotonic() + 300          # the cluster up and a frame written
        while not any(out.glob("0*.png")):
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline, "no frame written within 300 s"
            time.sleep(0.05)
        os.killpg(process.pid, signal.SIGINT)
        stdout, stderr = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    sys.stderr.write(stderr)      # where the conftest check sees Dr.Jit's bounds reports
    assert process.returncode == 130, (stdout, stderr)
    assert stderr.splitlines() == ["mimarble: interrupted"]
    # The workers were stopped by the sweep, not left running (or to notice it gone);
    # any that were are killed, so a failing run leaves nothing behind in CI.
    try:
        deadline = time.monotonic() + 60
        while processes_of_group(process.pid):
            assert time.monotonic() < deadline, processes_of_group(process.pid)
            time.sleep(0.1)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
    # Nothing half-written: the index whole and of this sweep, every image in the folder
    # whole, each frame it says is done there, no temporary file left behind.
    index = json.loads((out / "sweep.json").read_text())
    assert len(index["frames"]) == FRAMES
    done = [f for f in index["frames"] if f["status"] == "done"]
    assert 0 < len(done) < FRAMES and index["summary"]["rendered_now"] == len(done)
    assert {f["status"] for f in index["frames"]} <= {"done", "todo"}
    for frame in done:
        assert sweep_index.image_problem(out / frame["file"], (SIZE, SIZE)) is None
    names = [p.name for p in out.iterdir()]
    assert not [n for n in names if re.search(r"\.mimarble-\d+-", n)]
    for name in names:
        if name.endswith(".png"):
            assert sweep_index.image_problem(out / name, (SIZE, SIZE)) is None, name
