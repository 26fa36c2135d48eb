"""Choosing the libLLVM Dr.Jit loads, and the Mitsuba variant.

Dr.Jit 1.5 loads libLLVM when ``drjit`` is imported. With LLVM 15 it loads fine
and then aborts the whole process (SIGABRT, ``LLVM ERROR: Cannot select …
fminimum``) at the first kernel that uses a NaN-propagating min/max; LLVM 14 is
refused. So the library must be chosen *before* ``drjit`` is imported:

1. ``DRJIT_LIBLLVM_PATH`` set by the user: kept if it is LLVM ≥ 16, else the
   LLVM backend is switched off and the problem is reported in one sentence.
2. Otherwise the newest libLLVM ≥ 16 in the usual library folders is chosen.
3. None found: the LLVM backend is switched off (CUDA and scalar variants still
   work) and the sentence says what to install.

"Switched off" means ``DRJIT_LIBLLVM_PATH`` is pointed at a path that cannot be
loaded, so Dr.Jit disables its LLVM backend instead of aborting.

This module imports neither ``drjit`` nor ``mitsuba`` at module level: call
:func:`prepare_llvm` first, import them afterwards (:func:`import_drjit_and_mitsuba`
does both). Nor does it import any module of mimarble at module level (``./go``
runs it as a plain file to look for a libLLVM before the package is installed);
inside functions it imports only mimarble/runtime/llvm_target.py and llvm_blocks.py,
which import nothing of this module back (they reach drjit-core through
mimarble/runtime/drjit_core.py).
"""

from __future__ import annotations

import contextlib
import dataclasses
import glob
import os
import re
import sys
import warnings

MIN_LLVM_MAJOR = 16
INSTALL_HINT = "install libLLVM 16 or newer (on Debian or Ubuntu, as root: apt-get install libllvm19)"
VARIANT_ENV = "MIMARBLE_VARIANT"
AUTO_VARIANTS = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
#: The variants mimarble renders in: RGB, and (unpolarized) spectral, where its textures
#: upsample their colours with Mitsuba's sRGB model (mimarble/texture/srgb_model.py) and only path
#: mode renders (the whitted integrator computes in RGB). Mono and polarized: not.
COLOUR_SUFFIXES = ("_rgb", "_spectral")


def colour_variant(variant: str) -> bool:
    """Whether mimarble's plugins give their colours in ``variant`` (:data:`COLOUR_SUFFIXES`)."""
    return variant.endswith(COLOUR_SUFFIXES)


def whitted_problem(variant: str) -> str | None:
    """Why the ``whitted`` integrator cannot render in ``variant`` (a spectral one), or None."""
    if variant.endswith("_rgb"):
        return None
    return (f"The whitted integrator (whitted mode, the paper's model) computes in RGB, and "
            f"{variant} is a spectral variant: render in path mode (--mode path) or in an "
            f"RGB variant.")

# Dr.Jit disables its LLVM backend when this cannot be loaded (its search has no
# fallback once DRJIT_LIBLLVM_PATH is set).
_DISABLED_PATH = "/nonexistent/mimarble-disabled-libLLVM.so"

_SEARCH_GLOBS = (
    "/usr/lib/*-linux-gnu/libLLVM*.so*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/lib64/libLLVM*.so*",
    "/usr/lib/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
    "/opt/homebrew/opt/llvm/lib/libLLVM*.dylib",
    "/usr/local/opt/llvm/lib/libLLVM*.dylib",
)

# libLLVM-15.so.1, libLLVM-14.0.6.so.1, libLLVM.so.19.1, libLLVM-19.so, libLLVM.dylib…
_VERSION_IN_NAME = re.compile(r"libLLVM[-.](?:so\.)?(\d+)")


class SlowVariantWarning(UserWarning):
    """Only the scalar variant can render here."""


class EnvironmentProblem(RuntimeError):
    """Rendering cannot work in this environment; the message is one sentence for the user."""


@dataclasses.dataclass(frozen=True)
class LLVMChoice:
    path: str | None       # the library Dr.Jit is told to load (None: disabled or unknown)
    major: int | None      # its LLVM major version, when known
    source: str            # "DRJIT_LIBLLVM_PATH", "search", "already loaded", "none"
    problem: str | None    # one sentence when LLVM variants cannot work

    @property
    def usable(self) -> bool:
        return self.problem is None


def llvm_major_from_name(path: str) -> int | None:
    """The LLVM major version a library's file name (or its link target) states."""
    for name in (os.path.basename(path), os.path.basename(os.path.realpath(path))):
        m = _VERSION_IN_NAME.search(name)
        if m:
            return int(m.group(1))
    return None


_PROBE = r"""
import ctypes, sys
try:
    lib = ctypes.CDLL(sys.argv[1])
except OSError:
    print("unloadable"); sys.exit(0)
get = getattr(lib, "LLVMGetVersion", None)   # exists from LLVM 16 on
if get is None:
    print("old"); sys.exit(0)
v = [ctypes.c_uint() for _ in range(3)]
get(*[ctypes.byref(x) for x in v])
print(v[0].value)
"""


def probe_llvm_major(path: str) -> int | None | str:
    """Load the library in a child process and ask its version.

    Returns the major version, ``"old"`` (no ``LLVMGetVersion``: LLVM ≤ 15) or
    ``"unloadable"``. A child process, because a library loaded here would be
    the one Dr.Jit picks up.
    """
    import subprocess   # here, not at the top: the command line's start-up skips it
    try:
        out = subprocess.run([sys.executable, "-c", _PROBE, path], capture_output=True,
                             text=True, timeout=60).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unloadable"
    return int(out) if out.isdigit() else (out or "unloadable")


def llvm_major(path: str) -> int | str:
    """Major version of the libLLVM at ``path``, ``"old"`` or ``"unloadable"``."""
    if not os.path.isfile(path):
        return "unloadable"
    major = llvm_major_from_name(path)
    return major if major is not None else probe_llvm_major(path)


def search_libllvm() -> list[tuple[int, str]]:
    """Every libLLVM ≥ 16 found in the usual folders, newest first."""
    found = {}
    dirs = [d for d in os.environ.get("LD_LIBRARY_PATH", "").split(os.pathsep) if d]
    patterns = [os.path.join(d, "libLLVM*.so*") for d in dirs] + list(_SEARCH_GLOBS)
    for pattern in patterns:
        for path in glob.glob(pattern):
            major = llvm_major_from_name(path)
            real = os.path.realpath(path)
            if major is not None and major >= MIN_LLVM_MAJOR and os.path.isfile(real):
                found.setdefault(real, (major, path))
    return sorted(found.values(), key=lambda mp: (-mp[0], mp[1]))


def _loaded_libllvm() -> str | None:
    """The libLLVM mapped into this process, if any (Linux only)."""
    try:
        with open("/proc/self/maps") as f:
            m = re.search(r"(/\S*libLLVM\S*)", f.read())
    except OSError:
        return None
    return m.group(1) if m else None


def _bad_library_sentence(path: str, what: int | str) -> str:
    if what == "unloadable":
        detail = "cannot be loaded"
    elif what == "old":
        detail = f"is older than LLVM {MIN_LLVM_MAJOR}"
    else:
        detail = f"is LLVM {what}"
    return (f"DRJIT_LIBLLVM_PATH={path} {detail}, but Dr.Jit 1.5 needs libLLVM "
            f"{MIN_LLVM_MAJOR} or newer (LLVM 15 aborts the process): {INSTALL_HINT} "
            f"and point DRJIT_LIBLLVM_PATH at it, or unset it.")


_choice: LLVMChoice | None = None


def prepare_llvm() -> LLVMChoice:
    """Decide which libLLVM Dr.Jit will load; must run before ``import drjit``.

    Idempotent. Never aborts and never raises: a problem is recorded in the
    returned choice (and LLVM switched off), for callers to report.
    """
    global _choice
    if _choice is not None:
        return _choice

    if "drjit" in sys.modules:
        # Too late to choose: ask Dr.Jit what it loaded.
        import drjit as dr
        major = dr.detail.llvm_version()[0]
        path = _loaded_libllvm()
        if major < 0:
            problem = f"Dr.Jit found no usable libLLVM: {INSTALL_HINT}."
        elif major < MIN_LLVM_MAJOR:
            problem = (f"Dr.Jit was imported before mimarble and loaded LLVM {major} ({path}), "
                       f"which aborts the process: import mimarble first, or {INSTALL_HINT}.")
        else:
            problem = None
        _choice = LLVMChoice(path, major if major >= 0 else None, "already loaded", problem)
        return _choice

    user_path = os.environ.get("DRJIT_LIBLLVM_PATH")
    if user_path:
        what = llvm_major(user_path)
        if isinstance(what, int) and what >= MIN_LLVM_MAJOR:
            _choice = LLVMChoice(user_path, what, "DRJIT_LIBLLVM_PATH", None)
        else:
            _choice = LLVMChoice(None, what if isinstance(what, int) else None,
                                 "DRJIT_LIBLLVM_PATH", _bad_library_sentence(user_path, what))
    else:
        found = search_libllvm()
        if found:
            major, path = found[0]
            _choice = LLVMChoice(path, major, "search", None)
        else:
            _choice = LLVMChoice(None, None, "none",
                                 f"No libLLVM {MIN_LLVM_MAJOR} or newer was found: {INSTALL_HINT}.")

    os.environ["DRJIT_LIBLLVM_PATH"] = _choice.path if _choice.usable else _DISABLED_PATH
    return _choice


@contextlib.contextmanager
def _quiet_stderr(enabled: bool):
    """Silence file descriptor 2 (Dr.Jit's C++ prints there when LLVM is switched off)."""
    if not enabled:
        yield
        return
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


#: ``MIMARBLE_FREEZE=0`` turns off the replay of recorded passes (mimarble/mitsuba/rendering/replay.py).
FREEZE_ENV = "MIMARBLE_FREEZE"


def replay_wanted() -> bool:
    """Whether ``$MIMARBLE_FREEZE`` leaves replay on (anything but ``0``); read each time."""
    return os.environ.get(FREEZE_ENV, "1").strip() != "0"


def replay_sentence() -> str:
    """What ``mimarble doctor`` says about replay."""
    if replay_wanted():
        return (f"on in JIT RGB variants (recorded passes replayed, dr.freeze; {FREEZE_ENV}=0 "
                f"turns it off; spectral variants trace every pass)")
    return f"off ({FREEZE_ENV}=0)"


JIT_DEBUG_ENV = "MIMARBLE_JIT_DEBUG"
_jit_configured = False


def import_drjit_and_mitsuba():
    """Import Dr.Jit and Mitsuba, set up once; returns ``(dr, mi)``.

    Every module of mimarble that needs them comes through here, so the set-up
    holds whichever module loads first: the libLLVM is chosen before Dr.Jit
    loads one, the CPU kernels' LLVM target is set before the first kernel
    (mimarble/runtime/llvm_target.py) and the lanes of its launches' blocks
    (mimarble/runtime/llvm_blocks.py), and ``MIMARBLE_JIT_DEBUG=1`` turns on Dr.Jit's
    bounds checks (every gather, scatter and symbolic call checked, bad lanes
    masked and reported on stderr; ``./go test --jit-debug``).
    """
    global _jit_configured
    choice = prepare_llvm()
    with _quiet_stderr("drjit" not in sys.modules and not choice.usable):
        import drjit as dr
        import mitsuba as mi
    if not _jit_configured:
        _jit_configured = True
        if llvm_backend_up():
            from . import llvm_blocks, llvm_target
            llvm_target.configure()
            llvm_blocks.configure()          # after the target: its vector width
        if os.environ.get(JIT_DEBUG_ENV) == "1":
            enable_bounds_checks()
    return dr, mi


#: Mitsuba's differentiable integrators, Python modules of ``mitsuba.python.ad.integrators``
#: (Mitsuba 3.9); ``common`` (their base classes, cheap) is kept.
MITSUBA_AD_INTEGRATORS = ("prb_basic", "prb", "prbvolpath", "direct_projective",
                          "prb_projective", "volprim_rf_basic")


def skip_mitsuba_ad_integrators() -> bool:
    """Keep Mitsuba from building its differentiable integrators at the first ``set_variant``.

    Setting an LLVM or CUDA variant (re)imports ``mitsuba.python.ad.integrators``, whose
    modules rewrite ten ``@dr.syntax`` functions from their source: most of what
    ``set_variant`` takes, a large part of a short command's process (docs/benchmarks.md,
    "Figures moved out of the code"). The command line uses none of them (``whitted`` is
    mimarble's integrator, ``path`` Mitsuba's C++ one), so the command's process
    places empty modules under their names first: the package's ``__init__``
    then finds them imported and moves on. Only those integrators (``prb``,
    ``prbvolpath``, …) are missing from such a process; a later change of
    variant reloads them for real, so nothing breaks, it is only slower. Call it
    before the first variant is set; returns whether it was done.
    """
    _, mi = import_drjit_and_mitsuba()
    if mi.variant() is not None:
        return False
    import types
    for name in MITSUBA_AD_INTEGRATORS:
        full = f"mitsuba.python.ad.integrators.{name}"
        sys.modules.setdefault(full, types.ModuleType(full))
    return True


def llvm_backend_up() -> bool:
    dr, _ = import_drjit_and_mitsuba()
    try:
        return bool(dr.has_backend(dr.JitBackend.LLVM))
    except Exception:
        return False


def enable_bounds_checks() -> None:
    """Dr.Jit's ``JitFlag.Debug``: every gather, scatter and symbolic call bounds-checked.

    Out-of-range lanes are masked and reported on stderr. Packet operations are
    turned off with it: Dr.Jit 1.5 checks a packet ``scatter_reduce`` (Mitsuba's
    image block) against the wrong positions, reporting false out-of-bounds
    writes and dropping them (a plain Mitsuba ``direct`` render at 96², 4 spp:
    mean 0.84 → 0.60); separate scatters are checked correctly, same values.
    """
    dr, _ = import_drjit_and_mitsuba()
    dr.set_flag(dr.JitFlag.Debug, True)
    dr.set_flag(dr.JitFlag.PacketOps, False)


def cuda_usable() -> bool:
    dr, _ = import_drjit_and_mitsuba()
    try:
        return bool(dr.has_backend(dr.JitBackend.CUDA))
    except Exception:  # a broken driver reports itself as an exception
        return False


def variant_problem(variant: str) -> str | None:
    """Why ``variant`` cannot render here, or None when it can."""
    _, mi = import_drjit_and_mitsuba()
    if variant not in mi.variants():
        return (f"Unknown Mitsuba variant {variant!r}: this Mitsuba has "
                f"{', '.join(mi.variants())}.")
    if not colour_variant(variant):
        usable = [v for v in mi.variants() if colour_variant(v)]
        return (f"Variant {variant} is neither an RGB nor a spectral variant: mimarble's "
                f"colours are RGB (upsampled to spectra in spectral variants), so use one "
                f"of {', '.join(usable)}.")
    if variant.startswith("llvm_"):
        problem = prepare_llvm().problem
        if problem is None and not llvm_backend_up():
            problem = (f"Dr.Jit could not start its LLVM backend with {prepare_llvm().path}: "
                       f"{INSTALL_HINT}, or point DRJIT_LIBLLVM_PATH at a working libLLVM.")
        return problem
    if variant.startswith("cuda_") and not cuda_usable():
        return f"Variant {variant} needs a usable CUDA GPU and driver, and there is none."
    return None


def usable_variants() -> list[str]:
    """The RGB variants of this Mitsuba that can render here, best first."""
    _, mi = import_drjit_and_mitsuba()
    rgb = [v for v in mi.variants() if v.endswith("_rgb")]
    ordered = [v for v in AUTO_VARIANTS if v in rgb] + [v for v in rgb if v not in AUTO_VARIANTS]
    return [v for v in ordered if variant_problem(v) is None]


def with_alternatives(problem: str, requested: str) -> str:
    """``problem`` (one sentence) ending with the variants that can render here instead."""
    others = [v for v in usable_variants() if v != requested]
    if not others:
        return problem
    listed = others[0] if len(others) == 1 else f"{', '.join(others[:-1])} and {others[-1]}"
    return f"{problem.rstrip().rstrip('.')}; {listed} can render here."


def choose_variant(requested: str | None = None) -> str:
    """The variant to use: ``requested``, else ``$MIMARBLE_VARIANT``, else the best usable.

    Raises :class:`EnvironmentProblem` when an explicitly requested variant cannot work.
    Automatic choice: ``cuda_ad_rgb`` with a usable GPU, else ``llvm_ad_rgb``, else
    ``scalar_rgb`` with a warning that it is slow.
    """
    requested = requested or os.environ.get(VARIANT_ENV) or None
    if requested:
        problem = variant_problem(requested)
        if problem:
            raise EnvironmentProblem(with_alternatives(problem, requested))
        return requested
    for variant in AUTO_VARIANTS:
        if variant_problem(variant) is None:
            if variant.startswith("scalar"):
                llvm = prepare_llvm().problem
                warnings.warn(f"mimarble: using the slow scalar_rgb variant. {llvm}",
                              SlowVariantWarning, stacklevel=3)
            return variant
    raise EnvironmentProblem("No Mitsuba variant can render here.")  # scalar always can


def require_colour_variant(mode: str | None = None) -> None:
    """Raise :class:`EnvironmentProblem` (one sentence) unless the Mitsuba variant is an RGB
    or a spectral one, and an RGB one for ``mode`` ``"whitted"``."""
    _, mi = import_drjit_and_mitsuba()
    variant = mi.variant()
    problem = variant_problem(variant) if variant and not colour_variant(variant) else None
    if problem:
        raise EnvironmentProblem(with_alternatives(problem, variant))
    problem = whitted_problem(variant) if variant and mode == "whitted" else None
    if problem:
        raise EnvironmentProblem(problem)


def use_variant(requested: str | None = None) -> str:
    """Set the Mitsuba variant mimarble renders in, and return its name:
    ``mimarble.use_variant()`` and the command line's ``--variant`` both come here.

    ``requested`` None: ``$MIMARBLE_VARIANT`` when set (it wins over a variant already
    set, as it does for the command line), else a variant already set (``mi.set_variant``)
    is kept, else the best usable one (:func:`choose_variant`). A variant
    named (``use_variant("cuda_ad_rgb")``) is checked before Mitsuba switches to it:
    one that cannot render here — no GPU, no usable libLLVM, not RGB, unknown — raises
    :class:`EnvironmentProblem`, one sentence saying why and which variants can
    (instead of Dr.Jit's "CUDA backend hasn't been initialized" from ``mi.set_variant``).
    """
    _, mi = import_drjit_and_mitsuba()
    current = mi.variant()
    if requested is None and not os.environ.get(VARIANT_ENV) and current is not None:
        return current
    variant = choose_variant(requested)
    if variant != current:
        mi.set_variant(variant)
    return variant


def doctor(requested: str | None = None) -> tuple[list[tuple[str, str]], bool]:
    """Facts about the rendering environment, and whether rendering can work.

    ``requested`` is a variant the user asked for (``--variant``); without it,
    the automatic choice (or ``$MIMARBLE_VARIANT``) is examined.
    """
    choice = prepare_llvm()
    dr, mi = import_drjit_and_mitsuba()
    rows = [("python", sys.version.split()[0]),
            ("mitsuba", mi.__version__),
            ("drjit", dr.__version__)]
    loaded = _loaded_libllvm()
    version = dr.detail.llvm_version()
    if version[0] >= 0:
        rows.append(("libLLVM", f"{loaded or choice.path} (LLVM {'.'.join(map(str, version))}, "
                                f"chosen by {choice.source})"))
    else:
        rows.append(("libLLVM", "none loaded"))
    if llvm_backend_up():
        from . import llvm_target
        outcome = llvm_target.configure()
        rows.append(("llvm target", f"{outcome.target.summary()} ({outcome.how})"
                     if outcome.target else outcome.how))
        from . import llvm_blocks
        blocks = llvm_blocks.configure()
        rows.append(("llvm blocks", f"{blocks.block_size} lanes ({blocks.how})"
                     if blocks.block_size else blocks.how))
    rows.append(("cuda", "usable" if cuda_usable() else "not usable"))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # the problem gets its own row below
            variant = choose_variant(requested)
        rows.append(("variant", variant))
        spectral = [v for v in mi.variants() if v.endswith("_spectral")
                    and variant_problem(v) is None]
        rows.append(("spectral", f"{', '.join(spectral)} (--variant; path mode only)"
                     if spectral else "none usable here"))
    except EnvironmentProblem as e:
        rows.append(("variant", f"none: {e}"))
        return rows, False
    if choice.problem:
        rows.append(("problem", choice.problem))
    # Only the slow scalar fallback left counts as "cannot work": fix the problem above.
    return rows, not variant.startswith("scalar_")
