"""``mimarble render`` and ``mimarble reference``: one scene into one image file."""

from __future__ import annotations

import time

from mimarble.cli.shared import (adaptive_words, check_whitted_options, chosen_crop, load_scene,
    output_path, chosen_quality, say, chosen_spp, start_mitsuba, write_output)


def _render_to_file(args, renderer, description) -> int:
    """Load, check arguments, render, write whole, report: shared by render and reference.

    ``description(spp)`` names the renderer once it has started.
    """
    out = output_path(args)
    quality = chosen_quality(args, out)
    scene = load_scene(args)
    spp = chosen_spp(args, scene)
    crop = chosen_crop(args, scene)
    start_mitsuba(args)
    start = time.perf_counter()
    image = renderer(scene, spp)
    seconds = time.perf_counter() - start
    # A window's PNG is dithered where its pixels lie in the whole image: the full PNG's.
    write_output(out, image, quality=quality, origin=(0, 0) if crop is None else crop[:2])
    size = f"{scene.image.width}x{scene.image.height}"
    if crop is not None:
        from mimarble.mitsuba.rendering.crop import crop_words
        size = f"{image.shape[1]}x{image.shape[0]} (--crop {crop_words(crop)} of {size})"
    say(f"{out}: {size}, {spp} spp, {description(spp)}, {seconds:.2f} s")
    return 0


def _render(args) -> int:
    import mimarble
    check_whitted_options(args)
    return _render_to_file(args, lambda scene, spp: mimarble.render(
        scene, spp=spp, mode=args.mode, progress=True, tolerance=args.tolerance,
        filter=args.filter, edge_spp=args.edge_spp,
        crop=None if args.crop is None else tuple(args.crop), adaptive=args.adaptive,
        max_spp=args.max_spp),
        lambda spp: f"{args.mode} mode{adaptive_words(args, spp)}, {mimarble.mi.variant()}")


def _reference(args) -> int:
    from mimarble import reference
    return _render_to_file(args, lambda scene, spp: reference.render(scene, spp=spp, progress=True),
                           lambda spp: "reference tracer (NumPy float64)")
