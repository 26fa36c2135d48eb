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
        for path, seconds, kernels in kernel_cache.warm(scenes, progress=True):
            compiled += kernels
            say(f"warm: {path}: {kernels} kernel{'s' * (kernels != 1)} compiled, {seconds:.2f} s",
                  flush=True)
        print(f"warm: {compiled} kernels compiled in {time.perf_counter() - start:.1f} s; "
              f"{kernel_cache.describe()}")
    return 0
