"""The players benchmark: matching estimated people to true ones (``people_mpjpe``), and the part mIoU told
apart where people touch (``people_miou``)."""

import numpy as np
import pytest

from benchmarks.bench_players import MATCH_RADIUS_M, people_mpjpe


def _people(rng, n_people, n_frames=3):
    base = rng.normal(size=(1, 1, 14, 3)) * 0.3
    offsets = np.stack([[k * 2.0, 0.0, 0.0] for k in range(n_people)])[:, None, None, :]
    return np.repeat(base, n_people, 0).repeat(n_frames, 1) + offsets


def test_people_are_matched_whatever_their_order():
    rng = np.random.default_rng(0)
    truth = _people(rng, 3)
    estimated = truth[[2, 0]] + np.array([0.0, 0.05, 0.0])  # two of three found, 5 cm off, reordered
    errors = people_mpjpe(truth, estimated)
    assert errors[0] == pytest.approx(5.0) and errors[2] == pytest.approx(5.0)
    assert np.isnan(errors[1])


def test_a_person_too_far_away_is_not_matched():
    rng = np.random.default_rng(1)
    truth = _people(rng, 1)
    far = truth + np.array([MATCH_RADIUS_M + 0.2, 0.0, 0.0])
    assert np.isnan(people_mpjpe(truth, far)[0])
    assert np.isnan(people_mpjpe(truth, np.full((1, 3, 14, 3), np.nan))[0])


def test_only_the_frames_both_hold_are_compared():
    rng = np.random.default_rng(2)
    truth = _people(rng, 1, n_frames=4)
    estimated = truth[:, :2].copy()
    estimated[:, 1, :, 0] += 0.1
    assert people_mpjpe(truth, estimated)[0] == pytest.approx(5.0)


class _Views:
    """Two people in two cameras: side by side touching in ``a``, far apart in ``b`` (one frame)."""

    camera_names = ["a", "b"]
    people_count = 2

    def gt_instances(self, cam, t):
        inst = np.zeros((60, 80), np.uint8)
        inst[10:50, 10:30] = 1
        if cam == "a":
            inst[10:50, 30:50] = 2
        else:
            inst[10:50, 55:75] = 2
        return inst

    def gt_parts(self, cam, t):
        return np.where(self.gt_instances(cam, t) > 0, 2, 0).astype(np.uint8)


def test_miou_is_told_apart_where_people_touch(tmp_path):
    from toolkit.io import atomic_write_png
    from toolkit.io.frames import frame_filename

    from benchmarks.bench_players import people_miou

    ds = _Views()
    for cam in ds.camera_names:
        labels = ds.gt_parts(cam, 0)
        if cam == "a":
            labels[10:50, 25:35] = 3  # a wrong part where the two meet
        atomic_write_png(tmp_path / "parts" / cam / frame_filename(0), labels)
    every, touching, alone = people_miou(ds, tmp_path, 1, split=True)
    assert alone == pytest.approx([1.0, 1.0])
    assert touching[0] < 1.0 and touching[1] < 1.0
    assert every == pytest.approx([(a + b) / 2 for a, b in zip(touching, alone)])
    assert people_miou(ds, tmp_path, 1) == every
