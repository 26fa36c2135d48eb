"""Mitsuba's whitted render against the independent float64 reference, on every paper scene."""

import glob
import json
import os
import subprocess
import sys

import pytest

import mimarble
from mimarble import reference
from mimarble.tools.compare import LEGEND_HEIGHT, image_metrics
from mimarble.scene.edits import resized

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = sorted(glob.glob(os.path.join(ROOT, "scenes", "*.scene")))

# The targets, at equal sampling.
MIN_PSNR_DB = 50.0
MAX_FRACTION_OFF = 0.002


@pytest.mark.parametrize("path", SCENES, ids=os.path.basename)
def test_whitted_matches_reference_on_paper_scene(llvm, path):
    scene = resized(mimarble.scene.load(path), 64)
    metrics = image_metrics(mimarble.render(scene), reference.render(scene))
    assert metrics["psnr"] >= MIN_PSNR_DB, metrics
    assert metrics["frac_over_1_255"] <= MAX_FRACTION_OFF, metrics


def test_compare_command_prints_json_last_and_writes_the_map_with_its_legend(tmp_path):
    scene = os.path.join(ROOT, "scenes", "fig10a.scene")
    diff = tmp_path / "diff.png"
    env = dict(os.environ, MIMARBLE_VARIANT="llvm_ad_rgb",
               PYTHONPATH=os.pathsep.join(filter(None, [ROOT, os.environ.get("PYTHONPATH")])))
    result = subprocess.run([sys.executable, "-m", "mimarble", "compare", scene, "--spp", "1",
                             "--json", "--diff", str(diff)], capture_output=True, text=True,
                            env=env, timeout=300)
    sys.stderr.write(result.stderr)   # where the conftest check sees Dr.Jit's bounds reports
    assert result.returncode == 0, result.stderr
    metrics = json.loads(result.stdout.strip().splitlines()[-1])
    assert {"rmse", "psnr", "max_abs", "frac_over_1_255"} <= metrics.keys()
    assert metrics["psnr"] >= MIN_PSNR_DB
    picture = mimarble.mi.Bitmap(str(diff))
    assert (picture.width(), picture.height()) == (500, 500 + LEGEND_HEIGHT)   # legend under it
    assert "black <= 1e-6" in result.stdout and "legend" in result.stdout
