"""Our translucent render under another sampler, max_depth or survival power: CPU time, mean and noise.

    ./go python scripts/translucent_settings.py SCENE SIZE SPP SAMPLER:MAX_DEPTH[:POWER[:LO:HI]]

Renders SCENE at SIZE², SPP in path mode with volpath's sampler and ``max_depth`` replaced
(e.g. ``stratified:1024``; ``rr_depth`` lowered to it where above) and, with ``:POWER``
and ``:LO:HI``, the walk's survival power and the albedos it applies at
(``media.WALK_SURVIVAL_POWER``, ``media.WALK_POWER_ALBEDOS``, where the media end walks by
``roulette_isotropic``), once with seed 0 (warm-up),
then with seeds 1 and 2; prints one JSON line: the CPU seconds of each (``time.process_time``)
and the mean and noise over the object's pixels as scripts/translucent_vs_cycles.py computes
them. One setting a process: a loaded scene is kept by its structure, sampler included
(docs/benchmarks.md, "Walk length and sampler against Cycles").
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import translucent_vs_cycles as versus  # noqa: E402  (the sibling script)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 4 or argv[3].count(":") not in (1, 2, 4):
        print(__doc__.splitlines()[2].strip(), file=sys.stderr)
        return 2
    name, size, spp, setting = argv[0], int(argv[1]), int(argv[2]), argv[3]
    sampler, depth, *power = setting.split(":")
    import mimarble
    from mimarble import scene as scene_language
    from mimarble.mitsuba.translate import media, scene_dict
    if power:
        media.WALK_SURVIVAL_POWER = float(power[0])
    if power[1:]:
        media.WALK_POWER_ALBEDOS = (float(power[1]), float(power[2]))
    from mimarble.runtime import packaged_scenes
    from mimarble.scene.edits import resized
    original = scene_dict.integrator_and_sampler

    def replaced(*args, **kwargs):
        integrator, chosen = original(*args, **kwargs)
        if integrator["type"] == "volpath":
            chosen = dict(chosen, type=sampler)
            integrator = dict(integrator, max_depth=int(depth),
                              rr_depth=min(integrator["rr_depth"], int(depth)))
        return integrator, chosen

    scene_dict.integrator_and_sampler = replaced
    scene = resized(scene_language.load(packaged_scenes.resolve(name)), size)
    mask = versus.object_mask(scene)
    mimarble.render(scene, spp=spp, mode="path", seed=0)
    images, cpu = [], []
    for seed in (1, 2):
        used = time.process_time()
        images.append(mimarble.render(scene, spp=spp, mode="path", seed=seed))
        cpu.append(round(time.process_time() - used, 2))
    print(json.dumps({"setting": setting, "cpu_s": cpu,
                      **versus.statistics_of(images[0], images[1], mask)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
