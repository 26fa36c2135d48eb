"""Adaptive sampling (mimarble/mitsuba/rendering/adaptive.py): rounds of more samples where the
estimated error is, each pixel a plain render's at the spp it ends with."""


import gc

import numpy as np
import pytest

import mimarble
from mimarble import reference
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering import adaptive
from mimarble.mitsuba.rendering.passes import traced_pass, padded_count
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.scene.rules import adaptive_problem
from mimarble.scene.edits import resized, with_image_size, with_marbles

from commands import mimarble_cli

dr, mi = mimarble.dr, mimarble.mi


def loaded(scene, spp=1):
    return mi.load_dict(to_mitsuba(scene, spp=spp))


def small(name="fig10d", size=40, **marble):
    scene = resized(mimarble.scene.load(f"scenes/{name}.scene"), size)
    return with_marbles(scene, **marble) if marble else scene


def rmse(a, b):
    return float(np.sqrt(np.mean(np.square(np.asarray(a, np.float64) - b))))


def test_levels_take_the_samples_to_nine_times_and_keep_them_up_to_max_spp():
    assert adaptive.sample_levels(1, 81) == [1, 9, 81]
    assert adaptive.sample_levels(1, 64) == [1, 9, 27, 64]     # a third of the way, then 64
    assert adaptive.sample_levels(4, 64) == [4, 36, 64]
    assert adaptive.sample_levels(1, 16) == [1, 9, 16]
    assert adaptive.sample_levels(1, 4) == [1, 4]
    levels = adaptive.ladder(1, 64)
    # A round into a level traces what it adds; the last one (its own grid) replaces.
    assert [level.traced for level in levels] == [1, 8, 18, 64]
    assert [level.parent for level in levels] == [0, 1, 3, 0]
    assert [level.grid for level in levels] == [1, 3, 9, 8]


def test_levels_in_thirds_triple_the_samples(monkeypatch):
    monkeypatch.setattr(adaptive, "THIRDS", True)
    assert adaptive.sample_levels(1, 81) == [1, 3, 9, 27, 81]
    assert adaptive.sample_levels(1, 64) == [1, 3, 9, 27, 64]     # 64 off the ladder: last
    assert adaptive.sample_levels(4, 64) == [4, 12, 36, 64]
    assert adaptive.sample_levels(1, 4) == [1, 4]
    assert adaptive.sample_levels(9, 9) == [9]
    levels = adaptive.ladder(1, 64)
    # A round into a level traces what it adds; the last one (its own grid) replaces.
    assert [level.traced for level in levels] == [1, 2, 6, 18, 64]
    assert [level.parent for level in levels] == [0, 1, 1, 3, 0]
    assert [level.grid for level in levels] == [1, 3, 3, 9, 8]


def test_a_nested_grid_adds_the_strata_its_coarser_grid_lacks(llvm):
    """The new strata of the rounds into 3m² and 9m² samples and the m² kept centres are
    the (3m)² strata once each; the kept ones are the m grid's centres, and the 2 a cell
    gets first are symmetric about its centre (independent arithmetic in NumPy)."""
    from mimarble.mitsuba.rendering.pixel_tracer import nested_stratum
    for m in (1, 2, 3):
        for parity in (0, 1):
            def strata(per_cell, offset):
                new = dr.arange(mi.UInt32, per_cell * m * m)
                column, row = nested_stratum(new, m, per_cell, dr.opaque(mi.UInt32, offset),
                                             dr.full(mi.UInt32, parity, dr.width(new)))
                return (row * 3 * m + column).numpy()
            pairs, rest = strata(2, 0).astype(np.int64), strata(6, 2).astype(np.int64)
            rows, columns = np.divmod(np.arange(m * m), m)
            kept = (3 * rows + 1) * 3 * m + 3 * columns + 1
            every = np.concatenate([kept, pairs, rest])
            assert sorted(every.tolist()) == list(range(9 * m * m))
            # The round to 9m² in one (8 a cell): the same strata.
            at_once = np.concatenate([kept, strata(8, 0).astype(np.int64)])
            assert sorted(at_once.tolist()) == list(range(9 * m * m))
            # Their centres coincide: (i + ½)/m = (3i + 1 + ½)/3m.
            assert np.allclose((columns + 0.5) / m, (kept % (3 * m) + 0.5) / (3 * m))
            # Each cell's pair: symmetric about its centre, on a diagonal.
            y, x = np.divmod(pairs.reshape(m * m, 2), 3 * m)
            assert np.all(x.sum(axis=1) == 2 * (3 * columns + 1))
            assert np.all(y.sum(axis=1) == 2 * (3 * rows + 1))
            assert np.all(np.abs(x[:, 0] - x[:, 1]) == 2) and np.all(np.abs(y[:, 0] - y[:, 1]) == 2)


def test_the_estimate_falls_as_the_error_of_stratum_centres_does(llvm):
    f64 = mi.Float64
    doubt, spread = f64([0.0, 0.4, 0.4, 0.0]), f64([0.0, 0.0, 0.0, 0.6])
    contrast = f64([0.8, 0.8, 0.8, 0.0])
    edge = mi.Bool([False, False, True, False])
    at_1, at_3 = (adaptive.estimated_errors(n, doubt, spread, contrast, edge).numpy()
                  for n in (1, 3))          # 1 and 9 samples
    assert at_1[0] == 0.0                      # smooth and off any silhouette: no error
    assert at_1[1] == pytest.approx(adaptive.DOUBT_WEIGHT * 0.4)
    assert at_3[1] == pytest.approx(at_1[1] / 9)                  # 1/n², the midpoint rule
    assert at_1[2] == pytest.approx(adaptive.CONTRAST_WEIGHT * 0.8)   # the edge dominates
    assert at_3[2] == pytest.approx(at_1[2] / 3 ** 1.5)
    # A pixel's own spread is read once it has SPREAD_SAMPLES samples, not at 1.
    assert at_1[3] == 0.0 and adaptive.SPREAD_SAMPLES <= 9
    assert at_3[3] == pytest.approx(adaptive.SPREAD_WEIGHT * 0.6 / 9)


def test_each_pixel_is_the_plain_render_at_the_samples_it_ended_with(llvm):
    """Rounds add samples: a pixel's 1 centre is among its 9, its 9 among its 81, and the
    mean of point-sampled marble is the plain render's at that spp, bit for bit."""
    scene = small()
    m = loaded(scene)
    result = adaptive.render_adaptive(m, 1, 3e-5, 81, jump="never")
    counts = {int(k): int(n) for k, n in zip(*np.unique(result.samples, return_counts=True))}
    assert {1, 9, 81} <= set(counts) and min(counts.values()) > 0
    for spp in (1, 9, 81):
        plain = render_in_passes(m, spp)
        where = result.samples == spp
        np.testing.assert_array_equal(result.image[where], plain[where])
    # The cost counts every sample traced for a pixel once: kept ones are not traced again.
    assert result.traced == int(result.samples.sum())
    # Deterministic, and the same in passes of any size (pixels split across passes too).
    again = adaptive.render_adaptive(m, 1, 3e-5, 81, pass_samples=8, jump="never")
    np.testing.assert_array_equal(again.image, result.image)
    np.testing.assert_array_equal(again.samples, result.samples)
    # A level off the ladder (16 after 9) replaces: the plain render's again, at a cost.
    off = adaptive.render_adaptive(m, 1, 1e-6, 16, jump="never")
    where = off.samples == 16
    assert where.any()
    np.testing.assert_array_equal(off.image[where], render_in_passes(m, 16)[where])
    assert off.traced == int(np.sum(np.where(off.samples == 16, 9 + 16, off.samples)))


def test_levels_after_a_jump_to_the_four_by_four_grid():
    """A pixel the first round sends to 16 samples (the 4×4 grid, replacing its 1) goes on
    to 144 (the 12×12 grid keeps the 4×4 centres) or to max_spp's own grid."""
    levels = adaptive.jump_ladder(1, 144)
    assert [level.spp for level in levels] == [1, 16, 144]
    assert [level.traced for level in levels] == [1, 16, 128]
    assert [level.parent for level in levels] == [0, 0, 4]
    assert adaptive.sample_levels(16, 144) == [16, 144]
    assert [level.spp for level in adaptive.jump_ladder(1, 81)] == [1, 16, 81]
    assert [level.traced for level in adaptive.jump_ladder(1, 81)] == [1, 16, 81]
    assert [level.spp for level in adaptive.jump_ladder(4, 576)] == [4, 64, 576]
    assert adaptive.jump_ladder(1, 9) is None


def test_a_jumped_pixel_is_the_plain_render_at_its_samples(llvm):
    """Every pixel the first round refines sent to 16 (``jump="always"``): each is the
    plain 16-spp render's bit for bit, the others the plain 1-spp render's, and the cost
    counts the first sample it dropped; at 81 after 16 (max_spp's grid, replacing
    again) the plain 81-spp render's, at 1 + 16 + 81 traced."""
    m = loaded(small())
    result = adaptive.render_adaptive(m, 1, 3e-5, 81, jump="always", rounds=1)
    at_16 = result.samples == 16
    assert 0 < at_16.mean() < 1 and np.all(result.samples[~at_16] == 1)
    np.testing.assert_array_equal(result.image[at_16], render_in_passes(m, 16)[at_16])
    np.testing.assert_array_equal(result.image[~at_16], render_in_passes(m, 1)[~at_16])
    assert result.traced == result.samples.size + 16 * int(at_16.sum())
    deeper = adaptive.render_adaptive(m, 1, 3e-5, 81, jump="always")
    at_81 = deeper.samples == 81
    assert at_81.any() and set(np.unique(deeper.samples)) <= {1, 16, 81}
    np.testing.assert_array_equal(deeper.image[at_81], render_in_passes(m, 81)[at_81])
    assert deeper.traced == deeper.samples.size + 16 * int(np.sum(deeper.samples > 1)) \
        + 81 * int(at_81.sum())


def test_a_pixel_of_three_samples_is_its_centre_and_a_symmetric_pair(llvm, monkeypatch):
    """At 3 samples a pixel holds its centre and two points of the 3×3 grid symmetric
    about it: the pair's mean, from a plain 9-spp render's strata traced one by one
    (1-spp renders of a 3× larger image, whose pixel centres are those strata), is
    (3·adaptive − plain 1)/2."""
    monkeypatch.setattr(adaptive, "THIRDS", True)
    scene = small(size=24)
    m = loaded(scene)
    result = adaptive.render_adaptive(m, 1, -1.0, 9, rounds=1)     # every pixel: a bar < 0
    assert np.all(result.samples == 3)
    strata = render_in_passes(loaded(resized(scene, 72)), 1)       # (72, 72, 3)
    y, x = np.mgrid[0:24, 0:24]
    main = (x + y) % 2 == 0            # the diagonals alternate from pixel to pixel
    first = np.where(main[..., None], strata[3 * y, 3 * x], strata[3 * y, 3 * x + 2])
    second = np.where(main[..., None], strata[3 * y + 2, 3 * x + 2], strata[3 * y + 2, 3 * x])
    expected = (render_in_passes(m, 1) + first + second) / 3
    off = np.abs(result.image - expected).max(axis=-1)
    assert np.median(off) < 1e-6 and np.mean(off < 1e-4) > 0.97


def test_a_prefiltered_pixel_keeps_its_first_sample_with_its_wider_footprint(llvm):
    """A filtered marble averages a sample over 1/√spp of the pixel: the centre a pixel
    keeps from its 1-spp pass has the whole pixel's footprint, where a plain 9-spp render's
    has a third of it. So adaptive(9) = plain(9) + (plain(1) − c₉)/9, c₉ the centre at a
    third of the footprint — the centre pixels of a plain 1-spp render at 3× the size."""
    scene = small(size=30, filter="prefilter")
    m = loaded(scene)
    result = adaptive.render_adaptive(m, 1, 1e-6, 9)
    where = result.samples == 9
    assert where.sum() > 50
    finer = render_in_passes(loaded(resized(scene, 90)), 1)[1::3, 1::3]
    expected = render_in_passes(m, 9) + (render_in_passes(m, 1) - finer) / 9
    # Equal to float32 rounding of the film positions (the larger image's pixel centres
    # are computed otherwise) but where a position's rounding meets a vein or an edge.
    off = np.abs(result.image - expected).max(axis=-1)[where]
    assert np.median(off) < 1e-5 and np.mean(off < 1e-4) > 0.97
    # … and it is not the plain render's: the footprints do differ.
    plain_off = np.abs(result.image - render_in_passes(m, 9)).max(axis=-1)[where]
    assert np.median(plain_off) > 30 * np.median(off) and plain_off.max() > 1e-3


def test_a_lower_threshold_takes_more_samples_and_comes_closer_to_the_reference(llvm):
    scene = small(size=48)
    truth = reference.render(scene, spp=64)
    m = loaded(scene)
    coarse, fine = (adaptive.render_adaptive(m, 1, t, 81) for t in (0.02, 0.0005))
    assert fine.traced > coarse.traced
    assert rmse(fine.image, truth) < 0.6 * rmse(coarse.image, truth)
    # A threshold above every estimate is the first pass alone.
    alone = adaptive.render_adaptive(m, 1, 1e9, 81)
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
    recorded = traced_pass.recordings
    adaptive.render_adaptive(m, 1, 0.002, 16)
    assert traced_pass.recordings == recorded
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


def _image_doubt(image, share):
    """The test's own doubt of a plain 1-spp image (float64), per pixel: its second
    difference — the 3×3 neighbourhood, clipped at the border (the edge row or column
    again), summed, less 9 times the pixel, over 8 — or, where larger, ``share`` times
    its largest absolute step to a neighbour; each the largest over the colours. Also
    whether the step's term is the larger anywhere (else a test of it proves nothing)."""
    padded = np.pad(np.asarray(image, np.float64), ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = image.shape[:2]
    around = [padded[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
              for dy in (-1, 0, 1) for dx in (-1, 0, 1)]
    second = np.abs(sum(around) - 9.0 * image).max(axis=2) / 8.0
    step = share * np.max([np.abs(a - image).max(axis=2) for a in around], axis=0)
    return np.maximum(second, step), bool((step > second).any())


@pytest.mark.parametrize("width, height, share", [(23, 17, 0.0), (23, 17, 0.25), (1, 1, 0.25),
                                                  (2, 5, 0.25)])
def test_the_first_round_refines_where_the_images_doubt_says(llvm, monkeypatch, width, height,
                                                             share):
    """After a plain first pass (a point-sampled marble: no doubt kernel) a pixel's doubt
    is read from the first image (``refine``), weighed by CURVATURE_WEIGHT:
    E = CURVATURE_WEIGHT · max(second, DEVIATION_SHARE · step) at 1 sample (second:
    |Σ₃ₓ₃ − 9·pixel| / 8; step: the largest |neighbour − pixel|). With the silhouette's
    term off, the pixels the first round takes to 9 are those whose E, from the test's
    own doubt of a plain 1-spp render, is above the threshold (odd sizes, and images of
    one pixel or one column: the clipped borders; share 0: the second difference alone)."""
    monkeypatch.setattr(adaptive, "CONTRAST_WEIGHT", 0.0)
    monkeypatch.setattr(adaptive, "DEVIATION_SHARE", share)
    scene = with_image_size(small(size=max(width, height)), width, height)
    m = loaded(scene)
    assert not adaptive.traces_doubts(m)
    doubt, step_counts = _image_doubt(render_in_passes(m, 1), share)
    errors = adaptive.CURVATURE_WEIGHT * doubt
    if share and errors.size > 10:
        assert step_counts
    for threshold in np.quantile(errors, [0.3, 0.7]) if errors.size > 1 else [0.0]:
        result = adaptive.render_adaptive(m, 1, float(threshold), 9, rounds=1)
        refined = result.samples == 9
        assert np.all(result.samples[~refined] == 1)
        # float32 sums in the kernel, float64 here: a margin of 1e-4 relative.
        assert refined[errors > threshold * (1 + 1e-4)].all()
        assert not refined[errors < threshold * (1 - 1e-4)].any()
    if errors.size > 1:
        assert 0 < np.mean(result.samples == 9) < 1


def test_the_first_round_jumps_where_the_band_of_the_estimate_says(llvm, monkeypatch):
    """With max_spp 16 a pixel the first round refines goes to 16 samples (the 4×4 grid)
    when its E over the bar is in JUMP's band (3^q, 2·4^q], q = 2 + BAR_POWER — the 3×3
    grid would leave it over the bar at 9 under the estimate's 1/n² law, the 4×4 one by at
    most 2 — and to 9 when it
    is above the band or below it; E from the test's own doubt of a plain 1-spp render
    (silhouettes off)."""
    monkeypatch.setattr(adaptive, "CONTRAST_WEIGHT", 0.0)
    monkeypatch.setattr(adaptive, "JUMP_LEAST", 0)      # a 40² image: few jump
    m = loaded(small(size=40, period=6.0))
    doubt, _ = _image_doubt(render_in_passes(m, 1), adaptive.DEVIATION_SHARE)
    errors = adaptive.CURVATURE_WEIGHT * doubt
    low, high = adaptive.JUMP
    q = 2 + adaptive.BAR_POWER
    assert (low, high) == (3.0 ** q, 2 * 4.0 ** q)
    # A threshold that puts the band across the errors' spread: every kind present.
    threshold = float(np.quantile(errors, 0.97)) / high
    result = adaptive.render_adaptive(m, 1, threshold, 16, rounds=1)
    ratio, margin = errors / threshold, 1 + 1e-4
    jumped = (ratio > low * margin) & (ratio < high / margin)
    nine = (ratio > margin) & ((ratio < low / margin) | (ratio > high * margin))
    assert jumped.sum() > 5 and nine.sum() > 5 and (ratio > high * margin).sum() > 0
    assert np.all(result.samples[jumped] == 16) and np.all(result.samples[nine] == 9)
    assert np.all(result.samples[ratio < 1 / margin] == 1)
    # Fewer than JUMP_LEAST to jump: they go to 9 with the others (one pass, not two).
    monkeypatch.setattr(adaptive, "JUMP_LEAST", int(jumped.sum()) + 100)
    merged = adaptive.render_adaptive(m, 1, threshold, 16, rounds=1)
    np.testing.assert_array_equal(merged.samples, np.where(result.samples > 1, 9, 1))


def test_a_jumped_pixel_goes_on_over_its_own_bar(llvm, monkeypatch):
    """After the jump to 16 a pixel goes on to 81 (max_spp 81: the 9×9 grid) only over
    JUMPED_BAR times the ladder's bar. The jump's 16 replaces the pixel's samples and with
    them the first pass's doubt, so its own spread sends it on (silhouettes off here):
    with JUMPED_BAR 1 some jumped pixels go on, with JUMPED_BAR none; every pixel the
    bar is not about (not jumped) ends alike, and the default sends on a subset of what 1
    does."""
    monkeypatch.setattr(adaptive, "CONTRAST_WEIGHT", 0.0)
    monkeypatch.setattr(adaptive, "SPREAD_WEIGHT", 0.5)   # a spread that can send them on
    monkeypatch.setattr(adaptive, "JUMP_LEAST", 0)
    m = loaded(small(size=40, period=6.0))
    doubt, _ = _image_doubt(render_in_passes(m, 1), adaptive.DEVIATION_SHARE)
    errors = adaptive.CURVATURE_WEIGHT * doubt
    low, high = adaptive.JUMP
    threshold = float(np.quantile(errors, 0.97)) / high
    runs = {}
    for bar in (1.0, adaptive.JUMPED_BAR, 1e30):
        monkeypatch.setattr(adaptive, "JUMPED_BAR", bar)
        runs[bar] = adaptive.render_adaptive(m, 1, threshold, 81, rounds=2).samples
    ratio, margin = errors / threshold, 1 + 1e-4
    jumped = (ratio > low * margin) & (ratio < high / margin)
    assert jumped.sum() > 5 and np.all(runs[1e30][jumped] == 16)
    assert np.isin(runs[1.0][jumped], (16, 81)).all() and (runs[1.0][jumped] == 81).sum() > 0
    far = runs[1e30] != 16                        # not jumped: the bar is not theirs
    for samples in runs.values():
        np.testing.assert_array_equal(samples[far], runs[1e30][far])
    default = list(runs.values())[1]
    assert np.all(runs[1.0][default == 81] == 81)


def test_a_crop_refines_its_pixels_as_the_whole_image_does(llvm, monkeypatch):
    """A crop is traced with a ring of one pixel, so its pixels' first-round estimates
    (the image's second difference, the silhouette's contrast) read the whole image's
    neighbourhoods: after one round each pixel of the crop has the samples and the value
    it has in the whole image, bit for bit — at the image's border, inside, and 1×1."""
    scene = with_image_size(small(size=29), 29, 21)
    m = loaded(scene)
    whole = adaptive.render_adaptive(m, 1, 2e-4, 9, rounds=1)
    assert 0 < np.mean(whole.samples == 9) < 1
    for crop in ((0, 0, 11, 7), (5, 4, 24, 19), (13, 10, 14, 11), (20, 14, 29, 21)):
        x0, y0, x1, y1 = crop
        part = adaptive.render_adaptive(m, 1, 2e-4, 9, crop=crop, rounds=1)
        np.testing.assert_array_equal(part.samples, whole.samples[y0:y1, x0:x1])
        np.testing.assert_array_equal(part.image, whole.image[y0:y1, x0:x1])
    # With the first round's jump to 16 (every jump a pass, however few), alike.
    monkeypatch.setattr(adaptive, "JUMP_LEAST", 0)
    whole = adaptive.render_adaptive(m, 1, 2e-5, 16, rounds=1)
    assert {1, 9, 16} <= set(np.unique(whole.samples))
    for crop in ((0, 0, 11, 7), (5, 4, 24, 19)):
        x0, y0, x1, y1 = crop
        part = adaptive.render_adaptive(m, 1, 2e-5, 16, crop=crop, rounds=1)
        np.testing.assert_array_equal(part.samples, whole.samples[y0:y1, x0:x1])
        np.testing.assert_array_equal(part.image, whole.image[y0:y1, x0:x1])


def test_the_default_max_spp_is_81_or_the_first_pass_when_more():
    from mimarble.scene.rules import default_max_spp
    assert (default_max_spp(1), default_max_spp(100), default_max_spp(1, 16)) == (81, 100, 16)


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


def test_the_morton_order_interleaves_the_bits_of_x_and_y():
    """Against the definition, bit by bit in Python: pixel (x, y)'s code has x's bit k at
    2k and y's at 2k + 1; the order is every pixel once, by code (ties cannot occur)."""
    from mimarble.mitsuba.rendering.adaptive import morton_order
    width, height = 37, 23

    def code(x, y):
        return sum(((x >> k) & 1) << 2 * k | ((y >> k) & 1) << 2 * k + 1 for k in range(16))

    expected = sorted(range(width * height), key=lambda i: code(i % width, i // width))
    assert morton_order(width, height).tolist() == expected


def test_an_adaptive_render_traced_without_replay_is_the_replayed_one(llvm, monkeypatch):
    """``MIMARBLE_FREEZE=0`` traces every pass: a pass of one sample then hands back one
    array as its least and largest colour (and shape), which the pixel state must not hold
    as one (a scatter into either would change both, the spread 0 and the rounds other):
    samples, traced counts and image bit for bit the replayed render's, over rounds that
    keep, jump and replace samples."""
    monkeypatch.setattr(adaptive, "JUMP_LEAST", 0)
    m = loaded(small(size=29))
    replayed = adaptive.render_adaptive(m, 1, 2e-5, 81)
    assert {1, 9, 16} <= set(np.unique(replayed.samples)) and replayed.rounds >= 2
    monkeypatch.setenv("MIMARBLE_FREEZE", "0")
    traced = adaptive.render_adaptive(m, 1, 2e-5, 81)
    np.testing.assert_array_equal(traced.samples, replayed.samples)
    assert traced.traced == replayed.traced
    np.testing.assert_array_equal(traced.image, replayed.image)
