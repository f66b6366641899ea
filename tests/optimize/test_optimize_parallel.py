"""Stage 3 as a run, frames as tasks (issue 20): two Dask workers give the outputs of one.

"The outputs" is :func:`toolkit.pipeline.run.compare_runs`: ``joints3d.npz`` to 1e-9 m, every
frame's record and ``metrics.json`` less their wall times.  One worker runs in this process (no
Dask); two run the frames on a local cluster, each worker opening the dataset itself.
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.observe import RecordingObserver
from toolkit.optimize import OptimizeConfig
from toolkit.pipeline.optimize_joints import OptimizeJointsConfig, run
from toolkit.pipeline.run import compare_runs
from toolkit.synthetic import generate_scene, parse_spec

N_FRAMES = 3
SPEC = f"""
seed = 7
frames = {N_FRAMES}
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


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("stage3_parallel") / "scene"
    generate_scene(parse_spec(SPEC, "stage3_parallel.toml"), out, progress=False).close()
    return out


def test_two_workers_give_the_outputs_of_one(dataset, tmp_path, capsys):
    recipe = importlib.import_module("recipes.optimize_joints")
    common = ["--noise-cm", "5", "--sweeps", "1", "--no-recording"]
    assert recipe.main([str(dataset), "--out", str(tmp_path / "one"), *common]) == 0
    one_text = capsys.readouterr().out
    assert recipe.main([str(dataset), "--out", str(tmp_path / "two"), *common, "--workers", "2"]) == 0
    two_text = capsys.readouterr().out
    assert compare_runs(tmp_path / "one", tmp_path / "two") == []
    joints = np.load(tmp_path / "two" / "joints3d.npz")["joints"]
    assert joints.shape == (N_FRAMES, 14, 3) and np.all(np.isfinite(joints))
    # one line per frame, in frame order, whichever worker finished first
    for text in (one_text, two_text):
        frames = [int(line.split(":")[0].split()[1]) for line in text.splitlines() if line.startswith("frame ")]
        assert frames == list(range(N_FRAMES)) and "MPJPE" in text
    # the run identity leaves the workers out: the same run, resumed with another count, has nothing left to do
    assert recipe.main([str(dataset), "--out", str(tmp_path / "two"), *common]) == 0
    assert "0 frame(s)" in capsys.readouterr().out


def test_reports_come_back_in_frame_order(dataset, tmp_path):
    config = OptimizeJointsConfig(optimize=OptimizeConfig(max_sweeps=1), noise_cm=5.0, recording=False,
                                  max_frames=2, workers=2)
    obs = RecordingObserver()
    res = run(config, dataset=dataset, out=tmp_path / "o", observer=obs, log=None)
    assert res.complete and res.processed == 2
    frames = [d["frame"] for d in obs.of_kind("joints3d") if d.get("name") == "optimize/initial"]
    assert frames == [0, 1]
    record = json.loads((tmp_path / "o" / "frames" / "000001.json").read_text())
    assert record["n_sweeps"] == 1


def test_bad_worker_count_is_refused(dataset, tmp_path, capsys):
    recipe = importlib.import_module("recipes.optimize_joints")
    assert recipe.main([str(dataset), "--out", str(tmp_path / "o"), "--workers", "0"]) == 2
    assert "--workers" in capsys.readouterr().err
    with pytest.raises(InputError, match="--scheduler"):
        OptimizeJointsConfig(scheduler="localhost")
