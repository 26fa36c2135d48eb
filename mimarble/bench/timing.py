"""The benchmark's measurements of one render: warm run time after a sync, the first
render's compile time, the samples traced, and the converged reference it is measured
against (cached on disk).

Every timing is a median of warm runs taken after a sync (LLVM kernel launches are
asynchronous; converting the image to NumPy waits for it), with the first render's
compile time reported apart from Dr.Jit's kernel history.
"""

from __future__ import annotations

import dataclasses
import hashlib
import statistics
import time
from pathlib import Path

import numpy as np

from mimarble import reference
from mimarble.bench.modes import ADAPTIVE_FIRST_SPP
from mimarble.mitsuba.rendering.render import render_in_passes
from mimarble.mitsuba.rendering.silhouettes import edge_mask
from mimarble.mitsuba.translate.scene_dict import to_mitsuba
from mimarble.runtime import environment, files, kernel_cache

dr, mi = environment.import_drjit_and_mitsuba()



@dataclasses.dataclass
class Timing:
    run_ms: float                 # median of the warm runs
    runs_ms: list
    compile_ms: float             # codegen + backend of the first render's kernels
    kernels_compiled: int         # kernels of the first render not found in any cache
    image: np.ndarray = dataclasses.field(repr=False)
    result: object = dataclasses.field(default=None, repr=False)   # the last render's own


def _timed(render, repeats: int, image_of=lambda result: result) -> Timing:
    """Render once (compile), then ``repeats`` warm renders, each after a sync."""
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        result = render()
        first = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    runs = []
    for _ in range(repeats):
        dr.sync_thread()
        start = time.perf_counter()
        result = render()
        runs.append(1000 * (time.perf_counter() - start))
    return Timing(run_ms=statistics.median(runs), runs_ms=runs,
                  compile_ms=sum(k["codegen_time"] + k["backend_time"] for k in first),
                  kernels_compiled=kernel_cache.compiled(first), image=image_of(result),
                  result=result)


def time_render(scene, spp: int, repeats: int, edge_spp: int | None = None) -> Timing:
    """Load once, render once (compile), then ``repeats`` warm renders after a sync, as
    ``mimarble.render`` renders (``render_in_passes``: one kernel for every spp, ray
    differentials from the eye, edge samples)."""
    mitsuba_scene = mi.load_dict(to_mitsuba(scene, spp=spp))
    return _timed(lambda: render_in_passes(mitsuba_scene, spp, edge_spp=edge_spp), repeats)


def time_adaptive(scene, threshold: float, max_spp: int, repeats: int,
                  spp: int = ADAPTIVE_FIRST_SPP, loaded=None) -> Timing:
    """As :func:`time_render`, through ``render_adaptive`` (first pass ``spp``, more
    samples where a pixel's estimated error is above ``threshold``, at most ``max_spp``);
    the Timing's ``result`` is the last render's (``samples``, ``traced``, ``rounds``).
    ``loaded``: ``scene`` already loaded into Mitsuba (one load for every threshold)."""
    from mimarble.mitsuba.rendering.adaptive import render_adaptive
    mitsuba_scene = loaded if loaded is not None else mi.load_dict(to_mitsuba(scene, spp=spp))
    return _timed(lambda: render_adaptive(mitsuba_scene, spp, threshold, max_spp), repeats,
                  image_of=lambda result: np.asarray(result.image))


def samples_taken(mitsuba_scene, spp: int, edge_spp: int | None) -> float:
    """Mean samples traced per pixel by ``render_in_passes(mitsuba_scene, spp, edge_spp=…)``:
    ``spp``, plus ``edge_spp`` more on each silhouette pixel (its replaced samples count)."""
    if edge_spp is None or edge_spp <= spp:
        return float(spp)
    return spp + edge_spp * float(np.mean(edge_mask(mitsuba_scene, spp)))


def _reference_source_digest() -> str:
    """A digest of the reference tracer's code: a fixed tracer invalidates cached images."""
    digest = hashlib.sha256()
    for path in sorted(Path(reference.__file__).parent.glob("*.py")):
        digest.update(path.read_bytes())
    return digest.hexdigest()


def converged(scene, spp: int, cache_dir: Path) -> np.ndarray:
    """The reference tracer's image at ``spp``, cached by scene, spp and tracer code."""
    key = hashlib.sha256(repr((scene, spp, _reference_source_digest())).encode()).hexdigest()[:20]
    path = cache_dir / f"converged-{key}.npy"
    if path.exists():
        return np.load(path)
    image = reference.render(scene, spp=spp)
    cache_dir.mkdir(parents=True, exist_ok=True)
    files.write_atomically(path, lambda tmp: np.save(tmp, image))
    return image


def hit_fraction(image_alpha_free: np.ndarray, background) -> float:
    return float(np.mean(np.any(image_alpha_free != np.asarray(background, np.float32), axis=-1)))
