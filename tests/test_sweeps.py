"""Sweeps: settings, frames, one compile per structure, nothing lost, Dask."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import mimarble
from mimarble import scene as S
from mimarble.sweeps import (cluster as sweep_cluster, frames as sweep_frames,
                             index as sweep_index, run as sweeps, settings as sweep_settings)
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.mitsuba.rendering.loaded_scenes import LOADED
from mimarble.scene.edits import resized, with_marbles, with_value

dr, mi = mimarble.dr, mimarble.mi
ROOT = Path(__file__).resolve().parent.parent


def small(size=24):
    return resized(S.load(ROOT / "scenes" / "fig11a.scene"), size)


def png(path):
    from PIL import Image
    return np.asarray(Image.open(path))


def test_settings_are_lists_or_ranges():
    assert sweep_settings.parse_setting("marble.period=0.5,1,2,4").values == (0.5, 1, 2, 4)
    assert sweep_settings.parse_setting("marble.distortion=1:8:4").values == pytest.approx(
        (1.0, 3.3333333, 5.6666667, 8.0))
    assert sweep_settings.parse_setting("marble.function=sine,cosine").values == ("sine", "cosine")
    for bad in ("marble.period", "=1,2", "marble.period=1:2", "marble.period=1:2:0"):
        with pytest.raises(sweep_settings.SweepError):
            sweep_settings.parse_setting(bad)


def test_a_bad_key_is_a_sweep_error_naming_the_option():
    scene = small()
    with pytest.raises(sweep_settings.SweepError, match=r"^--set marble\.perod: unknown key"):
        sweep_frames.frames(scene, sweep_settings.settings_from({"marble.perod": [1.0]}))


def test_a_sweep_writes_every_frame_an_index_and_a_contact_sheet(llvm, tmp_path):
    scene = small()
    index = sweeps.sweep(scene, {"marble.period": [0.5, 2.0], "marble.distortion": [1.0, 3.0]},
                         tmp_path, spp=1)
    assert [f["status"] for f in index["frames"]] == ["done"] * 4
    assert json.loads((tmp_path / "sweep.json").read_text()) == index
    assert (tmp_path / "contact.png").exists()
    # Each frame is the image of that frame's scene rendered on its own, bit for bit.
    for frame in index["frames"]:
        values = frame["values"]
        alone = with_value(with_value(scene, "marble.period", values["marble.period"]),
                           "marble.distortion", values["marble.distortion"])
        expected = render_in_passes(mi.load_dict(to_mitsuba(alone, spp=1)), 1)
        from mimarble.mitsuba.rendering.image_output import srgb8
        assert np.array_equal(png(tmp_path / frame["file"]), srgb8(expected))


def test_in_place_values_reuse_the_loaded_scene_and_its_kernels(llvm, tmp_path):
    LOADED.scenes.clear()
    scene = small()
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        sweeps.sweep(scene, {"marble.period": [0.7, 1.1, 1.9, 2.3]}, tmp_path / "a", spp=1)
        kernels = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    assert len(LOADED.scenes) == 1               # one structure, loaded once
    first = set(LOADED.scenes)
    render_kernels = [k for k in kernels if k["operation_count"] > 500]
    assert len(render_kernels) == 4 and all(k["cache_hit"] for k in render_kernels[1:])
    sweeps.sweep(scene, {"marble.octaves": [3, 5]}, tmp_path / "b", spp=1)
    assert len(LOADED.scenes) == 2 and not first & set(LOADED.scenes)   # each: a structure


def test_an_interrupted_sweep_resumes_with_only_what_is_missing(llvm, tmp_path):
    scene, setting = small(), {"marble.period": [0.5, 1.0, 1.5, 2.0]}
    first = sweeps.sweep(scene, setting, tmp_path, spp=1, stop_after=2)
    assert [f["status"] for f in first["frames"]] == ["done", "done", "todo", "todo"]
    assert not (tmp_path / "contact.png").exists()
    kept = {f["file"]: (tmp_path / f["file"]).stat().st_mtime_ns for f in first["frames"][:2]}
    rendered = []
    original = sweeps.render_frame
    sweeps.render_frame = lambda job: rendered.append(job["index"]) or original(job)
    try:
        second = sweeps.sweep(scene, setting, tmp_path, spp=1)
    finally:
        sweeps.render_frame = original
    assert rendered == [2, 3]
    assert [f["status"] for f in second["frames"]] == ["done"] * 4
    assert {f: (tmp_path / f).stat().st_mtime_ns for f in kept} == kept
    assert (tmp_path / "contact.png").exists()


def test_a_resumed_command_says_what_was_already_done_and_what_it_rendered(tmp_path):
    env = dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb")
    out = tmp_path / "out"
    args = [sys.executable, "-m", "mimarble", "sweep", "scenes/fig11a.scene", "--set",
            "marble.period=1,2", "--set", "marble.distortion=1,3", "--width", "8",
            "--height", "8", "--spp", "1", "-o", str(out)]

    def run():
        result = subprocess.run(args, cwd=ROOT, env=env, capture_output=True, text=True,
                                timeout=300)
        sys.stderr.write(result.stderr)   # where the conftest check sees Dr.Jit's reports
        assert result.returncode == 0, result.stderr
        return result.stdout, json.loads((out / "sweep.json").read_text())["summary"]

    stdout, summary = run()
    assert "4 frames: 0 already done, 4 rendered now, 0 failed (" in stdout
    index = json.loads((out / "sweep.json").read_text())
    for frame in index["frames"][1:3]:           # two images gone: the resume sees them missing
        (out / frame["file"]).unlink()
    stdout, summary = run()
    assert "4 frames: 2 already done, 2 rendered now, 0 failed (" in stdout
    assert summary == {"frames": 4, "already_done": 2, "rendered_now": 2, "failed": 0, "left": 0}
    stdout, summary = run()
    assert "4 frames: 4 already done, 0 rendered now, 0 failed (" in stdout


def test_the_summary_counts_failed_frames_and_their_retry(llvm, tmp_path, monkeypatch):
    original = sweeps.render_frame
    monkeypatch.setattr(sweeps, "render_frame", lambda job: dict(original(job), error="boom")
                        if job["index"] == 1 else original(job))
    setting = {"marble.period": [1.0, 2.0, 3.0]}
    first = sweeps.sweep(small(8), setting, tmp_path, spp=1, stop_after=2)
    assert first["summary"] == {"frames": 3, "already_done": 0, "rendered_now": 1,
                                "failed": 1, "left": 1}
    assert sweep_index.summary_sentence(first) == \
        "3 frames: 0 already done, 1 rendered now, 1 failed, 1 left"
    monkeypatch.setattr(sweeps, "render_frame", original)
    second = sweeps.sweep(small(8), setting, tmp_path, spp=1)
    assert second["summary"] == {"frames": 3, "already_done": 1, "rendered_now": 2,
                                 "failed": 0, "left": 0}
    assert json.loads((tmp_path / "sweep.json").read_text())["summary"] == second["summary"]


def test_a_resumed_sweep_with_nothing_left_starts_no_cluster(llvm, tmp_path, monkeypatch):
    setting = {"marble.period": [1.0, 2.0]}
    sweeps.sweep(small(8), setting, tmp_path, spp=1)

    def no_cluster(*args, **kwargs):
        raise AssertionError("a LocalCluster was started for no frame")
    monkeypatch.setattr(sweep_cluster, "local_cluster", no_cluster)
    index = sweeps.sweep(small(8), setting, tmp_path, spp=1, workers=2)
    assert index["summary"]["already_done"] == 2


def test_a_failing_frame_is_recorded_and_the_sweep_goes_on(llvm, tmp_path, monkeypatch):
    # The sweep refuses octaves 70 up front (the parameter table's range), so the second
    # frame's scene gets it behind the check, unchecked: the plugin refuses it then.
    original = sweeps.render_frame

    def octaves_70_in_frame_1(job):
        if job["index"] == 1:
            job = dict(job, scene=with_marbles(job["scene"], octaves=70))
        return original(job)
    monkeypatch.setattr(sweeps, "render_frame", octaves_70_in_frame_1)
    index = sweeps.sweep(small(), {"marble.octaves": [2, 4, 3]}, tmp_path, spp=1)
    assert [f["status"] for f in index["frames"]] == ["done", "failed", "done"]
    error = index["frames"][1]["error"]
    assert "octaves" in error and "70" in error and "\n" not in error
    assert not (tmp_path / index["frames"][1]["file"]).exists()


def test_another_sweeps_folder_is_refused(llvm, tmp_path):
    sweeps.sweep(small(), {"marble.period": [1.0]}, tmp_path, spp=1)
    with pytest.raises(sweep_settings.SweepError, match="another sweep"):
        sweeps.sweep(small(), {"marble.period": [2.0]}, tmp_path, spp=1)


def test_a_local_cluster_of_two_workers_renders_the_same_images(llvm, tmp_path):
    pytest.importorskip("distributed")
    scene, setting = small(), {"marble.period": [0.5, 1.0, 1.5], "marble.octaves": [3, 4]}
    here = sweeps.sweep(scene, setting, tmp_path / "here", spp=1)
    there = sweeps.sweep(scene, setting, tmp_path / "there", spp=1, workers=2)
    assert [f["status"] for f in there["frames"]] == ["done"] * 6
    for a, b in zip(here["frames"], there["frames"]):
        assert np.array_equal(png(tmp_path / "here" / a["file"]), png(tmp_path / "there" / b["file"]))


def test_the_command_checks_its_settings_before_any_work(tmp_path):
    env = dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb")
    result = subprocess.run([sys.executable, "-m", "mimarble", "sweep", "scenes/fig11a.scene",
                             "--set", "marble.perod=1,2", "-o", str(tmp_path / "out")],
                            cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 2 and "unknown key" in result.stderr
    assert "Traceback" not in result.stderr and not (tmp_path / "out").exists()
    result = subprocess.run([sys.executable, "-m", "mimarble", "sweep", "scenes/fig11a.scene",
                             "--set", "marble.period=1,2", "--width", "16", "--height", "16",
                             "-o", str(tmp_path / "out")],
                            cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "0000_period-1.png", "0001_period-2.png", "contact.png", "sweep.json"]


def test_values_are_checked_and_numpy_values_taken(llvm, tmp_path):
    scene = small()
    for key, value, words in (("marble.function", "cosin", "function must be one of"),
                              ("marble.scale", 0.0, "scale must be > 0, found 0.0"),
                              ("marble.octaves", 70, "octaves must be in 0..64"),
                              ("camera.fov", 200.0, r"fov must be in \(0, 180\) degrees"),
                              ("image.samples", 3, "perfect square")):
        with pytest.raises(sweep_settings.SweepError, match=words):
            sweep_frames.frames(scene, sweep_settings.settings_from({key: [value]}))
    with pytest.raises(sweep_settings.SweepError, match="leave out --spp"):
        sweeps.sweep(scene, {"image.samples": [1, 4]}, tmp_path / "a", spp=1)
    index = sweeps.sweep(scene, {"marble.octaves": np.arange(2, 4)}, tmp_path / "b", spp=1)
    assert [f["values"]["marble.octaves"] for f in index["frames"]] == [2, 3]


def test_a_frame_whose_image_cannot_be_written_fails_alone(llvm, tmp_path):
    (tmp_path / "0001_period-2.png").mkdir()          # the image's name is taken by a folder
    index = sweeps.sweep(small(), {"marble.period": [1.0, 2.0, 3.0]}, tmp_path, spp=1)
    assert [f["status"] for f in index["frames"]] == ["done", "failed", "done"]
    assert index["frames"][1]["error"].startswith("writing the image")
    assert (tmp_path / "contact.png").exists()        # the failed cell is drawn grey


def test_a_resumed_sweep_must_be_the_same_scene_at_the_same_size(llvm, tmp_path):
    sweeps.sweep(small(24), {"marble.period": [1.0]}, tmp_path, spp=1)
    with pytest.raises(sweep_settings.SweepError, match="another sweep"):
        sweeps.sweep(small(32), {"marble.period": [1.0]}, tmp_path, spp=1)


def test_compare_records_each_frames_error_against_the_reference(llvm, tmp_path):
    index = sweeps.sweep(small(16), {"marble.period": [1.0, 2.0]}, tmp_path, spp=1, compare=True)
    for frame in index["frames"]:
        assert frame["psnr"] > 100 and frame["rmse"] < 1e-4   # whitted agrees with the reference


def test_a_running_scheduler_is_joined_by_its_address(llvm, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        index = sweeps.sweep(small(16), {"marble.period": [1.0, 2.0]}, tmp_path, spp=1,
                             scheduler=cluster.scheduler_address)
    assert [f["status"] for f in index["frames"]] == ["done", "done"]
    with pytest.raises(sweep_settings.SweepError, match="cannot start or reach"):
        sweeps.sweep(small(16), {"marble.period": [1.0]}, tmp_path / "x", spp=1,
                     scheduler="tcp://127.0.0.1:9")
