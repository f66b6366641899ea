"""The players benchmark's matching of estimated people to true ones (``people_mpjpe``)."""

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
