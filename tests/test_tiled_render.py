"""Large renders in passes: the same image as ``mi.render``, bounded memory, progress (issue 11)."""

import importlib

import numpy as np
import pytest

import mimarble
from mimarble import reference
from mimarble.gallery import resized

dr, mi = mimarble.dr, mimarble.mi
passes = importlib.import_module("mimarble.mitsuba.render")   # the module, not the function


def loaded(size, spp, mode="whitted", path="scenes/fig11a.scene"):
    scene = resized(mimarble.scene.load(path), size)
    return scene, mi.load_dict(mimarble.to_mitsuba(scene, mode=mode, spp=spp))


@pytest.mark.parametrize("spp, pass_samples", [(1, 97), (4, 1000), (9, 77), (4, 3)])
def test_passes_give_mitsubas_whitted_image(jit_variant, spp, pass_samples):
    """Ragged last passes, and pixels whose samples are split over passes (4, 3)."""
    size = 8 if pass_samples < spp else 24
    scene, mitsuba_scene = loaded(size, spp)
    expected = np.array(mi.render(mitsuba_scene), dtype=np.float32)[..., :3]
    image = passes.render_in_passes(mitsuba_scene, spp, "whitted", pass_samples=pass_samples)
    assert image.shape == expected.shape and image.dtype == np.float32
    np.testing.assert_allclose(image, expected, rtol=0, atol=1e-6)
    assert expected.mean() > 0.05


def test_every_full_pass_reuses_one_compiled_kernel(llvm):
    _, mitsuba_scene = loaded(40, 4)
    passes.render_in_passes(mitsuba_scene, 4, pass_samples=1600)             # compiles
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        passes.render_in_passes(mitsuba_scene, 4, pass_samples=1600)         # 4 passes
        history = dr.kernel_history()
    assert len(history) >= 4
    assert not [k for k in history if k.get("cache_hit") is False]


def test_path_mode_in_passes_is_deterministic_and_unbiased(llvm):
    _, mitsuba_scene = loaded(32, 16, mode="path")
    expected = np.array(mi.render(mitsuba_scene), dtype=np.float64)[..., :3]
    first = passes.render_in_passes(mitsuba_scene, 16, "path", pass_samples=4096)
    again = passes.render_in_passes(mitsuba_scene, 16, "path", pass_samples=4096)
    assert np.array_equal(first, again)
    # 16 384 samples per image: the means agree to within a few standard errors.
    assert abs(first.mean() - expected.mean()) < 0.03 * expected.mean()
    assert not np.array_equal(first, expected)        # passes are seeded apart from mi.render


def test_render_switches_to_passes_above_the_pass_size(llvm, monkeypatch):
    scene, mitsuba_scene = loaded(20, 4)
    expected = np.array(mi.render(mitsuba_scene), dtype=np.float32)[..., :3]
    monkeypatch.setattr(passes, "PASS_SAMPLES", 300)
    calls = []
    image = mimarble.render(scene, progress=lambda done, total: calls.append((done, total)))
    np.testing.assert_allclose(image, expected, rtol=0, atol=1e-6)
    assert len(calls) == -(-20 * 20 * 4 // 300) and calls[-1] == (1600, 1600)
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)


def test_reference_reports_progress_up_to_the_total():
    scene = resized(mimarble.scene.load("scenes/fig10a.scene"), 16)
    calls = []
    reference.render(scene, spp=4, progress=lambda done, total: calls.append((done, total)))
    assert calls and calls[-1] == (16 * 16 * 4, 16 * 16 * 4)
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)


def test_srgb8_is_the_exact_transfer_curve_rounded():
    x = np.random.default_rng(1).uniform(-0.2, 1.3, (300, 200, 3)).astype(np.float32)
    x[0, :3] = [np.nan, np.inf, -np.inf]
    ours = passes.srgb8(x, rows_per_chunk=7)
    e = np.clip(np.nan_to_num(x.astype(np.float64), nan=0.0), 0.0, 1.0)
    exact = np.rint(255 * np.where(e <= 0.0031308, 12.92 * e, 1.055 * e ** (1 / 2.4) - 0.055))
    off = ours.astype(int) != exact
    assert ours.dtype == np.uint8 and off.mean() < 1e-4      # float32 ties only
    assert np.abs(ours.astype(int) - exact).max() <= 1
    # Mitsuba's own converter approximates the curve: one code value apart at most.
    clamped = np.ascontiguousarray(np.clip(np.nan_to_num(x, nan=0.0), 0, 1))
    theirs = np.array(mi.Bitmap(clamped).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8,
                                                 srgb_gamma=True))
    assert np.abs(theirs.astype(int) - ours).max() <= 1


def test_rendering_in_a_non_rgb_variant_is_one_sentence():
    variant = "scalar_spectral"
    if variant not in mi.variants():
        pytest.skip(f"no {variant} here")
    previous = mi.variant()
    try:
        mi.set_variant(variant)
        with pytest.raises(mimarble.EnvironmentProblem, match="not an RGB variant"):
            mimarble.render("scenes/fig10a.scene")
    finally:
        mi.set_variant(previous)
