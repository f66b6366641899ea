"""The soft-body run with the stereo heads' silhouettes (issue 18 item 4): masks and cameras reach the fit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from benchmarks.bench_softbody import TRINOCULAR_SPEC
from toolkit.observe import RecordingObserver
from toolkit.pipeline.soft_body import SoftBodyRunConfig, run, wants_silhouettes
from toolkit.pipeline.soft_body_sources import StereoClouds
from toolkit.softbody import GlobalFitConfig, TrackConfig
from toolkit.synthetic.generator import build_scene, generate_scene
from toolkit.synthetic.spec import parse_spec

# the benchmark's trinocular scene (two heads, checked clothes), 2 frames of a wave
SPEC = TRINOCULAR_SPEC.format(seed=3, frames=2, height=1.72, motion="wave")


@pytest.fixture(scope="module")
def stereo_dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("sb_sil")
    spec = parse_spec(SPEC, "test_soft_body_silhouette")
    generate_scene(spec, root, progress=False)
    scene = build_scene(spec)
    np.savez(root / "init_joints.npz", joints=scene.joints)
    return root, scene


def test_silhouettes_are_the_masks_the_clouds_used(stereo_dataset):
    root, _ = stereo_dataset
    src = StereoClouds(root, foreground="groundtruth", keep_masks=True)
    src.cloud(0)
    kept = src.silhouettes(0)
    again = src.silhouettes(0)  # not kept any more: found again by the same foreground step
    assert [c.name for c, _ in kept] == [h[0].name for h in src.heads] == [c.name for c, _ in again]
    for (cam, m), (_, m2) in zip(kept, again):
        assert m.shape == (cam.height, cam.width) and m.any() and np.array_equal(m, m2)


@pytest.mark.slow
def test_run_fits_with_silhouettes_and_records_them(stereo_dataset, tmp_path):
    root, scene = stereo_dataset
    cfg = SoftBodyRunConfig(foreground="groundtruth", init_joints=root / "init_joints.npz", recording=False,
                            progress=False)
    assert wants_silhouettes(cfg) and not wants_silhouettes(replace(cfg, independent=True))  # on by default
    assert not wants_silhouettes(replace(cfg, track=TrackConfig(silhouette_weight=0.0),
                                         fit=GlobalFitConfig(silhouette_weight=0.0)))
    assert wants_silhouettes(replace(cfg, track=TrackConfig(silhouette_weight=0.0)))  # the global fit's
    obs = RecordingObserver()
    res = run(cfg, dataset=root, out=tmp_path / "fit", observer=obs, log=None)
    assert res.metrics["states"] == {"ok": 2}
    reps = obs.of_kind("silhouette")
    assert sorted((d["frame"], d["camera"]) for d in reps) == [(t, c) for t in range(2) for c in ("cam00", "cam03")]
    r = np.concatenate([d["residuals"] for d in reps])
    assert np.median(np.abs(r)) < 0.02  # the outlines graze the fitted model
    assert res.metrics["global_fit"]["mpjpe_mm"] < 60


#: The built-in detector's joints triangulated across the two heads (320 x 240 renders, the person about
#: 150 px tall), the model posed on them: 42 mm from the truth here (a clicked start with 3 px of noise:
#: about 46 mm, docs/softbody.md); a joint whose keypoint is 10-20 px off lands 100-200 mm away.
DETECTOR_START_MM = 60.0


def test_start_without_clicks_from_the_detector(stereo_dataset):
    """No clicks, no joints file: the model starts from the detector's keypoints on each head's reference
    camera, triangulated across the heads (clicks stay available: ``init = "clicks"``)."""
    pytest.importorskip("mediapipe")
    from toolkit.pipeline.soft_body import build_clouds, initial_model
    from toolkit.pipeline.soft_body_sources import open_source

    root, scene = stereo_dataset
    cfg = SoftBodyRunConfig(foreground="groundtruth", recording=False, progress=False)
    assert cfg.init == "auto" and cfg.init_joints is None and cfg.clicks is None
    src = open_source(root, "auto", foreground="groundtruth")
    clouds, _, _ = build_clouds(src, 1, cfg.patches)
    model, params, joints = initial_model(cfg, src, 1, clouds[0])
    err = 1000 * np.linalg.norm(model.joints(params) - scene.joints[0], axis=1)
    assert np.isfinite(joints).all()
    assert err.mean() < DETECTOR_START_MM, np.round(err)
