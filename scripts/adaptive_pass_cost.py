"""Where the time of an adaptive render's passes goes (issue 43): kernels, replays, the rest.

    ./go python scripts/adaptive_pass_cost.py [SCENE …] [--size 256] [--threshold 6e-4]
                                              [--rounds 9]

For each scene (default fig11a and veins-p4-d8-s4), point-sampled, a plain 1-spp render and
an adaptive one (first pass 1 spp, at most 81) are taken in turn ``--rounds`` times after a
warm-up; the adaptive render's steps are timed one by one, each closed by a sync
(``dr.sync_thread``), with the kernels they launched (Dr.Jit's kernel history: the flag is
set before the first render, since JIT flags are part of a recording's key):

- ``pass``: a pass of ``passes.trace_sums`` (the round's pixel list gathered, the recorded
  pass replayed); ``replay host`` is the frozen call's own time on the host (its walk of
  the inputs, then the recorded kernels' launch), ``walk`` what a frozen function that
  does nothing costs with the same inputs (the scene, its facts, the sampler);
- ``add``: the pass's sums into the pixels' state (``PixelState.add`` / ``take``);
- ``means``: the neighbourhood's packets of the pixels' means (``PixelState.neighbourhood``);
- ``refine``: the estimate and the next lists (``adaptive.refine``), host and kernels;
- ``rest``: everything else of the render (the lists' lengths read back — the sync of a
  round —, the image to NumPy, Python), the total less the steps.

A plain 1-spp render is split alike: the recorded pass's frozen call, its kernels, the rest
(its values to NumPy). Prints medians (ms), the CPU and the load. The syncs that close each
step cost a little themselves: the profiled total is printed beside the unprofiled one.
"""
from __future__ import annotations

import argparse
import os
import statistics
import time
from collections import defaultdict

import mimarble
from mimarble.mitsuba import to_mitsuba
from mimarble.mitsuba.rendering import adaptive, passes
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.runtime.machine import machine_facts
from mimarble.scene.edits import resized

dr, mi = mimarble.dr, mimarble.mi


class Profile:
    """Steps of one render: (round, step) → [wall ms, kernel ms, kernels, replay host ms]."""

    def __init__(self):
        self.steps = defaultdict(lambda: [0.0, 0.0, 0, 0.0])
        self.round = 0
        self.last = None
        self.replay_host = 0.0

    def step(self, name: str, call):
        if name == "pass" and self.last in ("means", "refine"):
            self.round += 1                       # a round's first pass after the estimate
        self.last = name
        dr.sync_thread()
        dr.kernel_history()                       # what came before is not this step's
        self.replay_host = 0.0
        start = time.perf_counter()
        result = call()
        dr.sync_thread()
        wall = 1000 * (time.perf_counter() - start)
        kernels = [k for k in dr.kernel_history() if k["type"] != dr.KernelType.Memset]
        row = self.steps[(self.round, name)]
        row[0] += wall
        row[1] += sum(k["execution_time"] for k in kernels)
        row[2] += len(kernels)
        row[3] += self.replay_host
        return result


PROFILE: Profile | None = None


def _instrument() -> None:
    """Wrap the adaptive render's steps (module docstring) in :data:`PROFILE`'s timers."""
    trace_sums, refine = adaptive.trace_sums, adaptive.refine
    add, take, means = adaptive.PixelState.add, adaptive.PixelState.take, \
        adaptive.PixelState.neighbourhood
    recorded = passes.traced_pass

    def timed_trace_sums(*args, **kwargs):
        generator = trace_sums(*args, **kwargs)
        while True:
            part = PROFILE.step("pass", lambda: next(generator, None)) if PROFILE else \
                next(generator, None)
            if part is None:
                return
            yield part

    def timed_refine(*args, **kwargs):
        if PROFILE is None:
            return refine(*args, **kwargs)
        return PROFILE.step("refine", lambda: _evaluated(refine(*args, **kwargs)))

    def timed(method, name):
        def call(self, *args, **kwargs):
            if PROFILE is None:
                return method(self, *args, **kwargs)
            if name == "means":
                return PROFILE.step(name, lambda: _evaluated(method(self, *args, **kwargs)))
            return PROFILE.step(name, lambda: method(self, *args, **kwargs))
        return call

    class TimedRecorded:
        def __call__(self, *args):
            start = time.perf_counter()
            result = recorded(*args)
            if PROFILE is not None:
                PROFILE.replay_host += 1000 * (time.perf_counter() - start)
            return result

    adaptive.trace_sums, adaptive.refine = timed_trace_sums, timed_refine
    adaptive.PixelState.add = timed(add, "add")
    adaptive.PixelState.take = timed(take, "add")
    adaptive.PixelState.neighbourhood = timed(means, "means")
    passes.traced_pass = TimedRecorded()


def _evaluated(value):
    dr.eval(value)
    return value


def walk_ms(loaded, repeats: int = 50) -> float:
    """A frozen function that does nothing with a pass's inputs: the replay's walk alone."""
    target = passes.Target.of(loaded, "whitted", adaptive.LOADED.parameters_of(loaded))
    facts = adaptive.scene_facts(target.scene, target.params)
    x = dr.arange(mi.Float, 16)
    frozen = dr.freeze(lambda scene, inputs, sampler, x: x + 1)
    for _ in range(3):
        dr.eval(frozen(target.scene, facts.inputs, target.sampler, x))
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        frozen(target.scene, facts.inputs, target.sampler, x)
        times.append(1000 * (time.perf_counter() - start))
    dr.sync_thread()
    return statistics.median(times)


def measure(path: str, size: int, threshold: float, rounds: int) -> None:
    global PROFILE
    scene = resized(mimarble.scene.load(path), size)
    loaded = mi.load_dict(to_mitsuba(scene, spp=1))
    plain = lambda: render_in_passes(loaded, 1)
    adapt = lambda: adaptive.render_adaptive(loaded, 1, threshold, 81)
    for _ in range(2):
        plain(), adapt()
    traced = adapt().traced / (size * size)
    totals = defaultdict(list)
    profiles = []
    for _ in range(rounds):
        for name, render in (("plain 1 spp", plain), ("adaptive", adapt)):
            dr.sync_thread()
            dr.kernel_history()
            start = time.perf_counter()
            render()
            dr.sync_thread()
            totals[name].append(1000 * (time.perf_counter() - start))
            totals[name + " kernels"].append(sum(
                k["execution_time"] for k in dr.kernel_history()
                if k["type"] != dr.KernelType.Memset))
        # The plain pass's frozen call alone (host), then the adaptive render profiled.
        PROFILE = Profile()
        PROFILE.step("plain", plain)
        totals["plain 1 spp replay host"].append(PROFILE.steps[(0, "plain")][3])
        PROFILE = Profile()
        start = time.perf_counter()
        adapt()
        dr.sync_thread()
        totals["adaptive profiled"].append(1000 * (time.perf_counter() - start))
        profiles.append(PROFILE)
        PROFILE = None
    walk = walk_ms(loaded)
    med = {name: statistics.median(v) for name, v in totals.items()}
    print(f"{path}, {size}², threshold {threshold:g}: {traced:.2f} samples a pixel traced")
    print(f"  plain 1 spp      {med['plain 1 spp']:7.2f} ms  kernels "
          f"{med['plain 1 spp kernels']:6.2f}  replay host "
          f"{med['plain 1 spp replay host']:5.2f} (walk {walk:.2f})")
    print(f"  adaptive         {med['adaptive']:7.2f} ms  kernels "
          f"{med['adaptive kernels']:6.2f}  profiled {med['adaptive profiled']:7.2f}")
    keys = sorted({key for p in profiles for key in p.steps},
                  key=lambda k: (k[0], ("pass", "add", "means", "refine").index(k[1])))
    accounted = 0.0
    for key in keys:
        rows = [p.steps[key] for p in profiles]
        wall, kernels, count, host = (statistics.median(r[i] for r in rows) for i in range(4))
        accounted += wall
        extra = f"  replay host {host:5.2f}" if key[1] == "pass" else ""
        print(f"  round {key[0]} {key[1]:7} {wall:7.2f} ms  kernels {kernels:6.2f} "
              f"({count:.0f}){extra}")
    print(f"  rest             {med['adaptive profiled'] - accounted:7.2f} ms")


def run_command_line(description: str, measure) -> None:
    """The command line of this script and of adaptive_lane_cost.py: ``SCENE …``, ``--size``,
    ``--threshold``, ``--rounds``; Dr.Jit's kernel history on before the first render (JIT
    flags are part of a recording's key); ``measure(path, size, threshold, rounds)`` for each
    scene, between the CPU and the load."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("scenes", nargs="*", default=["scenes/fig11a.scene",
                                                      "scenes/fine-veins/veins-p4-d8-s4.scene"])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--threshold", type=float, default=6e-4)
    parser.add_argument("--rounds", type=int, default=9)
    args = parser.parse_args()
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    facts = machine_facts()
    print(f"{facts.get('processor', '?')} ({facts.get('llvm_target', {}).get('cpu', '?')}); "
          f"load {os.getloadavg()}; medians of {args.rounds}")
    for path in args.scenes:
        measure(path, args.size, args.threshold, args.rounds)
    print(f"load after {os.getloadavg()}")


if __name__ == "__main__":
    _instrument()
    run_command_line(__doc__.splitlines()[0], measure)
