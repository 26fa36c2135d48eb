"""``mimarble doctor``: the libLLVM, variant, versions and kernel cache in use; --warm."""

from __future__ import annotations

import time

from mimarble.cli.shared import say, scene_list, start_mitsuba


def _doctor(args) -> int:
    from mimarble.runtime import environment, kernel_cache
    from mimarble import scene as scene_language
    if args.warm is not None:    # every scene error before minutes of compiling
        scenes = [(path, scene_language.load(path)) for path in scene_list(args.warm)]
    rows, ok = environment.doctor(args.variant)
    rows.append(("kernel cache", kernel_cache.describe()))
    rows.append(("replay", environment.replay_sentence()))
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"{key:<{width}}  {value}")
    print("rendering can work" if ok else
          "rendering cannot work here, or only in the slow scalar variant: see above")
    if not ok:
        return 1
    if args.warm is not None:
        start_mitsuba(args)
        start, compiled = time.perf_counter(), 0
        for path, seconds, kernels in _warm(scenes, progress=True):
            compiled += kernels
            say(f"warm: {path}: {kernels} kernel{'s' * (kernels != 1)} compiled, {seconds:.2f} s",
                  flush=True)
        print(f"warm: {compiled} kernels compiled in {time.perf_counter() - start:.1f} s; "
              f"{kernel_cache.describe()}")
    return 0


def _warm(scenes, progress=None):
    """Render each scene once at its own size, 1 spp; yields (name, seconds, kernels compiled).

    ``scenes``: (name, scene model) pairs. Afterwards a render of these scenes at
    their size compiles nothing, at any spp. ``progress`` as for :func:`mimarble.render`.
    """
    import mimarble
    from mimarble.runtime.kernel_cache import compiled
    dr = mimarble.dr
    for name, scene in scenes:
        start = time.perf_counter()
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
            mimarble.render(scene, spp=1, progress=progress)
            kernels = compiled(dr.kernel_history())
        yield name, time.perf_counter() - start, kernels
