"""Large renders in passes: the same image as ``mi.render``, bounded memory, progress (issue 11)."""

import dataclasses
import gc
import importlib
import io
import warnings

import numpy as np
import pytest

import mimarble
from mimarble.cli import main as cli
from mimarble import reference
from mimarble.runtime import progress as progress_module
from mimarble.mitsuba.rendering import image_output, passes
from mimarble.scene.edits import resized

dr, mi = mimarble.dr, mimarble.mi
render_module = importlib.import_module("mimarble.mitsuba.rendering.render")   # the module, not the function


def loaded(size, spp, mode="whitted", path="scenes/fig11a.scene", height=None):
    scene = resized(mimarble.scene.load(path), size)
    if height is not None:
        scene = dataclasses.replace(scene, image=dataclasses.replace(scene.image, height=height))
    return scene, mi.load_dict(mimarble.to_mitsuba(scene, mode=mode, spp=spp))


# ---------------------------------------------------------------------------
# whitted: the passes give Mitsuba's own image

@pytest.mark.parametrize("size, height, spp, pass_samples", [
    (24, None, 1, 97),        # ragged last pass; spp 1 is bit-identical
    (23, 17, 4, 1000),        # not square, a ragged last pass
    (24, None, 9, 77),        # passes of 8 pixels and a ragged one
    (8, None, 4, 3),          # each pixel's 4 samples split over two passes (3 + 1)
])
def test_passes_give_mitsubas_whitted_image(jit_variant, size, height, spp, pass_samples):
    scene, mitsuba_scene = loaded(size, spp, height=height)
    expected = np.array(mi.render(mitsuba_scene), dtype=np.float32)[..., :3]
    image = render_module.render_in_passes(mitsuba_scene, spp, "whitted", pass_samples=pass_samples)
    assert image.shape == expected.shape and image.dtype == np.float32
    # Measured: spp 1 equal bit for bit; spp 4, 9, 16 differ by 1-2 float32 ulps (≤ 2.4e-7)
    # in some pixels: Mitsuba's image block sums samples in float32, the passes in float64.
    np.testing.assert_allclose(image, expected, rtol=0, atol=1e-6)
    if spp == 1:
        assert np.array_equal(image, expected)
    assert expected.mean() > 0.05


def test_every_full_pass_reuses_one_compiled_kernel(llvm):
    _, mitsuba_scene = loaded(40, 4)
    render_module.render_in_passes(mitsuba_scene, 4, pass_samples=1600)             # compiles
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        render_module.render_in_passes(mitsuba_scene, 4, pass_samples=1600)         # 4 passes
        history = dr.kernel_history()
    assert len(history) >= 4
    assert not [k for k in history if k.get("cache_hit") is False]


def test_render_switches_to_passes_above_the_pass_size(llvm, monkeypatch):
    scene, mitsuba_scene = loaded(20, 4)
    expected = np.array(mi.render(mitsuba_scene), dtype=np.float32)[..., :3]
    monkeypatch.setattr(passes, "PASS_SAMPLES", 300)
    calls = []
    image = mimarble.render(scene, progress=lambda done, total: calls.append((done, total)))
    np.testing.assert_allclose(image, expected, rtol=0, atol=1e-6)
    assert calls[0] == (0, 1600) and calls[-1] == (1600, 1600)
    assert len(calls) == 1 + -(-20 * 20 * 4 // 300)       # the start, then once per pass
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)


def test_one_compiled_kernel_serves_every_spp(llvm):
    """The spp is opaque (issue 17): after a render at 1 spp, renders at 4, 9 and 16 spp
    run kernels from memory, none compiled or loaded from the disk cache (through
    ``mi.render`` each spp compiled its own)."""
    # Under --jit-debug a symbolic call's code holds the number of live instances: scenes
    # of earlier tests freed in between (by the cycle collector) would change it.
    from mimarble.mitsuba.rendering.loaded_scenes import LOADED
    LOADED.clear()
    gc.collect()
    scene = loaded(16, 1)[0]
    mimarble.render(scene, spp=1)
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        images = [mimarble.render(scene, spp=spp) for spp in (4, 9, 16)]
        kernels = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    # Under --jit-debug a gather's bounds check holds its source's size as a literal: the
    # compensated sum (passes.compensated_block_sum: one lane per pixel, gathering from the
    # pixels × spp samples) compiles once per spp there, and only there.
    summing = 16 * 16 if dr.flag(dr.JitFlag.Debug) else None
    assert kernels and all(k["cache_hit"] and not k["cache_disk"] for k in kernels
                           if k["size"] != summing)
    assert all(image.mean() > 0.05 for image in images)


def test_a_one_pass_render_is_mitsubas_image(llvm):
    scene, mitsuba_scene = loaded(16, 4)
    expected = np.array(mi.render(mitsuba_scene), dtype=np.float32)[..., :3]
    np.testing.assert_allclose(mimarble.render(scene), expected, rtol=0, atol=1e-6)


# ---------------------------------------------------------------------------
# path: deterministic, and statistically Mitsuba's image

def test_path_mode_in_passes_is_deterministic_and_statistically_mitsubas(llvm):
    _, mitsuba_scene = loaded(64, 16, mode="path")
    first = render_module.render_in_passes(mitsuba_scene, 16, "path", pass_samples=10000)
    again = render_module.render_in_passes(mitsuba_scene, 16, "path", pass_samples=10000)
    assert np.array_equal(first, again)
    ours = first.astype(np.float64)
    theirs, other = (np.array(mi.render(mitsuba_scene, seed=s), dtype=np.float64)[..., :3]
                     for s in (1, 2))
    # Same mean: the difference of two independent estimates is within 4 standard errors.
    diff = ours - theirs
    assert abs(diff.mean()) < 4 * diff.std() / np.sqrt(diff.size)
    # Same noise: ours differs from a Mitsuba render as much as two Mitsuba renders do.
    ratio = np.sqrt(np.mean(diff ** 2) / np.mean((other - theirs) ** 2))
    assert 0.9 < ratio < 1.1, ratio


def test_path_mode_in_one_pass_is_mi_render(llvm):
    """The same sampler seeding, film mapping and ray weights as Mitsuba's own render loop."""
    _, mitsuba_scene = loaded(24, 4, mode="path")
    expected = np.array(mi.render(mitsuba_scene, seed=0), dtype=np.float32)[..., :3]
    image = render_module.render_in_passes(mitsuba_scene, 4, "path", pass_samples=24 * 24 * 4)
    np.testing.assert_allclose(image, expected, rtol=0, atol=1e-6)


# ---------------------------------------------------------------------------
# PNG: Mitsuba's 8-bit conversion, a band of rows at a time

def mitsuba_png_pixels(x):
    """What write_image did before bands: NaN → 0, clamp, Mitsuba's conversion of the whole."""
    clamped = np.ascontiguousarray(np.clip(np.nan_to_num(x, nan=0.0), 0, 1))
    return np.array(mi.Bitmap(clamped).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8,
                                               srgb_gamma=True))


def test_png_conversion_in_bands_is_mitsubas_conversion_of_the_whole_image(tmp_path):
    x = np.random.default_rng(1).uniform(-0.2, 1.3, (600, 70, 3)).astype(np.float32)
    x[0, :3] = [np.nan, np.inf, -np.inf]
    expected = mitsuba_png_pixels(x)
    assert np.array_equal(image_output.srgb8(x), expected)
    assert np.array_equal(image_output.srgb8(x.astype(np.float64), rows_per_band=512), expected)
    image_output.write_image(tmp_path / "x.png", x)
    assert np.array_equal(np.array(mi.Bitmap(str(tmp_path / "x.png"))), expected)
    with pytest.raises(ValueError, match="multiple of 256"):
        image_output.srgb8(x, rows_per_band=100)    # would not line up with Mitsuba's dither


def test_mitsubas_conversion_is_the_srgb_curve_dithered_by_under_one_code_value():
    """Why the 8-bit values are within ±1 of the IEC 61966-2-1 curve rounded: Mitsuba dithers."""
    x = np.random.default_rng(2).uniform(0, 1, (256, 256, 3)).astype(np.float32)
    e = x.astype(np.float64)
    exact = 255 * np.where(e <= 0.0031308, 12.92 * e, 1.055 * e ** (1 / 2.4) - 0.055)
    dithered = image_output.srgb8(x).astype(int)
    assert np.abs(dithered - exact).max() < 1.0 + 1e-3            # offsets in [−½, ½)
    assert np.mean(dithered != np.rint(exact)) > 0.1
    source, target = mi.Bitmap(x), mi.Bitmap(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, [256, 256])
    undithered = mi.StructConverter(source.struct_(), target.struct_(), True, False)
    plain = np.frombuffer(undithered.convert(x, 256), dtype=np.uint8).reshape(x.shape)
    off = plain != np.rint(exact)
    assert off.mean() < 1e-4                                       # without it: rounded
    assert np.all(np.abs(exact[off] - np.floor(exact[off]) - 0.5) < 1e-3)   # float32 ties only


# ---------------------------------------------------------------------------
# Progress

def test_reference_reports_progress_from_zero_to_the_total():
    scene = resized(mimarble.scene.load("scenes/fig10a.scene"), 16)
    calls = []
    image = reference.render(scene, spp=4, progress=lambda done, total: calls.append((done, total)))
    assert calls[0] == (0, 16 * 16 * 4) and calls[-1] == (16 * 16 * 4, 16 * 16 * 4)
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)
    for setting in (False, None, True):
        assert np.array_equal(reference.render(scene, spp=4, progress=setting), image)


class Terminal(io.StringIO):
    def isatty(self):
        return True


def render_command(tmp_path, monkeypatch, stderr=None):
    """`mimarble render` in this process, in 4 passes; what it wrote on stderr."""
    scene = tmp_path / "small.scene"
    scene.write_text(open("scenes/fig11a.scene").read())
    monkeypatch.setattr(passes, "PASS_SAMPLES", 24 * 24)
    monkeypatch.setattr(warnings, "showwarning", warnings.showwarning)   # main() replaces it
    if stderr is not None:
        monkeypatch.setattr("sys.stderr", stderr)
    status = cli.main(["render", str(scene), "--width", "24", "--height", "24", "--spp", "4",
                       "--variant", "llvm_ad_rgb", "-o", str(tmp_path / "out.png")])
    assert status == 0
    return stderr.getvalue() if stderr is not None else None


def test_cli_shows_no_progress_bar_when_stderr_is_not_a_terminal(llvm, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(progress_module, "DELAY_S", 0.0)      # however long it takes
    render_command(tmp_path, monkeypatch)
    assert capsys.readouterr().err == ""


def test_cli_shows_no_progress_bar_for_a_short_job(llvm, tmp_path, monkeypatch):
    assert render_command(tmp_path, monkeypatch, stderr=Terminal()) == ""   # under DELAY_S


def test_cli_shows_a_progress_bar_on_a_terminal_once_the_delay_is_past(llvm, tmp_path, monkeypatch):
    monkeypatch.setattr(progress_module, "DELAY_S", 0.0)
    shown = render_command(tmp_path, monkeypatch, stderr=Terminal())
    assert "render:" in shown and "/2.30k" in shown           # 24·24·4 samples, then cleared


def test_rendering_whitted_in_a_spectral_variant_is_one_sentence():
    variant = "scalar_spectral"
    if variant not in mi.variants():
        pytest.skip(f"no {variant} here")
    previous = mi.variant()
    try:
        mi.set_variant(variant)
        with pytest.raises(mimarble.EnvironmentProblem, match="whitted integrator .* RGB"):
            mimarble.render("scenes/fig10a.scene")
    finally:
        mi.set_variant(previous)
