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
