"""MPJPE, written once (toolkit.skeleton.metrics): values, missing joints, the aligned variant, bad shapes."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.skeleton import joint_errors, mpjpe, pose_errors


def test_mpjpe_is_the_mean_joint_distance_over_known_joints():
    rng = np.random.default_rng(0)
    truth = rng.normal(size=(5, 14, 3))
    est = truth.copy()
    est[..., 0] += 0.03  # every joint 3 cm off along x
    assert mpjpe(est, truth) == pytest.approx(0.03, abs=1e-12)
    est[2, 4] = np.nan  # a missing joint is left out, not counted as zero
    est[3] = np.nan
    assert mpjpe(est, truth) == pytest.approx(0.03, abs=1e-12)
    assert np.isnan(joint_errors(est, truth)[3]).all()
    assert np.isnan(mpjpe(np.full((14, 3), np.nan), truth[0]))
    assert pose_errors(est, truth) == {"mpjpe_m": pytest.approx(0.03, abs=1e-12), "frames": 3}


def test_aligned_removes_each_poses_translation_only():
    rng = np.random.default_rng(1)
    truth = rng.normal(size=(3, 14, 3))
    shift = np.array([[0.1, -0.2, 0.05], [0.0, 0.3, 0.0], [-0.4, 0.0, 0.2]])[:, None, :]
    noise = rng.normal(scale=0.01, size=truth.shape)
    est = truth + shift + noise
    assert mpjpe(est, truth) > 0.1
    # aligned: the error of the noise less its own mean
    expected = np.linalg.norm(noise - noise.mean(axis=1, keepdims=True), axis=-1).mean()
    assert mpjpe(est, truth, aligned=True) == pytest.approx(expected, rel=1e-12)
    # one pose (J, 3) as the benchmarks pass it, with a missing joint: the shift of the known ones
    one = est[0].copy()
    one[5] = np.nan
    d = (one - truth[0])[np.arange(14) != 5]
    assert mpjpe(one, truth[0], aligned=True) == pytest.approx(
        np.linalg.norm(d - d.mean(axis=0), axis=-1).mean(), rel=1e-12)


def test_bad_shapes_are_input_errors():
    with pytest.raises(InputError, match="shape"):
        mpjpe(np.zeros((14, 3)), np.zeros((13, 3)))
    with pytest.raises(InputError, match="pose_errors"):
        pose_errors(np.zeros((2, 14, 2)), np.zeros((2, 14, 2)))
