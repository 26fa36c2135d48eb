"""One Adam step of notebook 02's inverse rendering (part 3), traced every time against
replayed through ``dr.freeze``.

    ./go python scripts/adam_step_timing.py        # prints a table; well under a minute

The step is the notebook's: the optimiser's period, distortion and vein colour into the
scene (the colour spliced into the known ramp with ``dr.select``), ``mi.render`` at
16 spp with a fresh ``mi.UInt32`` seed, the L2 loss, ``dr.backward``, ``opt.step()`` and
the colour clipped to [0, 1]. The scene is part 3's: ``prb`` (max_depth 2), 64×64, a unit
sphere whose diffuse reflectance is a marble, under a constant sky. Each variant runs
STEPS steps from the same start, in a fresh scene; the first WARM (tracing, compiling,
recording) are left out of:

* whole step: the wall time of one call, ``dr.sync_thread()`` before reading the clock
  (median over the steps);
* kernels: the execution time of the step's JIT kernels, from Dr.Jit's kernel history
  (on in both variants, in the same run; median);
* launches: JIT kernels per step (median).

Then both variants again for CHECK steps on one Dr.Jit thread, where a run is
deterministic, and the largest absolute differences of their losses and parameters (0:
bit for bit). On the default threads two runs of either variant already differ by a few
ulp (the film's and the gradients' atomic adds come in any order); those differences
of the timed runs are printed too. The loss is the notebook's mse, the sum times 1/n
(``dr.mean`` divides by n inside ``dr.freeze``, times 1/n outside: 1 ulp apart).
"""

import os
import platform
import sys

import numpy as np

import mimarble

mimarble.start()

from mimarble.bench.adam import RES, SPP, STEPS, TRUE, WARM, adam_step, marble_scene, run

dr, mi = mimarble.dr, mimarble.mi
CHECK = 20


def cpu():
    with open("/proc/cpuinfo") as info:
        model = next((line.split(":", 1)[1].strip() for line in info
                      if line.startswith("model name")), "?")
    return f"{model} (platform.processor(): {platform.processor() or '?'}, {os.cpu_count()} cores)"


def main():
    target = mi.render(marble_scene(**TRUE), spp=32, seed=1)
    traced = run(adam_step, target)
    frozen_step = dr.freeze(adam_step)
    frozen = run(frozen_step, target)
    rows = ["| step | whole step ms | kernels ms | launches/step |", "|---|---|---|---|"]
    for name, ((wall, kernels, launches), _, _) in (("traced (not frozen)", traced),
                                                     ("dr.freeze (replayed)", frozen)):
        rows.append(f"| {name} | {wall:.1f} | {kernels:.1f} | {launches:g} |")
    print(f"One Adam step, {RES}x{RES}, {SPP} spp prb, {mi.variant()}, median of steps "
          f"{WARM + 1}-{STEPS}; CPU: {cpu()}\n")
    print("\n".join(rows))
    print(f"\nspeed-up (whole step): {traced[0][0] / frozen[0][0]:.2f}x; "
          f"recordings: {frozen_step.n_recordings}")
    print(f"after {STEPS} steps (period, distortion, vein rgb): "
          f"{np.array2string(frozen[2], precision=4)}; truth {TRUE['period']}, "
          f"{TRUE['distortion']}, {TRUE['vein']}")

    def differences(a, b):
        return np.abs(a[1] - b[1]).max(), np.abs(a[2] - b[2]).max()
    print("traced against frozen, max |difference| of losses, of parameters: "
          "%.3g, %.3g (%d threads)" % (*differences(traced, frozen), dr.thread_count()))
    threads = dr.thread_count()
    dr.set_thread_count(1)
    try:
        loss_diff, value_diff = differences(run(adam_step, target, CHECK),
                                            run(frozen_step, target, CHECK))
    finally:
        dr.set_thread_count(threads)
    print("traced against frozen, max |difference| of losses, of parameters: "
          f"{loss_diff:.3g}, {value_diff:.3g} (1 thread, {CHECK} steps: "
          f"{'bit for bit' if loss_diff == value_diff == 0 else 'NOT identical'})")
    return 0 if loss_diff == value_diff == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
