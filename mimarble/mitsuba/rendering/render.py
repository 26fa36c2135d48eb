"""Rendering a scene through Mitsuba: the scene translated and loaded, then traced in passes.

:func:`render` is ``mimarble.render``: a scene model or file in, a linear
float32 image out. JIT variants render through :func:`render_in_passes`,
which fills the image from the pass loop (mimarble/mitsuba/rendering/passes.py) and,
with edge samples, traces the silhouette pixels again
(mimarble/mitsuba/rendering/silhouettes.py); the scalar variant renders through
``mi.render``. Writing the image is mimarble/mitsuba/rendering/image_output.py's.
"""

from __future__ import annotations

import os
import warnings

import numpy as np

from mimarble.runtime import environment, packaged_scenes
from mimarble import scene as scene_language
from mimarble.mitsuba.rendering.crop import as_integers, crop_problem
from mimarble.runtime.progress import report
from mimarble.scene.python_numbers import plain_numbers
from mimarble.scene.model import samples_per_axis
from mimarble.scene.rules import (adaptive_problem, default_max_spp, seed_problem, shortened,
                                  spp_problem)
from mimarble.scene.edits import with_image_size
from .adaptive import render_adaptive
from .passes import Target, trace_in_passes
from .replay import refresh_derived
from .silhouettes import edge_sample_passes
from .loaded_scenes import LOADED
from .window import Window

dr, mi = environment.import_drjit_and_mitsuba()


def render(scene_or_path, *, spp: int | None = None, mode: str | None = None,
           progress=False, tolerance: float | None = None, filter: str | None = None,
           edge_spp: int | None = None, seed: int = 0, width: int | None = None,
           height: int | None = None, crop=None, adaptive: float | None = None,
           max_spp: int | None = None) -> np.ndarray:
    """Render a scene (model, path of a scene file — or, when no such file exists, a
    packaged scene's name such as ``"fig11a"``, as the command line takes it —, or a loaded
    ``mi.Scene``) → linear float32 (H, W, 3).

    Everything but the scene is a keyword (``mi.render``'s second argument is
    ``params``, not ``spp``). ``mode``: ``whitted`` (the default for a model or a file)
    or ``path``. A loaded ``mi.Scene`` renders as ``mi.render`` renders it — its
    integrator, film and sensor's sample count unless ``spp`` is given; with the
    ``whitted`` integrator in a JIT variant through the pass renderer below (the same
    image, in bounded memory, one kernel for every spp); ``tolerance`` and ``filter``,
    which the translator applies, are refused for it in one sentence. ``seed``: the
    sampler seed of path mode, 0..2³²−1 (whitted mode is deterministic). ``width``,
    ``height``: the image's size in pixels (each within ``mimarble.scene.LIMITS``), in place of the scene's (as the
    command line's ``--width``/``--height``: the fov is the full vertical angle, so a new
    height shows the same view at another resolution and a new width crops or extends it
    sideways); a loaded ``mi.Scene`` renders at its film's size, so they are refused for it.
    ``crop``: ``(x0, y0, x1, y1)``, a window of the image (after ``width``/``height``) —
    pixel indices from 0 at the top-left, x1 and y1 exclusive: the full render's
    ``[y0:y1, x0:x1]`` — rendered alone (:func:`render_in_passes`); a scene model or file only.

    A scene model or file is loaded once and kept by its structure
    (mimarble/mitsuba/rendering/loaded_scenes.py): another render of it, or of a scene that
    differs only in its marbles' scale, period or distortion, edits the loaded scene in
    place, and its passes replay their recorded kernels (mimarble/mitsuba/rendering/replay.py).

    Memory is the image plus a bounded working set whatever the size and spp:
    JIT variants render in passes of up to
    :data:`~mimarble.mitsuba.rendering.passes.PASS_SAMPLES` samples
    (:func:`render_in_passes`; one kernel for every spp), the scalar variant
    through ``mi.render``. ``progress``: True for a
    progress bar on stderr (shown once the render has taken 1.5 s), or a
    callable ``progress(samples_done, samples_total)``. ``tolerance``: every
    marble's error budget (colour units, 0 = every octave; default: each marble's
    own, else the scene's, see ``to_mitsuba``). ``filter``: every marble's pixel
    filter (``none``, ``bandlimit``, ``prefilter``; default: each marble's own).
    ``edge_spp``: n² stratum-centre samples for pixels on a silhouette
    (:func:`render_in_passes`; whitted mode, JIT variants; default: none).
    ``adaptive``: adaptive sampling (whitted mode, JIT variants): ``spp`` is the first pass,
    then every pixel whose estimated error is above ``adaptive`` (linear colour units, at
    1 spp; times n³ at n² samples) gets three times its samples, which keep the ones it
    has, up to ``max_spp`` (a perfect square; default 81) — mimarble/mitsuba/rendering/adaptive.py.
    It refines silhouettes itself, so it does not take ``edge_spp``. NumPy's scalars are
    taken as the Python numbers they hold (mimarble/scene/python_numbers.py).
    """
    spp, seed, width, height, tolerance, edge_spp, adaptive, max_spp = plain_numbers(
        spp, seed, width, height, tolerance, edge_spp, adaptive, max_spp)
    # RGB or spectral; whitted mode (a scene's default) RGB only: one sentence, before any work.
    environment.require_colour_variant(
        mode if mode is not None or isinstance(scene_or_path, mi.Scene) else "whitted")
    if isinstance(scene_or_path, mi.Scene):
        if width is not None or height is not None or crop is not None:
            given = ("crop applies" if width is None and height is None
                     else "width and height apply")
            raise ValueError(f"render: {given} to a scene model or file; a "
                             f"loaded mi.Scene renders at its film's size (its film's own "
                             f"crop_offset and crop_size crop it)")
        return _render_loaded(scene_or_path, spp, mode, progress, tolerance, filter,
                              edge_spp, seed, adaptive, max_spp)
    mode = "whitted" if mode is None else mode
    check_edge_spp(edge_spp, mode)
    check_filter(filter, mode)
    check_adaptive(adaptive, max_spp, mode, edge_spp)
    problem = seed_problem(seed)
    if problem:
        raise ValueError(f"render: {problem}")
    scene = scene_or_path
    if isinstance(scene_or_path, (str, os.PathLike)):   # a file, else a packaged scene's name
        scene = scene_language.load(packaged_scenes.resolve(scene_or_path))
    elif not isinstance(scene_or_path, scene_language.Scene):
        raise TypeError(f"render: {scene_or_path!r:.80} is not a scene: give a scene file's "
                        f"path, a mimarble.scene.Scene or a loaded mi.Scene")
    scene = _sized(scene, width, height, spp)
    if crop is not None:
        problem = crop_problem(crop, scene.image.width, scene.image.height)
        if problem:
            raise (TypeError if problem.startswith("must be") else ValueError)(
                f"render: crop {problem}")
        crop = as_integers(crop)
    try:
        mitsuba_scene = LOADED.scene_of(scene, mode=mode, spp=spp, tolerance=tolerance,
                                        filter=filter)
    except RuntimeError:
        check_images(scene)              # an image map that does not decode: said at its file
        raise
    spp = scene.image.samples if spp is None else spp
    total = scene.image.width * scene.image.height * spp
    if adaptive is not None:
        max_spp = default_max_spp(spp, max_spp)
    check_adaptive(adaptive, max_spp, mode, edge_spp, spp, scene.image.width, scene.image.height)
    if adaptive is not None:                    # NumPy's numbers too, as Python's
        adaptive, max_spp = float(adaptive), int(max_spp)
    if not dr.is_jit_v(mi.Float):
        for asked, what in ((edge_spp, "edge samples"), (adaptive, "adaptive sampling")):
            if asked:
                warnings.warn(f"{what} need{'s' if what[-1] == 'g' else ''} a JIT variant "
                              f"(llvm_ad_rgb, cuda_ad_rgb); {mi.variant()} renders without",
                              stacklevel=2)
        done = report(progress, "render")
        done(0, total)
        image = np.array(mi.render(mitsuba_scene, seed=seed), dtype=np.float32)[..., :3]
        done(total, total)
        # A window of the whole render: Mitsuba's own film crop (crop_offset, crop_size)
        # maps film positions through other float32 arithmetic, so its pixels differ
        # (whitted: by up to 6e-5, measured; path: a different sample stream).
        return image if crop is None else np.ascontiguousarray(image[_slices(crop)])
    return render_in_passes(mitsuba_scene, spp, mode, progress, edge_spp=edge_spp, seed=seed,
                            crop=crop, adaptive=adaptive, max_spp=max_spp)


def _slices(crop):
    """``(x0, y0, x1, y1)`` as the (rows, columns) slices of an (H, W, …) array."""
    x0, y0, x1, y1 = crop
    return slice(y0, y1), slice(x0, x1)


def _sized(scene, width, height, spp):
    """The scene at ``width`` × ``height`` (None: its own), checked by the scene model's
    own rules (each within the image-size limit, and within the sample limit at ``spp`` when given, else at the
    scene's samples), as ``--width``/``--height`` are."""
    try:
        return with_image_size(scene, width=width, height=height, spp=spp)
    except (TypeError, ValueError) as e:
        raise type(e)(f"render: {e}") from None


def _render_loaded(mitsuba_scene, spp, mode, progress, tolerance, filter, edge_spp, seed,
                   adaptive, max_spp):
    """:func:`render` of a loaded ``mi.Scene``."""
    from mimarble.mitsuba.plugins.whitted import Whitted
    given = [name for name, value in (("tolerance", tolerance), ("filter", filter))
             if value is not None]
    if given:
        raise ValueError(f"render: {' and '.join(given)} {'apply' if len(given) > 1 else 'applies'} "
                         f"to a scene model or file (the "
                         f"translator sets them on each marble); a loaded mi.Scene renders "
                         f"with its textures' own")
    if not mitsuba_scene.sensors():
        raise ValueError("render: the mi.Scene has no sensor to render from")
    whitted = isinstance(mitsuba_scene.integrator(), Whitted)
    if whitted:
        Whitted.check_scene(mitsuba_scene)   # the wrong BSDF or light said before any trace
    if mode is not None and mode != ("whitted" if whitted else "path"):
        raise ValueError(f"render: mode={mode!r:.40} does not fit the scene's integrator "
                         f"({type(mitsuba_scene.integrator()).__name__}); leave mode out")
    sensor = mitsuba_scene.sensors()[0]
    spp = sensor.sampler().sample_count() if spp is None else spp
    width, height = (int(x) for x in sensor.film().crop_size())
    problem = spp_problem(spp, width, height) or seed_problem(seed)
    if problem:
        raise ValueError(f"render: {problem}")
    check_edge_spp(edge_spp, "whitted" if whitted else "path")
    if adaptive is not None:
        max_spp = default_max_spp(spp, max_spp)
    check_adaptive(adaptive, max_spp, "whitted" if whitted else "path", edge_spp, spp, width,
                   height)
    if adaptive is not None:
        adaptive, max_spp = float(adaptive), int(max_spp)
        if not dr.is_jit_v(mi.Float):
            warnings.warn(f"adaptive sampling needs a JIT variant (llvm_ad_rgb, cuda_ad_rgb); "
                          f"{mi.variant()} renders without", stacklevel=3)
    if whitted and dr.is_jit_v(mi.Float):   # its stratum centres, in passes (one kernel)
        return render_in_passes(mitsuba_scene, spp, "whitted", progress, edge_spp=edge_spp,
                                adaptive=adaptive, max_spp=max_spp)
    # Any other integrator, film filter or AOV: Mitsuba's own render, as it would be.
    refresh_derived(mitsuba_scene)
    return np.array(mi.render(mitsuba_scene, spp=spp, seed=seed), dtype=np.float32)[..., :3]


def check_images(scene) -> None:
    """Every image map decodes (``to_mitsuba`` checked the headers: regular files,
    complete 8-bit PNG or JPEG within the pixel limit), and so does the environment's file,
    else a SceneError at its ``file`` string. Called when loading the scene failed, so a
    good image is not decoded twice."""
    for channel in scene.image_maps():
        try:
            mi.Bitmap(channel.location)
        except Exception as e:   # Mitsuba's reader raises RuntimeError with libpng's reason
            raise scene_language.SceneError.undecodable_image(scene, channel, _reason(e)) \
                from None
    sky = scene.environment
    if sky is not None and sky.file is not None:
        try:
            mi.Bitmap(sky.location)
        except Exception as e:   # OpenEXR's or the RGBE reader's reason, after the stream
            reason = _reason(e).rsplit(']".', 1)[-1].strip()     # Mitsuba prints the stream
            raise scene_language.SceneError.in_file(
                scene.source, sky.pos, f"environment file '{shortened(sky.file, 256)}' "
                f"cannot be decoded: {reason}") from None


def _reason(error: Exception) -> str:
    """The last line of a reader's message (its reason), or the error's class."""
    text = str(error).strip()
    return text.splitlines()[-1] if text else type(error).__name__


def check_filter(filter, mode: str = "whitted") -> None:
    """A pixel filter other than ``none`` needs whitted mode: Mitsuba's ``path`` gives a
    texture no ray differentials to filter over (docs/mitsuba-scene.md)."""
    if filter not in (None, "none") and mode != "whitted":
        raise ValueError(f"filter={filter!r:.40} needs whitted mode (its ray differentials); "
                         f"Mitsuba's path integrator gives the marble none: leave filter out")


def check_adaptive(adaptive, max_spp, mode: str = "whitted", edge_spp=None,
                   spp: int | None = None, width: int = 1, height: int = 1) -> None:
    """``adaptive`` None, or a threshold for whitted mode without ``edge_spp``, with a
    ``max_spp`` that fits (``scene.rules.adaptive_problem``; checked against ``spp`` and
    the image size once they are known); ``max_spp`` only with ``adaptive``."""
    if adaptive is None:
        if max_spp is not None:
            raise ValueError("max_spp applies to adaptive sampling: give adaptive=THRESHOLD too")
        return
    problem = adaptive_problem(adaptive, None if spp is None else max_spp, spp or 1, width,
                               height)
    if problem:
        raise ValueError(f"render: {problem}")
    if mode != "whitted":
        raise ValueError(f"adaptive sampling needs whitted mode (its stratum centres); mode is "
                         f"{mode!r}")
    if edge_spp is not None:
        raise ValueError("adaptive sampling refines silhouettes itself: give adaptive or "
                         "edge_spp, not both")


def check_edge_spp(edge_spp, mode: str = "whitted") -> None:
    """``edge_spp`` is None or a perfect square ≥ 1, in whitted mode (ValueError otherwise)."""
    if edge_spp is None:
        return
    try:
        samples_per_axis(edge_spp)
    except ValueError:
        raise ValueError(f"edge_spp={edge_spp!r} must be a perfect square ≥ 1 "
                         f"(1, 4, 9, 16, …)") from None
    if mode != "whitted":
        raise ValueError(f"edge_spp needs whitted mode (its stratum centres); mode is {mode!r}")


def render_in_passes(mitsuba_scene, spp: int, mode: str = "whitted", progress=False,
                     pass_samples: int | None = None, edge_spp: int | None = None,
                     seed: int = 0, crop: tuple | None = None, adaptive: float | None = None,
                     max_spp: int | None = None) -> np.ndarray:
    """What ``mi.render`` computes, in passes of at most ``pass_samples`` samples
    (default :data:`~mimarble.mitsuba.rendering.passes.PASS_SAMPLES`; :func:`trace_in_passes`).

    Each pass takes a run of whole pixels (or, when one pixel has more samples
    than a pass, a run of one pixel's samples) and does what Mitsuba's
    ``SamplingIntegrator.render`` does for them: film position → the sensor's
    ``sample_ray_differential`` (differentials scaled by 1/√spp, starting at the
    eye: :class:`PixelTracer`) → the integrator's ``sample``; with the
    translator's ``box`` filter a pixel is the plain mean of its samples. Sample
    positions: whitted mode takes the n×n stratum centres (what the non-jittered
    ``stratified`` sampler gives, in another order), path mode the scene's
    sampler, seeded per pass.

    ``edge_spp`` (whitted mode): afterwards, every pixel on a silhouette — among
    its own samples and those of its 8 neighbours, the first shapes hit are not
    all the same (a miss counts as a shape) — is rendered again with
    ``edge_spp`` = m² stratum centres, which replace all of its ``spp`` samples
    (so only an ``edge_spp`` above ``spp`` does anything; mimarble/mitsuba/rendering/silhouettes.py).
    Deterministic, like the rest.

    ``adaptive`` (whitted mode; not with ``edge_spp``): the first pass at ``spp``, then
    rounds that render again, with twice the samples per axis up to ``max_spp`` (default
    64), the pixels whose estimated error is above the threshold
    (:func:`~mimarble.mitsuba.rendering.adaptive.render_adaptive`, which also says each pixel's
    samples and the samples traced).

    ``crop`` ``(x0, y0, x1, y1)`` (checked by the caller: :func:`~mimarble.mitsuba.rendering.crop.crop_problem`):
    only that window is traced, as a list of the full image's pixel indices, and the
    (y1 − y0, x1 − x0, 3) window comes back. Whitted mode gives exactly the full render's
    pixels there, edge samples included: the first passes also trace a one-pixel ring
    around the window (inside the image), so that each window pixel's silhouette test sees
    the same 8 neighbours as in the full render. Path mode draws the window's samples in
    its own passes (the sampler is seeded per pass, lane by lane), so its noise there
    differs from the full render's, as Mitsuba's own film crop does: the same expected image.

    The numbers that vary between renders of one scene structure are opaque
    (pass offsets, samples per pixel, image width and height), so a scene
    compiles one kernel for every spp: a new user's renders at 1, 4 and
    16 spp cost one compilation (docs/benchmarks.md, "Start-up"), not three,
    as they did through ``mi.render``, whose sampler and sample indexing take
    the spp as a constant. JIT variants therefore always render here, also in
    one pass. A new image size still compiles a new kernel (measured: 16², 24²,
    33² one each; something of the loaded Mitsuba scene bakes the film size in).
    """
    check_edge_spp(edge_spp, mode)
    if adaptive is not None:
        max_spp = default_max_spp(spp, max_spp)
        return render_adaptive(mitsuba_scene, spp, adaptive, max_spp, progress, crop,
                               pass_samples).image
    if edge_spp is not None and edge_spp <= spp:
        edge_spp = None                                # fewer samples would not help a pixel
    target = Target.of(mitsuba_scene, mode, LOADED.parameters_of(mitsuba_scene))
    # What is traced: the whole image, or a window of it (with edge samples, the window
    # and a ring of one pixel, so that its silhouettes are found as in the whole image).
    traced = Window.of(target, crop, ring=1 if edge_spp else 0)
    width, height = traced.width, traced.height
    pixels = width * height
    image = np.empty((pixels, 3), dtype=np.float32)   # the only full-size array
    # First and last shape hit among each pixel's samples (0: a miss), for edge_spp.
    shapes = np.zeros((2, pixels), dtype=np.uint32) if edge_spp else None
    done = report(progress, "render")
    samples_done, samples_total = 0, pixels * spp
    # With edge samples to come, the first passes report against one more sample than
    # they take, so that a bar stays open until the edge pass has said how much it adds.
    pending = 1 if edge_spp else 0
    done(0, samples_total + pending)                   # a bar's delay counts from here
    first_passes = trace_in_passes(target, spp, traced.pixels, with_shapes=shapes is not None,
                                   pass_samples=pass_samples, seed=seed)
    for samples in _fill(image, first_passes, spp, shapes, traced.local):
        samples_done += samples
        done(samples_done, samples_total + pending)
    if edge_spp:
        edge_samples, edge_passes = edge_sample_passes(target, shapes, edge_spp, pass_samples,
                                                       traced)
        samples_total += edge_samples
        done(samples_done, samples_total)
        for samples in _fill(image, edge_passes, edge_spp, local=traced.local):
            samples_done += samples
            done(samples_done, samples_total)
    return traced.window_of(image.reshape(height, width, 3))


def _fill(image: np.ndarray, traced_passes, spp: int, shapes: np.ndarray | None = None,
          local=lambda pixels: pixels):
    """Store each pass's pixel means (its float64 sums / ``spp``, rounded to float32) in
    ``image`` (pixels, 3), and with ``shapes`` their first-hit shape ranges in it
    (2, pixels); yields the samples each pass traced, once it is stored. ``local``: the
    whole image's pixel indices → ``image``'s (a crop's window)."""
    for traced in traced_passes:
        pixels = local(traced.pixels)
        image[pixels] = traced.means
        if shapes is not None:
            shapes[0, pixels] = traced.first_shape
            shapes[1, pixels] = traced.last_shape
        yield traced.samples
