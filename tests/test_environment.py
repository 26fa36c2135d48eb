"""The libLLVM guard and the variant choice, in child processes (a bad LLVM must never abort)."""

import glob
import os
import subprocess
import sys

import pytest

import mimarble
from mimarble.runtime import environment

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CLEAR = "needs libLLVM 16 or newer"


def run(code_or_args, env_extra=None, module=False):
    env = {k: v for k, v in os.environ.items()
           if k not in ("DRJIT_LIBLLVM_PATH", environment.VARIANT_ENV)}
    env.update(env_extra or {})
    args = ["-m", "mimarble", *code_or_args] if module else ["-c", code_or_args]
    return subprocess.run([sys.executable, *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)


def old_llvm():
    # LLVM 15 first: Dr.Jit loads it and then aborts, the case that matters most.
    found = (sorted(glob.glob("/usr/lib/*-linux-gnu/libLLVM-15.so*")) +
             sorted(glob.glob("/usr/lib/*-linux-gnu/libLLVM-14*.so*")))
    if not found:
        pytest.skip("no libLLVM 14/15 on this machine")
    return found[0]


@pytest.fixture
def garbage_library(tmp_path):
    path = tmp_path / "libLLVM-custom.so"       # no version in the name: probed
    path.write_bytes(b"this is not a shared library")
    return str(path)


def test_version_is_read_from_library_names():
    assert environment.llvm_major_from_name("/x/libLLVM-15.so.1") == 15
    assert environment.llvm_major_from_name("/x/libLLVM-14.0.6.so.1") == 14
    assert environment.llvm_major_from_name("/x/libLLVM.so.19.1") == 19
    assert environment.llvm_major_from_name("/x/libLLVM-19.so") == 19
    assert environment.llvm_major_from_name("/x/libfoo.so") is None


def test_unversioned_library_is_probed_in_a_child_process(tmp_path, garbage_library):
    assert environment.llvm_major(garbage_library) == "unloadable"
    assert environment.llvm_major(str(tmp_path / "missing.so")) == "unloadable"
    link = tmp_path / "libsomething.so"
    link.symlink_to(old_llvm())
    # symlink target names the version; a copy under a neutral name must be probed
    assert environment.llvm_major(str(link)) in (14, 15)
    assert environment.probe_llvm_major(old_llvm()) == "old"


def test_the_search_finds_only_usable_versions():
    for major, path in environment.search_libllvm():
        assert major >= environment.MIN_LLVM_MAJOR
        assert os.path.exists(path)


def test_old_llvm_forced_gives_clear_sentence_and_normal_exit():
    result = run(["--variant", "llvm_ad_rgb", "doctor"], {"DRJIT_LIBLLVM_PATH": old_llvm()}, module=True)
    assert result.returncode == 1                      # not -6 (SIGABRT)
    assert CLEAR in result.stdout + result.stderr
    assert "Traceback" not in result.stderr


def test_unloadable_library_forced_gives_clear_sentence_and_normal_exit(garbage_library):
    result = run(["doctor"], {"DRJIT_LIBLLVM_PATH": garbage_library}, module=True)
    assert result.returncode == 1
    assert "cannot be loaded" in result.stdout and CLEAR in result.stdout
    assert "Traceback" not in result.stderr


def test_with_old_llvm_forced_the_package_still_works_without_aborting():
    code = ("import mimarble, numpy as np; from mimarble import noise; "
            "print(mimarble.mi.variant(), noise.perlin(np.array([[3.14, 42, 7]]))[0])")
    result = run(code, {"DRJIT_LIBLLVM_PATH": old_llvm()})
    assert result.returncode == 0, result.stderr
    variant, value = result.stdout.split()
    assert variant.startswith("scalar") or variant.startswith("cuda")
    assert abs(float(value) - 0.13691995878400012) < 1e-6
    assert CLEAR in result.stderr                       # the warning says why it is slow


def test_drjit_imported_first_with_old_llvm_is_detected_not_run():
    code = "import drjit; import mimarble; print(mimarble.mi.variant())"
    result = run(code, {"DRJIT_LIBLLVM_PATH": old_llvm()})
    assert result.returncode == 0, result.stderr
    assert "import mimarble first" in result.stderr
    assert not result.stdout.strip().startswith("llvm")


def test_requesting_llvm_with_bad_library_raises_environment_problem():
    code = ("import mimarble\ntry:\n    mimarble.use_variant('llvm_ad_rgb')\n"
            "except mimarble.EnvironmentProblem as e:\n    print('problem:', e)")
    result = run(code, {"DRJIT_LIBLLVM_PATH": old_llvm()})
    assert result.returncode == 0 and "problem:" in result.stdout and CLEAR in result.stdout


def test_import_keeps_a_variant_the_user_set():
    code = ("import mitsuba as mi; mi.set_variant('scalar_rgb'); import mimarble; "
            "t = mi.load_dict({'type': 'marble'}); print(mi.variant())")
    result = run(code)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "scalar_rgb"


def test_variant_environment_variable_is_honoured():
    result = run("import mimarble; print(mimarble.mi.variant())",
                 {environment.VARIANT_ENV: "scalar_rgb"})
    assert result.stdout.strip() == "scalar_rgb"


def test_unknown_variant_is_a_clear_error():
    result = run(["--variant", "nonsense_rgb", "doctor"], module=True)
    assert result.returncode == 1
    assert "Unknown Mitsuba variant 'nonsense_rgb'" in result.stdout


@pytest.mark.parametrize("variant", ["llvm_ad_mono", "llvm_ad_spectral_polarized",
                                     "scalar_spectral_polarized"])
def test_a_variant_neither_rgb_nor_spectral_is_one_clear_sentence_before_any_work(variant):
    if variant not in mimarble.mi.variants():
        pytest.skip(f"this Mitsuba has no {variant}")
    scene = os.path.join(ROOT, "scenes", "fig10a.scene")
    render = run(["--variant", variant, "render", scene, "-o", os.devnull + ".png"], module=True)
    assert render.returncode == 2, render.stderr
    assert f"Variant {variant} is neither an RGB nor a spectral variant" in render.stderr
    assert "Traceback" not in render.stderr and len(render.stderr.strip().splitlines()) == 1
    doctor = run(["--variant", variant, "doctor"], module=True)
    assert doctor.returncode == 1
    assert "neither an RGB nor a spectral" in doctor.stdout \
        and "rendering can work" not in doctor.stdout
    from_environment = run(["render", scene], {environment.VARIANT_ENV: variant}, module=True)
    assert from_environment.returncode == 2 \
        and "neither an RGB nor a spectral" in from_environment.stderr


def test_doctor_reports_library_variant_and_versions():
    result = run(["doctor"], module=True)
    out = result.stdout
    for key in ("libLLVM", "variant", "mitsuba", "drjit"):
        assert key in out
    expected_ok = environment.prepare_llvm().usable or environment.cuda_usable()
    assert (result.returncode == 0) == expected_ok


def test_drjit_core_is_opened_only_once_drjit_is_imported(monkeypatch):
    """mimarble/runtime/drjit_core.py opens the imported Dr.Jit's libdrjit-core, and never imports
    Dr.Jit itself (that is environment's job, which chooses the libLLVM first)."""
    from mimarble.runtime import drjit_core, kernel_cache
    lib = drjit_core.library()                  # `import mimarble` imported Dr.Jit
    assert hasattr(lib, kernel_cache._CACHE_DIR)
    assert kernel_cache.folder() is not None or not os.environ.get("HOME")
    monkeypatch.delitem(sys.modules, "drjit")
    with pytest.raises(OSError, match="not imported"):
        drjit_core.library()


def test_marble_is_registered_for_variants_set_after_import():
    previous = mimarble.mi.variant()
    try:
        mimarble.mi.set_variant("scalar_rgb")
        assert "Marble" in str(mimarble.mi.load_dict({"type": "marble"}))
    finally:
        mimarble.mi.set_variant(previous)
