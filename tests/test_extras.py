"""The optional extras (dask, matplotlib): without one, its features refuse in one sentence
naming it, and everything else works. A missing extra is simulated by an import hook that
refuses its modules, not by uninstalling it."""

import os
import subprocess
import sys

import pytest

from commands import ROOT, one_sentence
from mimarble.runtime.extras import EXTRAS, MissingExtra, missing_extra, require_extra
from mimarble.sweeps.cluster import check_scheduler, check_workers
from mimarble.sweeps.settings import SweepError

DASK = "sweeps with --workers need the 'dask' extra: pip install 'mimarble[dask]'"
MATPLOTLIB_DIFF = ("error maps' legends (compare --diff) need the 'matplotlib' extra: "
                   "pip install 'mimarble[matplotlib]'")
MATPLOTLIB_PLOT = ("benchmark plots (bench --plot) need the 'matplotlib' extra: "
                   "pip install 'mimarble[matplotlib]'")
SCENE = ROOT / "scenes" / "fig11a.scene"

# Run in a fresh process before mimarble: imports of the named packages fail as if they
# were not installed.
_HOOK = """
import sys
class Missing:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in {missing!r}:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
sys.meta_path.insert(0, Missing())
from mimarble.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


def without(missing, *args, cwd=ROOT):
    """``mimarble ARGS`` in a fresh process where the packages ``missing`` cannot be
    imported."""
    env = dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb",
               PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    result = subprocess.run([sys.executable, "-c", _HOOK.format(missing=set(missing)),
                             *map(str, args)], cwd=cwd, env=env, capture_output=True,
                            text=True, timeout=300)
    sys.stderr.write(result.stderr)
    return result


@pytest.fixture
def hide(monkeypatch):
    """hide(extra): its module cannot be imported in this process while the test runs."""
    def hide(extra):
        monkeypatch.setitem(sys.modules, EXTRAS[extra], None)
    return hide


def test_installed_extras_are_not_missing():
    assert missing_extra("sweep --workers") is None
    assert missing_extra("bench --plot") is None
    require_extra("compare --diff")


def test_sweeps_on_dask_refuse_without_it(hide):
    hide("dask")
    with pytest.raises(SweepError) as e:
        check_workers(2)
    assert str(e.value) == DASK
    with pytest.raises(SweepError, match=r"^sweeps with --scheduler need the 'dask' extra"):
        check_scheduler("tcp://127.0.0.1:9")
    with pytest.raises(SweepError, match="whole number"):      # a bad number is still that
        check_workers(0)


def test_plots_and_legends_refuse_without_matplotlib(hide, tmp_path):
    from mimarble.bench.plot import plot_error_against_time
    from mimarble.tools.compare import error_map_legend
    hide("matplotlib")
    with pytest.raises(MissingExtra) as e:
        error_map_legend(400)
    assert str(e.value) == MATPLOTLIB_DIFF and isinstance(e.value, ImportError)
    with pytest.raises(MissingExtra, match=r"^benchmark plots \(bench --plot\) need"):
        plot_error_against_time({"runs": []}, tmp_path / "plot.png")


def test_commands_refuse_in_one_sentence_before_any_work(tmp_path):
    sweep = without({"dask", "distributed"}, "sweep", SCENE, "--set", "marble.period=1,2",
                    "--workers", "2", "-o", tmp_path / "sweep")
    assert one_sentence(sweep) == f"mimarble: {DASK}"
    assert not (tmp_path / "sweep").exists()
    diff = without({"matplotlib"}, "compare", SCENE, "--diff", tmp_path / "diff.png")
    assert one_sentence(diff) == f"mimarble: {MATPLOTLIB_DIFF}"
    plot = without({"matplotlib"}, "bench", SCENE, "--plot", tmp_path / "plot.png")
    assert one_sentence(plot) == f"mimarble: {MATPLOTLIB_PLOT}"
    assert list(tmp_path.iterdir()) == []


def test_render_and_a_sweep_in_one_process_need_no_extra(llvm, tmp_path):
    missing = {"dask", "distributed", "matplotlib"}
    render = without(missing, "render", SCENE, "--width", "8", "--height", "8", "--spp", "1",
                     "-o", tmp_path / "m.png")
    assert render.returncode == 0, render.stderr
    assert (tmp_path / "m.png").stat().st_size > 0
    sweep = without(missing, "sweep", SCENE, "--set", "marble.period=1,2", "--width", "8",
                    "--height", "8", "--spp", "1", "-o", tmp_path / "sweep")
    assert sweep.returncode == 0, sweep.stderr
    assert (tmp_path / "sweep" / "contact.png").exists()
