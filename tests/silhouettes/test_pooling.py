"""Candidate pooling: the weighted mean of the database entries that agree with the chosen pose."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.silhouettes.pooling import ERROR_FLOOR, pool_pose
from toolkit.skeleton import SKELETON_14

FLIP = SKELETON_14.flip_permutation


def test_pools_agreeing_and_mirrored_entries_and_skips_the_rest():
    rng = np.random.default_rng(3)
    truth = rng.uniform(0, 100, (14, 2))
    a = truth + 1.0
    b = truth - 1.0
    far = truth + 40.0
    cands = np.stack([a, b[FLIP], far, np.full((14, 2), np.nan)])  # b is stored with its labels swapped
    errors = np.array([0.1, 0.1, 0.05, 0.0])
    pooled, n = pool_pose(a, cands, errors, radius_px=5.0)
    assert n == 2
    np.testing.assert_allclose(pooled, truth)  # equal weights: the mean of a and b
    # weights follow 1 / (E_S + floor)
    pooled, _ = pool_pose(a, cands, np.array([0.1, 0.3, 0.05, 0.0]), radius_px=5.0)
    wa, wb = 1 / (0.1 + ERROR_FLOOR), 1 / (0.3 + ERROR_FLOOR)
    np.testing.assert_allclose(pooled, (wa * a + wb * b) / (wa + wb))


def test_fewer_than_two_members_keeps_the_chosen_pose():
    p = np.arange(28, dtype=float).reshape(14, 2)
    pooled, n = pool_pose(p, np.stack([p + 50.0]), np.array([0.1]), radius_px=5.0)
    assert n == 0 and np.array_equal(pooled, p)
    with pytest.raises(InputError, match="pool_pose"):
        pool_pose(p, p, np.array([0.1]), radius_px=5.0)
