"""mimarble — the marble solid texture of Park & Park (2004) for Mitsuba 3.

Importing the package chooses a libLLVM that cannot abort the process (before
Dr.Jit loads one), sets a Mitsuba variant if none is set yet (``cuda_ad_rgb``
with a usable GPU, else ``llvm_ad_rgb``, else ``scalar_rgb``; ``$MIMARBLE_VARIANT``
overrides), and registers the ``marble`` texture for every variant.

The ``mimarble`` command's own process (its console script, ``python -m
mimarble``) defers all of that to :func:`start`, which a command calls once it
needs to render: help, usage errors and scene errors then answer before Dr.Jit
and Mitsuba load (docs/design-decisions.md, "Start-up"; the times: docs/benchmarks.md,
"Start-up: the whole process").
Touching any of the names below that need them (``mimarble.render``,
``mimarble.mi``, …) starts the package too.

The API: ``mimarble.render(scene_or_path, spp=…, width=…, height=…, mode=…, …)`` (a
scene file, model or loaded ``mi.Scene`` → linear float32 (H, W, 3); ``width`` and
``height`` as the command line's ``--width``/``--height``), ``mimarble.use_variant(name)``
(a variant checked before it is set: one sentence naming what can render when it cannot,
as ``--variant`` says it), ``mimarble.sweep``, ``mimarble.to_mitsuba``,
``mimarble.write_image``, ``mimarble.scene`` (the scene language),
``mimarble.packaged_scenes`` (the paper's scenes shipped with the package) and
``mimarble.studio(scene)`` (the marble studio inline in a notebook; ``mimarble studio``).
"""

import importlib
import os
import sys

from mimarble.runtime import environment, moved
from mimarble.runtime.environment import EnvironmentProblem, use_variant

moved.install()                          # the old import paths of moved modules, one release

__all__ = ["EnvironmentProblem", "marble", "noise", "render", "scene", "start", "sweep",
           "to_mitsuba", "use_variant", "write_image"]
__version__ = "0.1.0"

# Names that exist once start() has run.
_STARTED_NAMES = frozenset(("dr", "mi", "noise", "marble", "plugins", "render", "to_mitsuba",
                            "write_image", "startup_problem"))
# The modules behind the public names above: name -> path under mimarble.
_STARTED_MODULES = {"noise": "texture.noise", "marble": "mitsuba.plugins.marble",
                    "plugins": "mitsuba.plugins.registration", "scene": "scene"}
_state = {"started": False, "starting": False}


def start() -> None:
    """Load Dr.Jit and Mitsuba the safe way, pick a variant, register the plugins; idempotent.

    A variant problem (a bad ``$MIMARBLE_VARIANT``) does not raise here: it is
    kept in ``mimarble.startup_problem`` and raised again by whatever needs the
    variant.
    """
    if _state["started"] or _state["starting"]:
        return
    _state["starting"] = True
    try:
        dr, mi = environment.import_drjit_and_mitsuba()
        startup_problem = None
        if mi.variant() is None:
            try:
                use_variant()
            except EnvironmentProblem as e:
                startup_problem = e
        modules = {name: importlib.import_module(f"{__name__}.{path}")
                   for name, path in _STARTED_MODULES.items()}
        mitsuba_side = importlib.import_module(f"{__name__}.mitsuba")
        globals().update(dr=dr, mi=mi, startup_problem=startup_problem,
                         render=mitsuba_side.render, to_mitsuba=mitsuba_side.to_mitsuba,
                         write_image=mitsuba_side.write_image, **modules)
        modules["plugins"].install()
        _state["started"] = True
    finally:
        _state["starting"] = False


def __getattr__(name):
    if name in _STARTED_NAMES:
        start()
        if name in globals():
            return globals()[name]
    elif name == "scene":                # neither imports Dr.Jit nor Mitsuba
        return importlib.import_module(f"{__name__}.scene")
    elif name == "packaged_scenes":
        return importlib.import_module(f"{__name__}.runtime.packaged_scenes")
    elif name == "sweep":                # mimarble.sweeps.run.sweep: its frames start the package
        return importlib.import_module(f"{__name__}.sweeps.run").sweep
    elif name == "studio":               # a callable package: mimarble.studio(scene) in Jupyter
        return importlib.import_module(f"{__name__}.studio")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _is_the_command_process() -> bool:
    """Whether this process is the ``mimarble`` command: its console script or ``-m mimarble``."""
    argv = list(getattr(sys, "orig_argv", ()))
    i = 1
    while i < len(argv):                 # the interpreter's own options, up to what it runs
        arg = argv[i]
        if arg == "-m":
            return argv[i + 1:i + 2] in (["mimarble"], ["mimarble.cli"])
        if arg.startswith("-m"):
            return arg[2:] in ("mimarble", "mimarble.cli")
        if arg in ("-X", "-W", "--check-hash-based-pycs"):
            i += 2
            continue
        if arg == "-c" or arg == "-" or not arg.startswith("-"):
            break
        i += 1
    return os.path.basename(sys.argv[0]) in ("mimarble", "mimarble.exe")


if not _is_the_command_process():
    start()
