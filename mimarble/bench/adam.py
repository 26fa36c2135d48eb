"""One Adam step of notebook 02's inverse rendering, traced every time and frozen.

The step is the notebook's (part 3): the optimiser's period, distortion and vein colour
into the scene (the colour spliced into the known ramp with ``dr.select``), ``mi.render``
at 16 spp with a fresh ``mi.UInt32`` seed, the L2 loss, ``dr.backward``, ``opt.step()``
and the colour clipped to [0, 1]. The scene: ``prb`` (max_depth 2), 64×64, a unit sphere
whose diffuse reflectance is a 5-octave marble, under a constant sky. Each variant runs
``steps`` steps from the same start in a fresh scene; the first WARM (tracing, compiling,
recording) are left out of the medians of the whole step (a sync before the clock), its
JIT kernels' execution time (Dr.Jit's kernel history, on in both variants) and its
launches. The loss is the sum times 1/n (``dr.mean`` divides by n inside ``dr.freeze``,
multiplies by 1/n outside: 1 ulp apart).
"""

from __future__ import annotations

import math
import statistics
import time

import numpy as np

from mimarble.runtime import environment

dr, mi = environment.import_drjit_and_mitsuba()

RES, SPP, STEPS, WARM = 64, 16, 33, 3
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


def optimiser_at_start(scene):
    """(marble, opt): the ramp the step splices the vein colour into, and Adam holding
    START's period, distortion and vein colour (the notebook's)."""
    marble = {"known_ramp": mi.Color3f(mi.traverse(scene)[KEY + "ramp"]),
              "free": dr.arange(mi.UInt32, 3) == 1}
    opt = mi.ad.Adam(lr=0.02)
    opt["period"], opt["distortion"] = mi.Float(START["period"]), mi.Float(START["distortion"])
    opt["vein"] = mi.Color3f(START["vein"])
    return marble, opt


def run(step, target, steps: int = STEPS):
    """`steps` steps from START: per-step wall ms, kernel ms, launches; losses; final values."""
    scene = marble_scene(**START)
    marble, opt = optimiser_at_start(scene)
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



def step_rows(steps: int = STEPS) -> dict:
    """{"traced", "frozen"}: each {"whole_ms", "kernels_ms", "launches"} (medians), and the
    largest difference of their losses and parameters after ``steps`` steps."""
    target = mi.render(marble_scene(**TRUE), spp=32, seed=1)
    traced = run(adam_step, target, steps)
    frozen = run(dr.freeze(adam_step), target, steps)
    rows = {name: dict(zip(("whole_ms", "kernels_ms", "launches"), result[0]))
            for name, result in (("traced", traced), ("frozen", frozen))}
    rows["loss_difference"] = float(np.abs(traced[1] - frozen[1]).max())
    rows["parameter_difference"] = float(np.abs(traced[2] - frozen[2]).max())
    return rows
