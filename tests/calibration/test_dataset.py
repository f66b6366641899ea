"""Refining a dataset's cameras, and the cameras a run writes and later stages read back."""

from __future__ import annotations

import numpy as np
import pytest

from tests.synthetic.conftest import tiny_dataset  # noqa: F401 - session fixture
from toolkit.calibration import (
    USED_CALIBRATION,
    background_image,
    calibration_error_px,
    cameras_for_run,
    refine_dataset,
    refined_cameras,
    stage_rig,
)
from toolkit.errors import InputError
from toolkit.io import Dataset, read_calibration, write_calibration


def test_broadcast_datasets_carry_their_field_model(tiny_dataset):  # noqa: F811
    ds = Dataset.open(tiny_dataset)
    fm = ds.field_model()
    assert fm is not None and len(fm.polylines) == 5
    assert (tiny_dataset / "field_model.json").is_file()


def test_refine_dataset_reduces_the_calibration_error(tiny_dataset):  # noqa: F811
    ds = Dataset.open(tiny_dataset)
    rig, results = refine_dataset(ds)
    J = ds.gt_joints3d()
    for c in ds.camera_names:
        before = calibration_error_px(ds.rig[c], ds.gt_rig[c], J)
        after = calibration_error_px(rig[c], ds.gt_rig[c], J)
        if results[c].accepted:  # 320x180: a camera may see too little of the lines; then it is kept
            assert after < 0.5 * before
        else:
            assert rig[c] is ds.rig[c] and results[c].reason
    assert any(r.accepted for r in results.values())


def test_background_image_prefers_the_clean_plate_and_falls_back_to_the_median(tiny_dataset, tmp_path):  # noqa: F811
    ds = Dataset.open(tiny_dataset)
    c = ds.camera_names[0]
    assert np.array_equal(background_image(ds, c), ds.background(c))

    class NoPlate:
        def __init__(self, ds):
            self.ds = ds
            self.n_frames = ds.n_frames

        def background(self, camera):
            return None

        def frame(self, camera, i):
            return self.ds.frame(camera, i)

        def video_path(self, camera):
            return self.ds.video_path(camera)

    med = background_image(NoPlate(ds), c)
    assert med.shape == ds.background(c).shape and med.dtype == np.uint8
    # the subject covers few pixels: the median of the frames is close to the plate almost everywhere
    assert np.mean(np.abs(med.astype(int) - ds.background(c).astype(int)).max(2) < 30) > 0.95


def test_cameras_for_run_writes_and_reuses_the_calibration(tiny_dataset, tmp_path):  # noqa: F811
    ds = Dataset.open(tiny_dataset)
    lines = []
    rig = cameras_for_run(ds, tmp_path / "run", log=lines.append)
    path = tmp_path / "run" / USED_CALIBRATION
    assert path.is_file()
    back = read_calibration(path)
    assert all(np.allclose(a.cam_from_world, b.cam_from_world) and np.allclose(a.K, b.K) for a, b in zip(rig, back))
    assert any("refined" in s or "kept" in s for s in lines)
    # a resumed run reuses the file even when asked to keep the measured cameras
    again = cameras_for_run(ds, tmp_path / "run", refine=False, resumed=True, log=lines.append)
    assert all(np.allclose(a.cam_from_world, b.cam_from_world) for a, b in zip(rig, again))
    assert "reusing" in lines[-1]
    # a new run in the same folder does what it is asked: here, keep the measured cameras
    n = len(lines)
    fresh = cameras_for_run(ds, tmp_path / "run", refine=False, log=lines.append)
    assert not any("reusing" in s for s in lines[n:])
    assert all(np.allclose(a.cam_from_world, b.cam_from_world) for a, b in zip(fresh, ds.rig))
    assert all(np.allclose(a.cam_from_world, b.cam_from_world) for a, b in zip(read_calibration(path), ds.rig))
    kept = cameras_for_run(ds, tmp_path / "kept", refine=False, log=None)
    assert all(np.allclose(a.cam_from_world, b.cam_from_world) for a, b in zip(kept, ds.rig))
    assert stage_rig(ds, tmp_path / "nothing-here") is ds.rig
    assert stage_rig(ds, None) is ds.rig


def test_stage_rig_rejects_cameras_of_another_dataset(tiny_dataset, tmp_path):  # noqa: F811
    ds = Dataset.open(tiny_dataset)
    from toolkit.cameras import Rig
    write_calibration(tmp_path / USED_CALIBRATION, Rig((ds.rig[0].replace(name="zzz"),)))
    with pytest.raises(InputError, match="cameras"):
        stage_rig(ds, tmp_path)


def test_a_run_resumed_without_calibration_keeps_the_measured_cameras(tiny_dataset, tmp_path):  # noqa: F811
    ds = Dataset.open(tiny_dataset)
    lines = []
    rig = cameras_for_run(ds, tmp_path / "old", resumed=True, log=lines.append)
    assert all(np.allclose(a.cam_from_world, b.cam_from_world) for a, b in zip(rig, ds.rig))
    assert "measured calibration" in lines[0] and (tmp_path / "old" / USED_CALIBRATION).is_file()


def test_refined_cameras_read_back_from_the_run(tiny_dataset, tmp_path):  # noqa: F811
    ds = Dataset.open(tiny_dataset)
    _, results = refine_dataset(ds)
    cameras_for_run(ds, tmp_path / "run", log=None)
    assert refined_cameras(tmp_path / "run") == tuple(n for n, r in results.items() if r.accepted)
    cameras_for_run(ds, tmp_path / "kept", refine=False, log=None)
    assert refined_cameras(tmp_path / "kept") == ()
    assert refined_cameras(tmp_path / "nothing-here") == () and refined_cameras(None) == ()
    # stage 1 gives those cameras the tight offset prior
    from toolkit.multiview import REFINED_OFFSET_PRIOR_PX
    from toolkit.silhouettes import Stage1Config
    cfg = Stage1Config().with_refined_cameras(refined_cameras(tmp_path / "run"))
    for n in ds.camera_names:
        want = REFINED_OFFSET_PRIOR_PX if n in refined_cameras(tmp_path / "run") else Stage1Config().multiview.offset_prior_px
        assert cfg.multiview.offset_prior_of(n) == want


def test_refined_cameras_malformed_metadata(tmp_path):
    (tmp_path / USED_CALIBRATION).write_text("[metadata]\nrefined_on_field_lines = 3\n")
    with pytest.raises(InputError, match="refined_on_field_lines"):
        refined_cameras(tmp_path)
    (tmp_path / USED_CALIBRATION).write_text("[metadata\n")
    with pytest.raises(InputError, match="calibration.toml"):
        refined_cameras(tmp_path)
