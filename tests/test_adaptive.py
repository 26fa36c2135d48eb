"""Adaptive sampling (mimarble/mitsuba/rendering/adaptive.py): rounds of more samples where the
estimated error is, each pixel a plain render's at the spp it ends with."""


import gc

import numpy as np
import pytest

import mimarble
from mimarble import reference
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering import adaptive
from mimarble.mitsuba.rendering.passes import _traced_pass, padded_count
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.scene.rules import adaptive_problem
from mimarble.scene.edits import resized, with_marbles

from commands import mimarble_cli

dr, mi = mimarble.dr, mimarble.mi


def loaded(scene, spp=1):
    return mi.load_dict(to_mitsuba(scene, spp=spp))


def small(name="fig10d", size=40, **marble):
    scene = resized(mimarble.scene.load(f"scenes/{name}.scene"), size)
    return with_marbles(scene, **marble) if marble else scene


def rmse(a, b):
    return float(np.sqrt(np.mean(np.square(np.asarray(a, np.float64) - b))))


def test_levels_double_the_samples_per_axis_up_to_max_spp():
    assert adaptive.sample_levels(1, 64) == [1, 4, 16, 64]
    assert adaptive.sample_levels(4, 64) == [4, 16, 64]
    assert adaptive.sample_levels(1, 36) == [1, 4, 16, 36]
    assert adaptive.sample_levels(9, 9) == [9]


def test_the_estimate_falls_as_the_error_of_stratum_centres_does():
    doubt = np.array([0.0, 0.4, 0.4])
    contrast = np.array([0.8, 0.8, 0.8])
    edge = np.array([False, False, True])
    at_1 = adaptive.estimated_errors(1, doubt, contrast, edge)
    at_2 = adaptive.estimated_errors(2, doubt, contrast, edge)
    assert at_1[0] == 0.0                      # smooth and off any silhouette: no error
    assert at_1[1] == pytest.approx(adaptive.DOUBT_WEIGHT * 0.4)
    assert at_2[1] == pytest.approx(at_1[1] / 4)                  # 1/n², the midpoint rule
    assert at_1[2] == pytest.approx(adaptive.CONTRAST_WEIGHT * 0.8)   # the edge dominates
    assert at_2[2] == pytest.approx(at_1[2] / 2 ** 1.5)


def test_each_pixel_is_the_plain_render_at_the_samples_it_ended_with(llvm):
    scene = small()
    m = loaded(scene)
    result = adaptive.render_adaptive(m, 1, 0.002, 16)
    counts = {int(k): int(n) for k, n in zip(*np.unique(result.samples, return_counts=True))}
    assert set(counts) == {1, 4, 16} and counts[1] > counts[16] > 0
    for spp in counts:
        plain = render_in_passes(m, spp)
        where = result.samples == spp
        np.testing.assert_array_equal(result.image[where], plain[where])
    # The cost counts every sample traced for a pixel: each of its levels.
    assert result.traced == sum(1 + (4 if k >= 4 else 0) + (16 if k >= 16 else 0)
                                for k in result.samples.ravel())
    # Deterministic, and the same in passes of any size (pixels split across passes too).
    again = adaptive.render_adaptive(m, 1, 0.002, 16, pass_samples=8)
    np.testing.assert_array_equal(again.image, result.image)
    np.testing.assert_array_equal(again.samples, result.samples)


def test_a_lower_threshold_takes_more_samples_and_comes_closer_to_the_reference(llvm):
    scene = small(size=48)
    truth = reference.render(scene, spp=64)
    m = loaded(scene)
    coarse, fine = (adaptive.render_adaptive(m, 1, t, 64) for t in (0.02, 0.0005))
    assert fine.traced > coarse.traced
    assert rmse(fine.image, truth) < 0.6 * rmse(coarse.image, truth)
    # A threshold above every estimate is the first pass alone.
    alone = adaptive.render_adaptive(m, 1, 1e9, 64)
    np.testing.assert_array_equal(alone.image, render_in_passes(m, 1))
    assert alone.rounds == 0 and alone.traced == 48 * 48


def test_a_prefiltered_marble_of_linear_phase_is_left_alone_inside(llvm):
    """Without noise the prefilter is exact across the pixel: only silhouettes are
    refined, and the interior is the reference's (fine stripes a point sample aliases)."""
    base = small(size=40)
    stripes = with_marbles(base, distortion=0.0, period=9.0)
    prefiltered = with_marbles(stripes, filter="prefilter")
    edge = mimarble.mitsuba.rendering.silhouettes.edge_mask(loaded(stripes), 1)
    kept = adaptive.render_adaptive(loaded(prefiltered), 1, 0.001, 16)
    assert np.all(kept.samples[~edge] == 1)
    point = adaptive.render_adaptive(loaded(stripes), 1, 0.001, 16)
    assert np.mean(point.samples[~edge] > 1) > 0.2   # the aliased point samples are refined


def test_rounds_replay_their_recordings(llvm):
    gc.collect()     # earlier tests' scenes freed now, not between the renders below
    m = loaded(small(size=32))
    adaptive.render_adaptive(m, 1, 0.002, 16)
    recorded = _traced_pass.recordings
    adaptive.render_adaptive(m, 1, 0.002, 16)
    assert _traced_pass.recordings == recorded
    # Pixel lists are padded to a few sizes: lists of many lengths share a recording.
    assert {padded_count(n, 10 ** 6) for n in range(1000, 1190)} == {1024, 1218}


def test_adaptive_numbers_are_checked():
    assert adaptive_problem(0.01, 64, 1, 10, 10) is None
    for bad in (0, -1.0, float("nan"), float("inf"), True, "0.1"):
        assert "finite number > 0" in adaptive_problem(bad, 64, 1, 10, 10)
    for bad in (0, 8, 2.0, True):
        assert "perfect square" in adaptive_problem(0.01, bad, 1, 10, 10)
    assert "below the first pass" in adaptive_problem(0.01, 4, 16, 10, 10)
    assert adaptive_problem(0.01, 16384 ** 2, 1, 16384, 16384).startswith("max_spp=")
    assert adaptive_problem(np.float32(0.01), np.int64(16), 1, 10, 10) is None


def test_render_refuses_what_adaptive_sampling_cannot_do(llvm):
    scene = small(size=8)
    with pytest.raises(ValueError, match="needs mimarble's 'whitted'"):
        adaptive.render_adaptive(mi.load_dict(to_mitsuba(scene, mode="path", spp=1)), 1, 0.01)
    with pytest.raises(ValueError, match="whitted mode"):
        mimarble.render(scene, adaptive=0.01, mode="path")
    with pytest.raises(ValueError, match="not both"):
        mimarble.render(scene, adaptive=0.01, edge_spp=16)
    with pytest.raises(ValueError, match="give adaptive"):
        mimarble.render(scene, max_spp=16)
    with pytest.raises(ValueError, match="perfect square"):
        mimarble.render(scene, adaptive=0.01, max_spp=10)
    image = mimarble.render(scene, spp=1, adaptive=0.01, max_spp=4)
    assert image.shape == (8, 8, 3) and np.isfinite(image).all()


def test_the_command_line_renders_adaptively_and_says_what_is_wrong(tmp_path):
    out = tmp_path / "a.png"
    done = mimarble_cli("render", "scenes/fig10d.scene", "--width", "24", "--height", "24",
                        "--spp", "1", "--adaptive", "0.01", "--max-spp", "16", "-o", str(out))
    assert done.returncode == 0, done.stderr
    assert out.is_file() and "adaptive" in done.stdout
    bad = mimarble_cli("render", "scenes/fig10d.scene", "--adaptive", "-1", "-o",
                       str(tmp_path / "b.png"))
    assert bad.returncode == 2 and "--adaptive" in bad.stderr and "> 0" in bad.stderr
    assert "Traceback" not in bad.stderr and not (tmp_path / "b.png").exists()
    for wrong in (["--max-spp", "0"], ["--max-spp", "10"], ["--edge-spp", "16"],
                  ["--mode", "path"]):
        refused = mimarble_cli("render", "scenes/fig10d.scene", "--adaptive", "0.01", *wrong,
                               "-o", str(tmp_path / "c.png"))
        assert refused.returncode == 2 and "Traceback" not in refused.stderr, wrong
        assert refused.stderr.startswith("mimarble:"), refused.stderr


def test_progress_counts_the_samples_asked_for(llvm):
    """A pass over a pixel list pads it; the padding is not reported as done."""
    calls = []
    adaptive.render_adaptive(loaded(small(size=24)), 1, 0.002, 16,
                             progress=lambda done, total: calls.append((done, total)))
    assert all(done <= total for done, total in calls) and calls[-1][0] == calls[-1][1]
