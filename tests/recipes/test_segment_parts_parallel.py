"""Stage 2 as a run, frames as tasks (issue 20): two Dask workers give the outputs of one.

"The outputs" is :func:`toolkit.pipeline.run.compare_runs`: every part-label PNG byte for byte,
every frame's record.  The silhouettes (foreground extraction with a motion prior) are made in the
main process in frame order; a frame's segmentation is a task.
"""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

from toolkit.errors import InputError
from toolkit.observe import RecordingObserver
from toolkit.pipeline.run import compare_runs
from toolkit.pipeline.segment_parts import SegmentPartsConfig, run
from toolkit.synthetic import generate_scene, parse_spec

N_FRAMES = 3
SPEC = f"""
name = "seg_parallel"
seed = 5
frames = {N_FRAMES}
fps = 25
[subject]
height_m = 1.70
motion = "wave"
[cameras]
count = 2
layout = "studio"
resolution = [320, 180]
calibration_error_px = 3.0
[novel]
count = 0
"""


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("seg_parallel") / "ds"
    generate_scene(parse_spec(SPEC), out, progress=False).close()
    return out


def test_two_workers_give_the_outputs_of_one(dataset, tmp_path, capsys):
    main = importlib.import_module("recipes.segment_parts").main
    common = ["--gt-joints", "--gt-masks", "--quiet", "--no-recording"]
    assert main([str(dataset), "--out", str(tmp_path / "one"), *common]) == 0
    assert main([str(dataset), "--out", str(tmp_path / "two"), *common, "--workers", "2"]) == 0
    text = capsys.readouterr().out
    assert f"segmented {2 * N_FRAMES} views ({N_FRAMES} frames x 2 cameras)" in text
    assert compare_runs(tmp_path / "one", tmp_path / "two") == []
    assert len(list((tmp_path / "two" / "parts").rglob("*.png"))) == 2 * N_FRAMES
    mean_iou = float(text.split("IoU against groundtruth/parts: mean ")[-1].split(";")[0])
    assert mean_iou > 0.5  # labels worth comparing (0.885 on its first 2 frames: tests/recipes/test_segment_parts.py)


def test_streamed_silhouettes_and_reports_in_frame_order(dataset, tmp_path):
    """Foreground extraction (the sequential part) feeding two workers; reports come back in frame order."""
    config = SegmentPartsConfig(gt_joints=True, recording=False, progress=False)
    one = run(config, dataset=dataset, out=tmp_path / "one", log=None)
    obs = RecordingObserver()
    two = run(SegmentPartsConfig(gt_joints=True, recording=False, progress=False, workers=2), dataset=dataset,
              out=tmp_path / "two", observer=obs, log=None)
    assert one.complete and two.complete and two.processed == N_FRAMES
    assert compare_runs(tmp_path / "one", tmp_path / "two") == []
    frames = [d["frame"] for d in obs.of_kind("image")]
    assert frames == sorted(frames) and set(frames) == set(range(N_FRAMES)) and len(frames) == 2 * N_FRAMES
    assert one.metrics == two.metrics and one.metrics["views"] == 2 * N_FRAMES


def test_bad_worker_count_is_refused(dataset, tmp_path, capsys):
    main = importlib.import_module("recipes.segment_parts").main
    assert main([str(dataset), "--out", str(tmp_path / "o"), "--gt-joints", "--workers", "0", "--quiet"]) == 2
    assert "--workers" in capsys.readouterr().err
    with pytest.raises(InputError, match="--scheduler"):
        SegmentPartsConfig(scheduler="localhost")
