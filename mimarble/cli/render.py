"""``mimarble render`` and ``mimarble reference``: one scene into one image file."""

from __future__ import annotations

import time

from mimarble.cli.shared import (_adaptive_words, _check_whitted_options, _crop, _load_scene,
    _output_path, _quality, _say, _spp, _start, _write)


def _render_to_file(args, renderer, description) -> int:
    """Load, check arguments, render, write whole, report: shared by render and reference.

    ``description(spp)`` names the renderer once it has started.
    """
    out = _output_path(args)
    quality = _quality(args, out)
    scene = _load_scene(args)
    spp = _spp(args, scene)
    crop = _crop(args, scene)
    _start(args)
    start = time.perf_counter()
    image = renderer(scene, spp)
    seconds = time.perf_counter() - start
    # A window's PNG is dithered where its pixels lie in the whole image: the full PNG's.
    _write(out, image, quality=quality, origin=(0, 0) if crop is None else crop[:2])
    size = f"{scene.image.width}x{scene.image.height}"
    if crop is not None:
        from mimarble.mitsuba.rendering.crop import crop_words
        size = f"{image.shape[1]}x{image.shape[0]} (--crop {crop_words(crop)} of {size})"
    _say(f"{out}: {size}, {spp} spp, {description(spp)}, {seconds:.2f} s")
    return 0


def _render(args) -> int:
    import mimarble
    _check_whitted_options(args)
    return _render_to_file(args, lambda scene, spp: mimarble.render(
        scene, spp=spp, mode=args.mode, progress=True, tolerance=args.tolerance,
        filter=args.filter, edge_spp=args.edge_spp,
        crop=None if args.crop is None else tuple(args.crop), adaptive=args.adaptive,
        max_spp=args.max_spp),
        lambda spp: f"{args.mode} mode{_adaptive_words(args, spp)}, {mimarble.mi.variant()}")


def _reference(args) -> int:
    from mimarble import reference
    return _render_to_file(args, lambda scene, spp: reference.render(scene, spp=spp, progress=True),
                           lambda spp: "reference tracer (NumPy float64)")
