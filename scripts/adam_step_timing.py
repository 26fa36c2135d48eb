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

import math
import os
import platform
import statistics
import sys
import time

import numpy as np

import mimarble

dr, mi = mimarble.dr, mimarble.mi
RES, SPP, STEPS, WARM, CHECK = 64, 16, 33, 3, 20
KEY = "sphere.bsdf.reflectance."
TRUE = {"period": 1.3, "distortion": 2.0, "vein": (0.55, 0.35, 0.25)}
START = {"period": 1.35, "distortion": 2.25, "vein": (0.5, 0.5, 0.5)}   # as the coarse search


def marble_scene(period, distortion, vein):
    """Notebook 02's scene (part 3)."""
    ramp = f"0.95 0.92 0.85, {vein[0]} {vein[1]} {vein[2]}, 0.12 0.08 0.06"
    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "prb", "max_depth": 2},
        "sensor": {"type": "perspective", "fov": 32,
                   "to_world": mi.ScalarTransform4f().look_at([0, 0, 4], [0, 0, 0], [0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": RES, "height": RES,
                            "rfilter": {"type": "box"}}},
        "sphere": {"type": "sphere", "radius": 1.0, "bsdf": {"type": "diffuse", "reflectance": {
            "type": "marble", "scale": 1.5, "period": period, "distortion": distortion,
            "octaves": 5, "ramp": ramp}}},
        "sky": {"type": "constant", "radiance": 1.0},
    })


def adam_step(scene, marble, opt, target, seed):
    """The notebook's step (full resolution): Dr.Jit work only, no value read."""
    params = mi.traverse(scene)
    params[KEY + "period"], params[KEY + "distortion"] = opt["period"], opt["distortion"]
    params[KEY + "ramp"] = dr.select(marble["free"], opt["vein"], marble["known_ramp"])
    params.update()
    image = mi.render(scene, params, spp=SPP, seed=seed)
    loss = dr.sum(dr.square(image - target), axis=None) * (1 / math.prod(image.shape))
    dr.backward(loss)
    opt.step()
    opt["vein"] = dr.clip(opt["vein"], 0.0, 1.0)
    return loss


def run(step, target, steps=STEPS):
    """`steps` steps from START: per-step wall ms, kernel ms, launches; losses; final values."""
    scene = marble_scene(**START)
    marble = {"known_ramp": mi.Color3f(mi.traverse(scene)[KEY + "ramp"]),
              "free": dr.arange(mi.UInt32, 3) == 1}
    opt = mi.ad.Adam(lr=0.02)
    opt["period"], opt["distortion"] = mi.Float(START["period"]), mi.Float(START["distortion"])
    opt["vein"] = mi.Color3f(START["vein"])
    wall, kernels, launches, losses = [], [], [], []
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        for it in range(steps):
            dr.sync_thread()
            dr.kernel_history()                                 # empties it
            start = time.perf_counter()
            loss = step(scene, marble, opt, target, mi.UInt32(it))
            dr.eval(loss, opt["period"], opt["distortion"], opt["vein"])
            dr.sync_thread()
            wall.append((time.perf_counter() - start) * 1e3)
            jit = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
            kernels.append(sum(k["execution_time"] for k in jit))
            launches.append(len(jit))
            losses.append(loss.numpy().item())
    final = np.concatenate([np.ravel(opt[k].numpy()) for k in ("period", "distortion", "vein")])
    return [statistics.median(x[WARM:]) for x in (wall, kernels, launches)], np.array(losses), final


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
