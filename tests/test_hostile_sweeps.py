"""Sweeps under hostile and careless input (issue 23): a sweep folder is data, not
instructions; a damaged index or image is said and rendered again; every limit is a
sentence before anything large is made; nothing is written outside the output folder."""

import json
import os
import random
import re
import socket
import threading
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from commands import mimarble_cli as cli, one_sentence  # noqa: E402

from mimarble import scene as S
from mimarble.sweeps import (cluster as sweep_cluster, contact_sheet, frames as sweep_frames,
                             index as sweep_index, run as sweeps, settings as sweep_settings)
from mimarble.scene.edits import resized

ROOT = Path(__file__).resolve().parent.parent
SETTING = {"marble.period": [1.0, 2.0]}
NAMES = ["0000_period-1.png", "0001_period-2.png"]


def tiny():
    return resized(S.load(ROOT / "scenes" / "fig11a.scene"), 8)






@pytest.fixture
def swept(llvm, tmp_path):
    """A finished two-frame sweep of 8×8 images in tmp_path/"out"."""
    out = tmp_path / "out"
    index = sweeps.sweep(tiny(), SETTING, out, spp=1)
    assert [f["status"] for f in index["frames"]] == ["done", "done"]
    return out


def resume(out, monkeypatch=None):
    """Run the same sweep again; (the index, the frames rendered, the warnings' texts)."""
    rendered = []
    original = sweeps.render_frame
    sweeps.render_frame = lambda job: rendered.append(job["index"]) or original(job)
    try:
        import warnings
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            index = sweeps.sweep(tiny(), SETTING, out, spp=1)
    finally:
        sweeps.render_frame = original
    return index, rendered, [str(w.message) for w in caught]


def usable(out):
    """Every frame done, its derived image a whole 8×8 PNG, the contact sheet there."""
    from PIL import Image
    index = json.loads((out / "sweep.json").read_text())
    assert [f["status"] for f in index["frames"]] == ["done", "done"]
    assert [f["file"] for f in index["frames"]] == NAMES
    for name in NAMES:
        assert np.asarray(Image.open(out / name)).shape == (8, 8, 3)
    assert (out / "contact.png").exists()
    return index


# ---------------------------------------------------------------------------
# A sweep folder is data, not instructions

@pytest.mark.parametrize("foreign", ["absolute", "../victim.png", "other.png"])
def test_the_index_file_field_is_never_written_to(swept, foreign):
    victim = swept.parent / "victim.png"
    target = str(victim) if foreign == "absolute" else foreign
    index = json.loads((swept / "sweep.json").read_text())
    index["frames"][1].update(status="todo", file=target)
    (swept / "sweep.json").write_text(json.dumps(index))
    (swept / NAMES[1]).unlink()
    _, rendered, _ = resume(swept)
    assert rendered == [1]
    assert not victim.exists() and not (swept / "other.png").exists()
    assert sorted(p.name for p in swept.parent.iterdir()) == ["out"]
    assert usable(swept)["frames"][1]["file"] == NAMES[1]


def test_the_index_file_field_is_never_read(swept):
    # A done frame pointing at an image outside: the frame is judged by its own derived
    # file alone (missing here, so rendered again), and the foreign file is not opened.
    foreign = swept.parent / "elsewhere.png"
    os.replace(swept / NAMES[0], foreign)
    before = foreign.stat()
    index = json.loads((swept / "sweep.json").read_text())
    index["frames"][0]["file"] = str(foreign)
    (swept / "sweep.json").write_text(json.dumps(index))
    _, rendered, warned = resume(swept)
    assert rendered == [0]
    assert any("0000_period-1.png: missing" in w for w in warned)
    assert foreign.stat().st_mtime_ns == before.st_mtime_ns
    usable(swept)


def test_a_link_in_the_folder_is_not_followed_out_of_it(swept):
    victim = swept.parent / "victim.png"
    victim.write_bytes(b"not yours")
    (swept / NAMES[1]).unlink()
    (swept / NAMES[1]).symlink_to(victim)       # a done frame's image: a link outside
    (swept / "sweep.json").rename(swept / "real.json")
    (swept / "sweep.json").symlink_to(swept.parent / "victim.png")   # the index too
    _, rendered, warned = resume(swept)
    assert any("symbolic link" in w for w in warned)
    assert rendered == [0, 1]                   # the index not read: started afresh
    assert victim.read_bytes() == b"not yours"
    assert not (swept / NAMES[1]).is_symlink() and not (swept / "sweep.json").is_symlink()
    usable(swept)


@pytest.mark.timeout(60)
def test_a_pipe_as_the_index_or_an_image_does_not_block(swept):
    (swept / "sweep.json").unlink()
    os.mkfifo(swept / "sweep.json")
    (swept / NAMES[0]).unlink()
    os.mkfifo(swept / NAMES[0])
    _, rendered, warned = resume(swept)
    assert any("not a regular file" in w for w in warned)
    assert rendered == [0, 1]                   # a fresh index: both rendered
    usable(swept)


# ---------------------------------------------------------------------------
# A damaged index: one warning, started afresh

DAMAGED_INDEXES = {
    "binary garbage": bytes(random.Random(23).randrange(256) for _ in range(4096)),
    "an array": b"[]",
    "null": b"null",
    "a number": b"3.5",
    "an object of another shape": b'{"frames": {"0": "done"}}',
    "a header of the wrong types": json.dumps({
        "scene_digest": 7, "settings": "all", "spp": "1", "compare": 0, "variant": None,
        "frames": []}).encode(),
    "100 000 nested arrays": b"[" * 100_000,
    "not UTF-8": b'{"scene": "\xff\xfe\xfd"}',
}


@pytest.mark.parametrize("what", DAMAGED_INDEXES)
def test_a_damaged_index_is_said_and_started_afresh(swept, what):
    (swept / "sweep.json").write_bytes(DAMAGED_INDEXES[what])
    _, rendered, warned = resume(swept)
    assert len(warned) == 1 and "the sweep index is damaged" in warned[0], warned
    assert "\n" not in warned[0]
    assert rendered == [0, 1]
    usable(swept)


def test_a_shortened_frame_list_is_started_afresh(swept):
    index = json.loads((swept / "sweep.json").read_text())
    index["frames"] = index["frames"][:1]
    (swept / "sweep.json").write_text(json.dumps(index))
    _, rendered, warned = resume(swept)
    assert len(warned) == 1 and "lists 1 frames, not 2" in warned[0]
    assert rendered == [0, 1]
    usable(swept)


def test_another_sweep_of_another_length_is_refused_not_started_afresh(swept):
    before = {p.name: p.stat().st_mtime_ns for p in swept.iterdir()}
    with pytest.raises(sweep_settings.SweepError, match="holds another sweep"):
        sweeps.sweep(tiny(), {"marble.period": [1.0, 2.0, 3.0]}, swept, spp=1)
    assert {p.name: p.stat().st_mtime_ns for p in swept.iterdir()} == before


def test_a_huge_index_is_not_read(swept, monkeypatch):
    monkeypatch.setattr(sweep_index, "MAX_INDEX_BYTES", 100)
    _, rendered, warned = resume(swept)
    assert len(warned) == 1 and "larger than" in warned[0]
    assert rendered == [0, 1]


@pytest.mark.parametrize("damage", [
    lambda e: e.pop("status"),
    lambda e: e.pop("values"),
    lambda e: e.update(status=["done"]),
    lambda e: e.update(status="finished"),
    lambda e: e.update(index="1"),
    lambda e: e.update(render_s="fast"),
    lambda e: e.update(error={"no": "text"}),
    lambda e: e.update(values={"marble.period": 9.0}),
], ids=["no status", "no values", "status a list", "unknown status", "index a string",
        "render time a string", "error an object", "other values"])
def test_a_damaged_frame_entry_renders_that_frame_alone_again(swept, damage):
    index = json.loads((swept / "sweep.json").read_text())
    damage(index["frames"][1])
    (swept / "sweep.json").write_text(json.dumps(index))
    _, rendered, warned = resume(swept)
    assert len(warned) == 1 and "1 frame entry of the sweep index is damaged (frame 1" in warned[0]
    assert rendered == [1]
    usable(swept)


def test_a_damaged_index_through_the_command_is_a_warning_line(tmp_path):
    args = ["sweep", "scenes/fig11a.scene", "--set", "marble.period=1,2", "--width", "8",
            "--height", "8", "--spp", "1", "-o", tmp_path / "out"]
    assert cli(*args).returncode == 0
    (tmp_path / "out" / "sweep.json").write_bytes(b"\x00\x01garbage")
    result = cli(*args)
    assert result.returncode == 0 and "Traceback" not in result.stderr
    warnings = [line for line in result.stderr.splitlines() if "warning" in line]
    assert len(warnings) == 1 and "the sweep index is damaged" in warnings[0]
    index = json.loads((tmp_path / "out" / "sweep.json").read_text())
    assert [f["status"] for f in index["frames"]] == ["done", "done"]


# ---------------------------------------------------------------------------
# A done frame whose image is damaged: found on resume, rendered again

def truncated(path):
    path.write_bytes(path.read_bytes()[:60])


def replaced_by_text(path):
    path.write_text("not an image at all\n")


def of_another_size(path):
    from PIL import Image
    Image.new("RGB", (4, 4), "red").save(path)


def garbled_inside(path):
    # Whole, the right size and ending, but its compressed pixels overwritten: only
    # decoding finds it (the contact sheet), and the frame is rendered again then.
    data = bytearray(path.read_bytes())
    start = data.find(b"IDAT") + 4
    data[start:start + 16] = b"\x00" * 16
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("damage, words", [
    (Path.unlink, "missing"), (truncated, "truncated"), (replaced_by_text, "not a PNG"),
    (of_another_size, "4×4 pixels, not 8×8"), (garbled_inside, "did not decode")])
def test_a_done_frame_whose_image_is_damaged_is_rendered_again(swept, damage, words):
    damage(swept / NAMES[1])
    if damage is garbled_inside:
        assert sweep_index.image_problem(swept / NAMES[1], (8, 8)) is None   # the header is fine
    _, rendered, warned = resume(swept)
    assert rendered == [1]
    assert len(warned) == 1 and words in warned[0] and NAMES[1] in warned[0], warned
    usable(swept)


def test_an_image_that_does_not_decode_fails_a_cell_not_the_sheet(swept):
    garbled_inside(swept / NAMES[0])
    index = json.loads((swept / "sweep.json").read_text())
    path = contact_sheet.write_contact_sheet(swept, index)
    assert path.exists()
    assert index["frames"][0]["status"] == "failed"
    assert index["frames"][0]["error"].startswith("its image does not decode")
    assert index["frames"][1]["status"] == "done"


# ---------------------------------------------------------------------------
# Limits, before anything large is made

def test_a_huge_range_is_refused_before_its_values_are_made():
    tracemalloc.start()
    try:
        with pytest.raises(sweep_settings.SweepError, match=r"1000000000 values; a sweep renders at "
                                                    r"most 10000 frames"):
            sweep_settings.parse_setting("marble.period=0:1:1000000000")
        with pytest.raises(sweep_settings.SweepError, match="at most 10000"):
            sweep_settings.settings_from({"marble.period": range(10 ** 12)})
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1_000_000


def test_too_many_frames_are_refused_before_any_is_made(monkeypatch):
    built = []
    monkeypatch.setattr(sweep_frames, "with_value", lambda *a: built.append(a))
    settings = sweep_settings.settings_from(["marble.period=0:1:200", "marble.distortion=1:8:200"])
    with pytest.raises(sweep_settings.SweepError, match=r"^40000 frames \(200 × 200 values\); a sweep "
                                                r"renders at most 10000"):
        sweep_frames.frames(tiny(), settings)
    assert built == []


@pytest.mark.parametrize("spec, words", [
    ({"marble.period": [1, 2], "marble.scale": []}, "marble.scale: no values"),
    ([f"light.0.intensity={v}" for v in (1, 2)], "given twice"),
    ({f"k{i}": [1] for i in range(17)}, "17 settings; a sweep takes at most 16"),
])
def test_settings_past_the_limits_are_refused(spec, words):
    with pytest.raises(sweep_settings.SweepError, match=words):
        sweep_frames.frames(tiny(), sweep_settings.settings_from(spec))


def test_too_many_frames_from_the_command_is_one_sentence(tmp_path):
    line = one_sentence(cli("sweep", "scenes/fig11a.scene", "--set", "marble.period=0:1:1000000000",
                            "-o", tmp_path / "out"))
    assert "at most 10000 frames" in line
    assert not (tmp_path / "out").exists()


def test_workers_past_a_few_per_core_are_refused_with_the_limit(tmp_path):
    most = sweep_cluster.WORKERS_PER_CORE * os.cpu_count()
    line = one_sentence(cli("sweep", "scenes/fig11a.scene", "--set", "marble.period=1",
                            "--workers", 1000, "-o", tmp_path / "out"))
    assert f"--workers 1000: at most {most} here" in line
    assert not (tmp_path / "out").exists()
    assert sweep_cluster.check_workers(most) == most
    for bad in (0, -1, True, 2.5, "3", most + 1):
        with pytest.raises(sweep_settings.SweepError, match="--workers"):
            sweep_cluster.check_workers(bad)


def test_a_contact_sheet_of_many_frames_stays_within_its_pixels(tmp_path):
    from PIL import Image
    n = 2000                 # 160-pixel cells would make a sheet of 57 million pixels
    index = {"scene": "x.scene", "settings": [{"key": "marble.period", "values": list(range(n))}],
             "frames": [{"index": k, "values": {"marble.period": k}, "status": "failed"}
                        for k in range(n)]}
    path = contact_sheet.write_contact_sheet(tmp_path, index)
    width, height = Image.open(path).size
    assert width * height <= contact_sheet.CONTACT_SHEET_PIXELS * 1.05


# ---------------------------------------------------------------------------
# --scheduler at something that is not a Dask scheduler

def serve(answer: bytes):
    """A TCP server on a free local port that answers every connection with ``answer``
    and keeps it open; its address."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    kept = []

    def run():
        while True:
            connection, _ = server.accept()
            kept.append(connection)
            if answer:
                connection.sendall(answer)
    threading.Thread(target=run, daemon=True).start()
    return f"tcp://127.0.0.1:{server.getsockname()[1]}"


def test_a_server_that_answers_garbage_is_not_a_dask_scheduler(tmp_path):
    pytest.importorskip("distributed")
    address = serve(b"\xde\xad\xbe\xef" * 64)   # read by Dask as a frame of 3 EiB
    line = one_sentence(cli("sweep", "scenes/fig11a.scene", "--set", "marble.period=1",
                            "--width", "8", "--height", "8", "--scheduler", address,
                            "-o", tmp_path / "out"))
    assert f"--scheduler {address}: is not a Dask scheduler" in line
    assert "allocate" not in line
    assert not (tmp_path / "out").exists()


def test_a_web_server_is_not_a_dask_scheduler(llvm, tmp_path):
    pytest.importorskip("distributed")
    address = serve(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
    with pytest.raises(sweep_settings.SweepError, match="is not a Dask scheduler"):
        sweeps.sweep(tiny(), SETTING, tmp_path / "out", spp=1, scheduler=address)
    assert not (tmp_path / "out").exists()


def test_a_server_that_says_nothing_times_out(llvm, tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr(sweep_cluster, "SCHEDULER_TIMEOUT_S", 1)
    address = serve(b"")
    with pytest.raises(sweep_settings.SweepError, match=r"no Dask scheduler answered there within 1 s"):
        sweeps.sweep(tiny(), SETTING, tmp_path / "out", spp=1, scheduler=address)
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------------
# -o

def test_an_output_name_too_long_is_one_sentence(tmp_path):
    line = one_sentence(cli("sweep", "scenes/fig11a.scene", "--set", "marble.period=1",
                            "-o", tmp_path / ("x" * 300)))
    assert "File name too long" in line


def test_an_output_name_too_long_from_python_is_a_sweep_error(llvm, tmp_path):
    with pytest.raises(sweep_settings.SweepError, match="cannot make the sweep's folder"):
        sweeps.sweep(tiny(), SETTING, tmp_path / ("x" * 300), spp=1)


# ---------------------------------------------------------------------------
# Issue 38: one sweep at a time in a folder; the API's settings, numbers and names

HOLD_LOCK = """
import fcntl, os, sys, time
fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT, 0o666)
fcntl.flock(fd, fcntl.LOCK_EX)
os.write(fd, str(os.getpid()).encode())
print("held", flush=True)
time.sleep(600)
"""


def another_process_holding_the_lock(out):
    """A process that holds the folder's lock as a running sweep does (its own flock)."""
    import subprocess
    import sys
    out.mkdir(exist_ok=True)
    holder = subprocess.Popen([sys.executable, "-c", HOLD_LOCK, str(out / sweep_index.LOCK)],
                              stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    return holder


def test_a_second_sweep_into_a_folder_in_use_is_refused_and_writes_nothing(llvm, tmp_path):
    out = tmp_path / "out"
    holder = another_process_holding_the_lock(out)
    try:
        with pytest.raises(sweep_settings.SweepError, match=rf"another sweep \(process {holder.pid}\) "
                                                    r"is writing into this folder"):
            sweeps.sweep(tiny(), SETTING, out, spp=1)
        (tmp_path / "s.scene").write_text((ROOT / "scenes" / "fig11a.scene").read_text())
        sentence = one_sentence(cli("sweep", tmp_path / "s.scene", "--set",
                                    "marble.period=1,2", "--width", "8", "--height", "8",
                                    "--spp", "1", "-o", out))
        assert "another sweep" in sentence
        assert sorted(os.listdir(out)) == [sweep_index.LOCK]
    finally:
        holder.kill()
        holder.wait()


def test_a_lock_left_by_a_killed_sweep_blocks_nothing(llvm, tmp_path):
    out = tmp_path / "out"
    holder = another_process_holding_the_lock(out)
    holder.kill()                                   # SIGKILL: no chance to let go
    holder.wait()
    assert (out / sweep_index.LOCK).read_text() == str(holder.pid)
    index = sweeps.sweep(tiny(), SETTING, out, spp=1)
    assert [f["status"] for f in index["frames"]] == ["done", "done"]
    sweeps.sweep(tiny(), SETTING, out, spp=1)       # and this one let go of it when it ended
    usable(out)


@pytest.mark.parametrize("plant", ["link", "fifo"])
def test_a_lock_file_that_is_a_link_or_a_pipe_is_refused(llvm, tmp_path, plant):
    out = tmp_path / "out"
    out.mkdir()
    victim = tmp_path / "victim"
    victim.write_text("keep")
    if plant == "link":
        (out / sweep_index.LOCK).symlink_to(victim)
    else:
        os.mkfifo(out / sweep_index.LOCK)
    with pytest.raises(sweep_settings.SweepError, match="symbolic link|not a regular file"):
        sweeps.sweep(tiny(), SETTING, out, spp=1)
    assert victim.read_text() == "keep" and sorted(os.listdir(out)) == [sweep_index.LOCK]


def test_sweep_resolves_a_packaged_scene_name_as_render_does(llvm, tmp_path, monkeypatch):
    from mimarble.runtime import packaged_scenes
    monkeypatch.chdir(tmp_path)                     # no file called fig11a here
    index = sweeps.sweep("fig11a", {"camera.fov": [30.0]}, "out", spp=1, stop_after=0)
    assert index["scene"] == str(packaged_scenes.find("fig11a"))
    assert [f["status"] for f in index["frames"]] == ["todo"]


@pytest.mark.parametrize("settings, words", [
    (None, "settings None: give a mapping"),
    (42, "settings 42: give a mapping"),
    ({1: [1]}, "setting key 1 is not a string"),
    ({("marble", "period"): [1]}, "is not a string"),
    ([1, 2], "setting 1: give a mapping"),
    ({"marble.period": [1e39]}, "number 1e+39 is too large"),
    ({"marble.period": [-3.5e38]}, "is too large"),
    ({"marble.scale": [float("inf")]}, "is not finite"),
    ({"light.0.intensity": [10 ** 400]}, "is too large"),
])
def test_settings_in_another_form_or_past_float32_are_one_sentence(llvm, tmp_path, settings,
                                                                    words):
    with pytest.raises(sweep_settings.SweepError, match=re.escape(words)):
        sweeps.sweep(tiny(), settings, tmp_path / "out", spp=1)
    assert not (tmp_path / "out").exists()


def test_one_set_string_is_one_setting(llvm, tmp_path):
    index = sweeps.sweep(tiny(), "marble.period=1,2", tmp_path / "out", spp=1)
    assert [f["values"] for f in index["frames"]] == [{"marble.period": 1},
                                                      {"marble.period": 2}]


@pytest.mark.parametrize("value", ["1e39", "-1e39", "3.5e38", "1e309"])
def test_a_value_past_float32_is_refused_before_any_frame(tmp_path, value):
    sentence = one_sentence(cli("sweep", "fig11a", "--set", f"marble.period=1,{value}",
                                "--width", "8", "--height", "8", "-o", tmp_path / "out"))
    assert "marble.period" in sentence and ("too large" in sentence or "not finite" in sentence)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("stop_after", [-1, 1.5, True, "1", np.float64(1.0)])
def test_stop_after_is_a_whole_number_at_least_0(llvm, tmp_path, stop_after):
    with pytest.raises(sweep_settings.SweepError, match="stop_after=.* must be a whole number ≥ 0"):
        sweeps.sweep(tiny(), SETTING, tmp_path / "out", spp=1, stop_after=stop_after)
    assert not (tmp_path / "out").exists()


def test_numpy_numbers_are_taken_as_the_python_numbers_they_hold(llvm, tmp_path):
    python = sweeps.sweep(tiny(), {"marble.period": [1.5, 2.0], "marble.octaves": [3]},
                          tmp_path / "python", spp=1, stop_after=1)
    numpy = sweeps.sweep(tiny(), {"marble.period": np.array([1.5, 2.0], np.float32),
                                  "marble.octaves": [np.int64(3)]},
                         tmp_path / "numpy", spp=np.int64(1), stop_after=np.int64(1))
    assert [f["status"] for f in numpy["frames"]] == ["done", "todo"]
    assert [f["values"] for f in numpy["frames"]] == [f["values"] for f in python["frames"]]
    assert (tmp_path / "numpy" / NAMES[0].replace("period-1", "period-1.5_octaves-3")
            ).read_bytes() == (tmp_path / "python" / NAMES[0].replace(
                "period-1", "period-1.5_octaves-3")).read_bytes()


@pytest.mark.parametrize("out", ["", "a\0b", os.fsdecode(b"o\xff")])
def test_a_sweep_folder_name_no_writer_takes_is_refused(llvm, tmp_path, monkeypatch, out):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(sweep_settings.SweepError, match="empty name|NUL|not UTF-8"):
        sweeps.sweep(tiny(), SETTING, out, spp=1)
    assert os.listdir(tmp_path) == []
