"""End-to-end test of recipes/optimize_joints.py on a tiny synthetic scene."""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import numpy as np
import pytest

from toolkit.anthropometry import AnthropometricConstraints
from toolkit.optimize.rules import joint_rule_reasons
from toolkit.synthetic import generate_scene, parse_spec

ROOT = Path(__file__).resolve().parents[2]
SPEC = """
seed = 5
frames = 1
fps = 25
[subject]
height_m = 1.75
motion = "walk"
[cameras]
count = 3
layout = "broadcast"
resolution = [320, 180]
calibration_error_px = 0.0
[novel]
count = 0
"""
#: The start is the ground truth displaced by this much (RMS 3D, cm).
NOISE_CM = 5.0
#: One sweep moves a joint by at most the grid reach (4.8 + 2.4 + 1.2 cm per axis around the
#: two best candidates), so the MPJPE cannot change by more than ~15 cm.
MAX_CHANGE_M = 0.15


def _recipe():
    return importlib.import_module("recipes.optimize_joints")


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("stage3") / "scene"
    generate_scene(parse_spec(SPEC, "stage3.toml"), out, progress=False).close()
    return out


def test_recipe_end_to_end(dataset, tmp_path, capsys):
    out = tmp_path / "out"
    rc = _recipe().main([str(dataset), "--out", str(out), "--noise-cm", str(NOISE_CM), "--sweeps", "1",
                         "--no-recording"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "part labels: ground truth" in text
    z = np.load(out / "joints3d.npz")
    assert z["joints"].shape == (1, 14, 3) and np.all(np.isfinite(z["joints"]))
    assert z["n_evaluations"][0] > 100  # joint-score evaluations: the grids of 14 joints
    m = json.loads((out / "metrics.json").read_text())
    assert 0.02 < m["mpjpe_before_m"] < 0.08
    assert abs(m["mpjpe_after_m"] - m["mpjpe_before_m"]) < MAX_CHANGE_M
    assert sum(m["joint_outcomes"].values()) == 14 and "joints " in text  # how the search ended per joint
    assert m["joint_outcomes"].get("moved", 0) == int(np.sum(np.any(z["joints"][0] != z["initial"][0], axis=1)))
    # every moved joint obeys the rules it takes part in
    cons = AnthropometricConstraints()
    J0, J1 = z["initial"][0], z["joints"][0]
    pose = J0.copy()
    for j in range(14):
        if not np.array_equal(J1[j], J0[j]):
            assert joint_rule_reasons(cons, pose, j, J1[j][None])[0][0]
        pose[j] = J1[j]


def test_recipe_reports_bad_input(dataset, tmp_path, capsys):
    rc = _recipe().main([str(dataset), "--out", str(tmp_path / "o"), "--poses", str(tmp_path / "missing")])
    assert rc == 2
    assert "poses3d.npz" in capsys.readouterr().err


def test_recipe_resumes_and_refuses_other_options(dataset, tmp_path, capsys):
    """A finished frame has a record and is skipped; another search config is another run (refused)."""
    out = tmp_path / "out"
    args = [str(dataset), "--out", str(out), "--noise-cm", str(NOISE_CM), "--sweeps", "1", "--no-recording"]
    assert _recipe().main(args) == 0
    first = np.load(out / "joints3d.npz")["joints"]
    assert (out / "frames" / "000000.json").is_file() and (out / "run.json").is_file()
    capsys.readouterr()
    assert _recipe().main(args) == 0  # resumed: nothing left to do, same results
    assert "0 frame(s)" in capsys.readouterr().out
    np.testing.assert_array_equal(np.load(out / "joints3d.npz")["joints"], first)
    assert _recipe().main(args[:-3] + ["--sweeps", "2", "--no-recording"]) == 2
    assert "optimize.max_sweeps" in capsys.readouterr().err
