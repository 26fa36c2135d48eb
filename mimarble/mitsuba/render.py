"""Rendering a scene through Mitsuba, and writing images whole or not at all."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from .. import environment
from .. import scene as scene_language
from ..image_formats import IMAGE_FORMATS
from ..progress import report
from .translate import to_mitsuba

dr, mi = environment.import_drjit_and_mitsuba()

#: Samples traced at once. A lane of fig11a costs about 85 bytes in whitted and in
#: path mode (measured), so a pass of 2²² samples holds ~0.35 GiB; larger images are
#: rendered in passes of whole pixels (docs/design-decisions.md, "Rendering").
PASS_SAMPLES = 1 << 22


def render(scene_or_path, spp: int | None = None, mode: str = "whitted",
           progress=False, tolerance: float | None = None) -> np.ndarray:
    """Render a scene (model, or path of a scene file) → linear float32 (H, W, 3).

    Memory is the image plus a bounded working set whatever the size and spp:
    JIT variants render in passes of up to :data:`PASS_SAMPLES` samples
    (:func:`render_in_passes`; one kernel for every spp), the scalar variant
    through ``mi.render``. ``progress``: True for a
    progress bar on stderr (shown once the render has taken 1.5 s), or a
    callable ``progress(samples_done, samples_total)``. ``tolerance``: every
    marble's error budget (colour units, 0 = every octave; default: each marble's
    own, else the scene's, see ``to_mitsuba``).
    """
    environment.require_rgb_variant()
    scene = scene_or_path
    if isinstance(scene_or_path, (str, os.PathLike)):
        scene = scene_language.load(scene_or_path)
    mitsuba_scene = mi.load_dict(to_mitsuba(scene, mode=mode, spp=spp, tolerance=tolerance))
    spp = scene.image.samples if spp is None else spp
    total = scene.image.width * scene.image.height * spp
    if not dr.is_jit_v(mi.Float):
        done = report(progress, "render")
        done(0, total)
        image = np.array(mi.render(mitsuba_scene), dtype=np.float32)[..., :3]
        done(total, total)
        return image
    return render_in_passes(mitsuba_scene, spp, mode, progress)


def render_in_passes(mitsuba_scene, spp: int, mode: str = "whitted", progress=False,
                     pass_samples: int | None = None) -> np.ndarray:
    """What ``mi.render`` computes, in passes of at most ``pass_samples`` samples.

    Each pass takes a run of whole pixels (or, when one pixel has more samples
    than a pass, a run of one pixel's samples) and does what Mitsuba's
    ``SamplingIntegrator.render`` does for them: film position → the sensor's
    ``sample_ray_differential`` (differentials scaled by 1/√spp) → the
    integrator's ``sample``; with the translator's ``box`` filter a pixel is
    the plain mean of its samples. Sample positions: whitted mode takes the
    n×n stratum centres (what the non-jittered ``stratified`` sampler gives, in
    another order), path mode the scene's sampler, seeded per pass.

    Every number that varies between renders of one scene structure is opaque
    (pass offsets, samples per pixel, image width and height), so a scene
    compiles one kernel for every spp and size: a new user's renders at 1, 4 and
    16 spp cost one compilation (0.45 s for fig11a on the AMD EPYC), not three,
    as they did through ``mi.render``, whose sampler and sample indexing take
    the spp as a constant. JIT variants therefore always render here, also in
    one pass.
    """
    pass_samples = PASS_SAMPLES if pass_samples is None else int(pass_samples)
    sensor = mitsuba_scene.sensors()[0]
    integrator = mitsuba_scene.integrator()
    width, height = (int(x) for x in sensor.film().crop_size())
    pixels = width * height
    whitted = mode == "whitted"
    n = int(round(spp ** 0.5))
    sampler = sensor.sampler().clone()
    image = np.empty((pixels, 3), dtype=np.float32)   # the only full-size array
    partial = np.zeros(3)                              # a pixel split over passes, so far
    done = report(progress, "render")
    samples_done, samples_total = 0, pixels * spp
    done(0, samples_total)                             # a bar's delay counts from here
    pixels_per_pass = max(1, pass_samples // spp)
    samples_per_pass = min(spp, pass_samples)
    u32, f32 = (lambda v: dr.opaque(mi.UInt32, v)), (lambda v: dr.opaque(mi.Float, v))
    columns, per_axis = u32(width), u32(n)
    # Reciprocals, as Dr.Jit makes of a division by a constant: Mitsuba's own image bit for bit.
    inv_film, inv_n = mi.Point2f(f32(1.0 / width), f32(1.0 / height)), f32(1.0 / n)
    for index, (p0, q0, n_pixels, n_samples) in enumerate(
            _passes(pixels, spp, pixels_per_pass, samples_per_pass)):
        lanes = n_pixels * n_samples
        lane = dr.arange(mi.UInt32, lanes)
        pixel = u32(p0) + lane // u32(n_samples)
        sub = u32(q0) + lane % u32(n_samples)
        y = pixel // columns
        x = pixel - y * columns
        if whitted:
            offset = (mi.Point2f(mi.Float(sub % per_axis), mi.Float(sub // per_axis)) + 0.5) * inv_n
        else:
            sampler.seed(u32(index), lanes)
            offset = sampler.next_2d()
        position = (mi.Point2f(mi.Float(x), mi.Float(y)) + offset) * inv_film
        ray, weight = sensor.sample_ray_differential(mi.Float(sensor.shutter_open()), 0.0,
                                                     position, mi.Point2f(0.5))
        if ray.has_differentials:
            ray.scale_differential(f32(1.0 / spp ** 0.5))
        radiance = integrator.sample(mitsuba_scene, sampler, ray, None, True)[0]
        sums = _pixel_sums(weight * radiance, lanes, n_samples)
        if n_samples == spp:
            image[p0:p0 + n_pixels] = sums / spp
        else:
            partial += sums[0]
            if q0 + n_samples == spp:
                image[p0] = partial / spp
                partial[:] = 0.0
        samples_done += lanes
        done(samples_done, samples_total)
    return image.reshape(height, width, 3)


def _pixel_sums(value, lanes: int, n_samples: int) -> np.ndarray:
    """Sums of each run of ``n_samples`` lanes of a Color3f, in float64 → (lanes/n_samples, 3).

    Summed by Dr.Jit (``block_sum``), so only one value per pixel comes back to
    NumPy; in float64, whose rounding is far below float32's.
    """
    value = mi.Color3d(value) + dr.zeros(mi.Color3d, lanes)   # constant channels: full width
    dr.eval(value)                                             # one kernel for all channels
    if n_samples > 1:
        value = dr.block_sum(value, n_samples)
    return np.array(value, dtype=np.float64).T


def _passes(pixels: int, spp: int, pixels_per_pass: int, samples_per_pass: int):
    """(first pixel, first sample, pixel count, samples per pixel) of each pass."""
    if samples_per_pass >= spp:
        for p0 in range(0, pixels, pixels_per_pass):
            yield p0, 0, min(pixels_per_pass, pixels - p0), spp
    else:
        for p0 in range(pixels):
            for q0 in range(0, spp, samples_per_pass):
                yield p0, q0, 1, min(samples_per_pass, spp - q0)


def write_image(path, image: np.ndarray) -> None:
    """Write linear RGB ``image`` to ``path`` (.exr: float; .png: 8-bit sRGB).

    PNG: what Mitsuba's ``Bitmap.convert(..., UInt8, srgb_gamma=True)`` makes of
    the image after NaN → 0 and clamping to [0, 1] (:func:`srgb8`), converted a
    band of rows at a time straight into the bitmap that is written, so the
    only full-size arrays are ``image`` and the 8-bit result. The file is
    written under a temporary name in the same folder and renamed into place,
    so a failure never leaves half a file.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in IMAGE_FORMATS:
        raise ValueError(f"{path}: unsupported image format {suffix or '(none)'!r}; "
                         f"use {' or '.join(IMAGE_FORMATS)}")
    if suffix == ".png":
        height, width = image.shape[:2]
        bitmap = mi.Bitmap(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, [width, height])
        srgb8(image, out=np.asarray(bitmap))     # a view of the bitmap's own pixels
    else:
        bitmap = mi.Bitmap(np.ascontiguousarray(image, dtype=np.float32))
    write_atomically(path, bitmap)


#: Mitsuba's 8-bit conversion dithers with a 256×256 threshold matrix indexed by the
#: pixel's position in the converted block: bands of a multiple of 256 rows line up with it.
DITHER_PERIOD = 256


def srgb8(image: np.ndarray, out: np.ndarray | None = None,
          rows_per_band: int = DITHER_PERIOD) -> np.ndarray:
    """Linear RGB → 8-bit sRGB, exactly as Mitsuba converts the whole image.

    NaN becomes 0 and values are clamped to [0, 1] (as ``write_image`` always
    did), then Mitsuba's ``Bitmap.convert(RGB, UInt8, srgb_gamma=True)`` applies
    the sRGB curve (IEC 61966-2-1) with its blue-noise dither (offsets in
    [−½, ½) of a code value, a 256×256 pattern), a band of ``rows_per_band``
    rows (a multiple of :data:`DITHER_PERIOD`) at a time: the result equals
    converting the whole image at once (tests/test_tiled_render.py), with only
    band-sized temporaries. ``out``: a uint8 (H, W, 3) array to fill.
    """
    if rows_per_band % DITHER_PERIOD:
        raise ValueError(f"rows_per_band={rows_per_band} must be a multiple of {DITHER_PERIOD}")
    height = image.shape[0]
    if out is None:
        out = np.empty(image.shape[:2] + (3,), dtype=np.uint8)
    for y0 in range(0, height, rows_per_band):
        # fmax/fmin: NaN → 0, and a clamp to [0, 1] (±inf → 1, 0), in two passes over the band.
        band = np.fmax(image[y0:y0 + rows_per_band, :, :3], 0.0, dtype=np.float32)
        np.fmin(band, 1.0, out=band)
        out[y0:y0 + rows_per_band] = mi.Bitmap(band).convert(
            mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True)
    return out


def write_rgb8(path, pixels: np.ndarray) -> None:
    """Write 8-bit RGB ``pixels`` (H, W, 3) to a .png as they are (no transfer curve)."""
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"{path}: 8-bit images are written as .png")
    height, width = pixels.shape[:2]
    bitmap = mi.Bitmap(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, [width, height])
    np.asarray(bitmap)[...] = pixels                   # into the bitmap's pixels: no copy
    write_atomically(path, bitmap)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


#: zlib level of the PNGs written: 1, the fastest (OpenCV's default too). Mitsuba's
#: default 5 made writing fig11a's 500² PNG 48 ms against 19 ms for a file 17 % larger
#: (193 → 226 kB; the dither leaves little to compress), on the AMD EPYC.
PNG_COMPRESSION = 1


def write_atomically(path: Path, bitmap) -> None:
    """Write under a temporary name in the same folder, then rename: whole or not at all."""
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=folder)
    os.close(fd)
    try:
        if path.suffix.lower() == ".png":
            bitmap.write(tmp, mi.Bitmap.FileFormat.PNG, PNG_COMPRESSION)
        else:
            bitmap.write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())   # mkstemp makes 0600; a new image gets the usual mode
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
