"""Multi-view selection: combination search, offsets, left/right flips, missing data."""

from __future__ import annotations

import numpy as np
import pytest
from multiview_scenes import broadcast_rig, walking_poses

from toolkit.anthropometry import AnthropometricConstraints
from toolkit.errors import InputError
from toolkit.multiview import (
    MultiViewConfig,
    MultiViewTracker,
    fit_offsets,
    offsets_modulo_gauge,
    select_multiview,
    select_sequence,
    stack_selections,
)
from toolkit.observe import RecordingObserver
from toolkit.skeleton import SKELETON_14

FLIP = SKELETON_14.flip_permutation
#: Exact recovery: double precision through undistortion and a 3x3 solve.
EXACT_M = 1e-6
#: Offsets (modulo the gauge) from noise-free data: perspective makes the gauge only
#: approximately a uniform shift, measured below 0.05 px at broadcast distances.
OFFSET_EXACT_PX = 0.1
#: Offsets (modulo the gauge) with 0.5 px keypoint noise (measured p90 0.45 px with 4 views).
OFFSET_NOISY_PX = 0.75
#: Body shape error once the gauge translation is removed, with 0.5 px noise (measured < 15 mm).
SHAPE_NOISY_M = 0.03
#: MPJPE with 8 px injected offsets: the gauge translation (8 px ~ 0.1 m at 20 m) is not
#: observable, measured median 30-40 mm, p90 below 65 mm.
MPJPE_OFFSETS_M = 0.08


def project(rig, X):
    return rig.project(X)  # (n_views, 14, 2)


def mpjpe(a, b):
    return float(np.nanmean(np.linalg.norm(a - b, axis=-1)))


def shape_error(a, b):
    """MPJPE after removing the mean translation."""
    return mpjpe(a - np.nanmean(a, 0), b - np.nanmean(b, 0))


@pytest.mark.parametrize("n_views", [2, 3, 4])
@pytest.mark.parametrize("distortion", [False, True])
def test_exact_recovery_without_noise_or_offsets(rng, n_views, distortion):
    rig = broadcast_rig(n_views, rng, distortion=distortion)
    X = walking_poses(rng, 3)[1]
    sel = select_multiview(project(rig, X)[:, None], rig)
    assert sel.success
    np.testing.assert_allclose(sel.joints3d, X, atol=EXACT_M)
    np.testing.assert_allclose(sel.offsets, 0.0, atol=1e-3)
    assert sel.cost < EXACT_M
    assert np.all(sel.choice == 0) and not sel.flipped.any()
    assert sel.violations == ()


@pytest.mark.parametrize("n_views", [2, 3, 4])
@pytest.mark.parametrize("residual", ["reprojection", "ray"])
def test_injected_offsets_recovered_modulo_gauge(rng, n_views, residual):
    cfg = MultiViewConfig(residual=residual)
    for _ in range(3):
        rig = broadcast_rig(n_views, rng, distortion=True)
        X = walking_poses(rng, 3)[2]
        true = rng.uniform(-8, 8, (n_views, 2))
        obs = project(rig, X) - true[:, None]  # adding ``true`` gives back the exact projections
        sel = select_multiview(obs[:, None], rig, cfg)
        err = offsets_modulo_gauge(sel.offsets, true, rig, X.mean(0))
        assert np.abs(err).max() < OFFSET_EXACT_PX
        assert shape_error(sel.joints3d, X) < 0.01
        assert mpjpe(sel.joints3d, X) < MPJPE_OFFSETS_M
        no_offsets = select_multiview(obs[:, None], rig, MultiViewConfig(optimise_offsets=False))
        assert sel.cost < 0.5 * no_offsets.cost


def test_injected_offsets_with_noise(rng):
    for n_views in (2, 3, 4):
        rig = broadcast_rig(n_views, rng)
        X = walking_poses(rng, 3)[0]
        true = rng.uniform(-8, 8, (n_views, 2))
        obs = project(rig, X) - true[:, None] + rng.normal(0, 0.5, (n_views, 14, 2))
        sel = select_multiview(obs[:, None], rig)
        assert np.abs(offsets_modulo_gauge(sel.offsets, true, rig, X.mean(0))).max() < OFFSET_NOISY_PX
        assert shape_error(sel.joints3d, X) < SHAPE_NOISY_M
        assert mpjpe(sel.joints3d, X) < MPJPE_OFFSETS_M


def test_reference_view_gauge_and_bound(rng):
    rig = broadcast_rig(3, rng)
    X = walking_poses(rng, 2)[0]
    true = np.array([[30.0, -25.0], [5.0, 3.0], [-4.0, 6.0]])
    obs = project(rig, X) - true[:, None]
    sel = select_multiview(obs[:, None], rig, MultiViewConfig(reference_view=1))
    np.testing.assert_array_equal(sel.offsets[1], 0.0)
    bounded = select_multiview(obs[:, None], rig, MultiViewConfig(max_offset_px=16.0))
    assert np.abs(bounded.offsets).max() <= 16.0


def test_best_of_three_candidates_is_the_true_one(rng):
    for n_views in (2, 3):
        rig = broadcast_rig(n_views, rng)
        poses = walking_poses(rng, 20)
        X = poses[5]
        true = rng.uniform(-8, 8, (n_views, 2))
        cands = []
        for v in range(n_views):
            truth = project(rig, X)[v] - true[v] + rng.normal(0, 0.5, (14, 2))
            # another pose in each view (the same other pose in every view would be a
            # consistent 3D pose itself, as good as the truth)
            wrong = project(rig, poses[11 + 4 * v])[v] - true[v]
            flipped = truth[FLIP]
            order = rng.permutation(3)
            cands.append(np.stack([truth, wrong, flipped])[order])
            cands[-1] = (cands[-1], int(np.flatnonzero(order == 0)[0]))
        cand = np.stack([c for c, _ in cands])
        expected = np.array([i for _, i in cands])
        sel = select_multiview(cand, rig, MultiViewConfig(flips=()))
        np.testing.assert_array_equal(sel.choice, expected)
        assert len(sel.combination_costs) == 3 ** n_views
        assert sel.combination_costs[sel.best] == pytest.approx(np.min(sel.combination_costs), rel=1e-6)
        assert shape_error(sel.joints3d, X) < SHAPE_NOISY_M


def _flipped_views_case(rng, n_views, flipped_views):
    rig = broadcast_rig(n_views, rng, distortion=True)
    X = walking_poses(rng, 10)[int(rng.integers(10))]
    true = rng.uniform(-8, 8, (n_views, 2))
    obs = project(rig, X) - true[:, None] + rng.normal(0, 1.0, (n_views, 14, 2))
    for v in flipped_views:
        obs[v] = obs[v][FLIP]
    return rig, X, obs


@pytest.mark.parametrize("n_views,flipped", [(2, [1]), (3, [0]), (3, [1, 2]), (4, [2])])
def test_left_right_flips_resolved(rng, n_views, flipped):
    rig, X, obs = _flipped_views_case(rng, n_views, flipped)
    sel = select_multiview(obs[:, None], rig)
    assert shape_error(sel.joints3d, X) < SHAPE_NOISY_M
    # the anatomy (knees forward, elbows back) fixes the global labelling
    assert mpjpe(sel.joints3d, X) < MPJPE_OFFSETS_M
    expect = np.zeros(n_views, bool)
    expect[flipped] = True
    np.testing.assert_array_equal(sel.flipped, expect)
    without = select_multiview(obs[:, None], rig, MultiViewConfig(flips=()))
    assert shape_error(without.joints3d, X) > 3 * shape_error(sel.joints3d, X)


def test_swap_rate_with_and_without_flips(rng):
    """Each view flipped with probability 0.3 (3 views): the search removes every swap."""
    swaps = {"flips": 0, "none": 0}
    trials = 12
    for _ in range(trials):
        flipped = np.flatnonzero(rng.uniform(size=3) < 0.3)
        rig, X, obs = _flipped_views_case(rng, 3, flipped)
        for name, cfg in (("flips", MultiViewConfig()), ("none", MultiViewConfig(flips=()))):
            s = select_multiview(obs[:, None], rig, cfg)
            swaps[name] += mpjpe(s.joints3d, X) > MPJPE_OFFSETS_M
    assert swaps["flips"] == 0
    assert swaps["none"] > 0


def test_mirror_tie_broken_by_previous_pose(rng):
    rig, X, obs = _flipped_views_case(rng, 2, [1])
    cfg = MultiViewConfig(anatomy_tie_break=False)
    # the two mirror combinations tie exactly; the previous pose decides
    for prev in (X, X[FLIP]):
        sel = select_multiview(obs[:, None], rig, cfg, previous_joints3d=prev)
        assert mpjpe(sel.joints3d, prev) < MPJPE_OFFSETS_M
    costs = select_multiview(obs[:, None], rig, cfg).combination_costs
    assert np.sum(np.isclose(costs, costs.min(), rtol=1e-6)) == 2


def test_partial_flips(rng):
    rig, X, obs = _flipped_views_case(rng, 3, [])
    legs = [SKELETON_14.index(n) for n in ("l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle")]
    perm = np.arange(14)
    perm[legs] = FLIP[legs]
    obs[2] = obs[2][perm]
    sel = select_multiview(obs[:, None], rig, MultiViewConfig(flips=("legs", "arms", "all")))
    assert list(sel.flip) == ["", "", "legs"]
    assert shape_error(sel.joints3d, X) < SHAPE_NOISY_M


def test_missing_joints_and_empty_view(rng):
    rig = broadcast_rig(3, rng)
    X = walking_poses(rng, 2)[0]
    obs = project(rig, X)
    obs[0, 3] = np.nan                 # one view misses the left elbow: two rays remain
    obs[1, 4] = obs[2, 4] = np.nan     # the left wrist is seen by one view only
    sel = select_multiview(obs[:, None], rig)
    assert sel.success
    np.testing.assert_allclose(np.delete(sel.joints3d, 4, 0), np.delete(X, 4, 0), atol=EXACT_M)
    assert np.isnan(sel.joints3d[4]).all()
    assert np.isnan(sel.ray_distances[0, 3])
    assert any("non_finite" in v for v in sel.violations)

    obs = project(rig, X)
    obs[1] = np.nan                    # a view with nothing
    sel = select_multiview(obs[:, None], rig)
    assert sel.success and sel.choice[1] == -1 and not sel.views_used[1]
    np.testing.assert_array_equal(sel.offsets[1], 0.0)
    np.testing.assert_allclose(sel.joints3d, X, atol=EXACT_M)

    obs[0] = np.nan                    # only one view left: no estimate, no exception
    sel = select_multiview(obs[:, None], rig)
    assert not sel.success and not sel
    assert np.isnan(sel.joints3d).all() and sel.cost == np.inf
    all_nan = select_multiview(np.full((3, 2, 14, 2), np.nan), rig)
    assert not all_nan.success


def test_robust_mode_drops_a_disagreeing_view(rng):
    rig = broadcast_rig(4, rng)
    poses = walking_poses(rng, 20)
    X = poses[3]
    obs = project(rig, X) + rng.normal(0, 0.5, (4, 14, 2))
    obs[2] = project(rig, poses[13])[2] + 60.0   # another pose, far off
    plain = select_multiview(obs[:, None], rig, MultiViewConfig(flips=()))
    robust = select_multiview(obs[:, None], rig, MultiViewConfig(flips=(), robust=True))
    assert not robust.views_used[2] and robust.choice[2] == -1
    assert "dropped" in robust.message
    assert mpjpe(robust.joints3d, X) < 0.02
    assert mpjpe(plain.joints3d, X) > 2 * mpjpe(robust.joints3d, X)


def test_weights_zero_drops_joints(rng):
    rig = broadcast_rig(3, rng)
    X = walking_poses(rng, 2)[0]
    obs = project(rig, X)
    obs[0, 5] += 80.0
    w = np.ones((3, 1, 14))
    w[0, 0, 5] = 0.0
    sel = select_multiview(obs[:, None], rig, weights=w)
    np.testing.assert_allclose(sel.joints3d, X, atol=EXACT_M)
    assert np.isnan(sel.ray_distances[0, 5])


def test_anthropometric_report(rng):
    rig = broadcast_rig(3, rng)
    X = walking_poses(rng, 2)[0].copy()
    X[SKELETON_14.index("l_wrist")] += np.array([0.0, 0.0, -0.4])   # a forearm 40 cm too long
    obs = RecordingObserver()
    sel = select_multiview(project(rig, X)[:, None], rig, observer=obs)
    assert any("l_elbow" in v and "l_wrist" in v for v in sel.violations)
    texts = [r["text"] for r in obs.of_kind("text") if r["name"] == "multiview/anthropometry"]
    assert texts and "l_elbow" in texts[0]
    none = select_multiview(project(rig, X)[:, None], rig, MultiViewConfig(constraints=None))
    assert none.violations == ()


def test_observer_reports_every_intermediate(rng):
    rig = broadcast_rig(3, rng)
    X = walking_poses(rng, 2)[0]
    obs = RecordingObserver()
    cand = np.stack([project(rig, X), project(rig, X)[:, FLIP]], axis=1)
    sel = select_multiview(cand, rig, observer=obs, frame=7)
    assert {"joints2d", "lines2d", "rays", "points3d", "joints3d", "scalar", "text"} <= obs.kinds
    assert all(d.get("frame") == 7 for _, d in obs.reports)
    rays = obs.of_kind("rays")[0]
    assert rays["origins"].shape == (3 * 14, 3) and rays["ends"].shape == (3 * 14, 3)
    # rays end beyond their joint: the joint lies on the drawn segment
    names = {d["name"] for d in obs.of_kind("scalar")}
    assert {f"multiview/offset_px/{c}/x" for c in rig.names} <= names
    assert "multiview/cost_mm" in names and "multiview/ray_distance_mm/l_knee" in names
    cams = {d["camera"] for d in obs.of_kind("joints2d")}
    assert cams == set(rig.names)
    cand_names = {d["name"] for d in obs.of_kind("joints2d")}
    assert {"multiview/candidate_0", "multiview/candidate_1", "multiview/chosen"} <= cand_names
    table = [d["text"] for d in obs.of_kind("text") if d["name"] == "multiview/combinations"][0]
    assert f"{len(sel.combination_costs)} combinations" in table
    np.testing.assert_allclose(obs.of_kind("joints3d")[0]["joints"], sel.joints3d)


def test_sequence_carries_offsets(rng):
    rig = broadcast_rig(3, rng)
    poses = walking_poses(rng, 5)
    true = rng.uniform(-8, 8, (3, 2))
    cands = np.stack([project(rig, X) - true[:, None] for X in poses])[:, :, None]
    sels = select_sequence(cands, rig)
    assert len(sels) == 5 and all(s.success for s in sels)
    for s, X in zip(sels, poses):
        assert np.abs(offsets_modulo_gauge(s.offsets, true, rig, X.mean(0))).max() < OFFSET_EXACT_PX
    tracker = MultiViewTracker(rig)
    first = tracker.step(cands[0])
    np.testing.assert_allclose(tracker.offsets, first.offsets)
    # an empty frame keeps the tracker's state and gives an explicit "no estimate"
    empty = tracker.step(np.full_like(cands[0], np.nan))
    assert not empty.success
    np.testing.assert_allclose(tracker.offsets, first.offsets)
    arrays = stack_selections([first, empty, None], 3)
    assert arrays["joints"].shape == (3, 14, 3) and arrays["poses2d"].shape == (3, 3, 14, 2)
    assert list(arrays["success"]) == [True, False, False]
    assert np.isnan(arrays["joints"][1:]).all()


def test_fit_offsets_inputs(rng):
    rig = broadcast_rig(2, rng)
    X = walking_poses(rng, 2)[0]
    fit = fit_offsets(project(rig, X), rig)
    assert fit.success and fit.cost < EXACT_M and fit.active.all()
    with pytest.raises(InputError, match="points2d"):
        fit_offsets(np.zeros((3, 14, 2)), rig)
    with pytest.raises(InputError, match="weights"):
        fit_offsets(project(rig, X), rig, weights=np.ones((2, 13)))
    with pytest.raises(InputError, match="initial_offsets"):
        fit_offsets(project(rig, X), rig, initial_offsets=np.zeros(2))


@pytest.mark.parametrize("bad,match", [
    (np.zeros((2, 14, 2)), "candidates"),          # no candidate axis
    (np.zeros((3, 1, 14, 2)), "candidates"),       # three views for a two-camera rig
    (np.zeros((2, 1, 13, 2)), "candidates"),       # wrong joint count
    (np.zeros((2, 0, 14, 2)), "candidates"),       # no candidates
    (np.full((2, 1, 14, 2), np.inf), "candidates"),
])
def test_bad_candidates_raise(rng, bad, match):
    rig = broadcast_rig(2, rng)
    with pytest.raises(InputError, match=match):
        select_multiview(bad, rig)


def test_bad_arguments_raise(rng):
    rig = broadcast_rig(2, rng)
    good = np.zeros((2, 1, 14, 2))
    with pytest.raises(InputError, match="weights"):
        select_multiview(good, rig, weights=np.ones((2, 1, 13)))
    with pytest.raises(InputError, match="weights"):
        select_multiview(good, rig, weights=-np.ones((2, 1, 14)))
    with pytest.raises(InputError, match="initial_offsets"):
        select_multiview(good, rig, initial_offsets=np.zeros((3, 2)))
    with pytest.raises(InputError, match="previous_joints3d"):
        select_multiview(good, rig, previous_joints3d=np.zeros((13, 3)))
    with pytest.raises(InputError, match="rig"):
        from toolkit.cameras import Rig
        select_multiview(np.zeros((1, 1, 14, 2)), Rig((rig[0],)))
    with pytest.raises(InputError, match="max_combinations"):
        select_multiview(np.zeros((2, 3, 14, 2)), rig, MultiViewConfig(max_combinations=10))


@pytest.mark.parametrize("field,value", [
    ("flips", ("sideways",)), ("residual", "l1"), ("max_offset_px", 0.0), ("offset_prior_px", -1.0),
    ("refine_top", 0), ("refine_ratio", 0.5), ("reference_view", -1), ("up", (0.0, 0.0, 0.0)),
    ("tie_relative", np.nan),
])
def test_bad_config_raises(field, value):
    with pytest.raises(InputError, match=field):
        MultiViewConfig(**{field: value})


def test_implausible_skeleton_loses_to_a_plausible_one(rng):
    # view 1 offers the truth and a candidate whose rays meet view 0's just as well, but with the
    # left wrist slid 0.8 m along camera 0's ray: a forearm over a metre long
    rig = broadcast_rig(2, rng)
    X = walking_poses(rng, 10)[4]
    wrist = SKELETON_14.index("l_wrist")
    bad = X.copy()
    ray = bad[wrist] - rig[0].center
    bad[wrist] += 0.8 * ray / np.linalg.norm(ray)
    noise = lambda: rng.normal(0, 0.5, (14, 2))  # noqa: E731
    v0 = project(rig, X)[0] + noise()
    cand = np.full((2, 2, 14, 2), np.nan)
    cand[0, 0] = v0
    cand[1, 0] = project(rig, bad)[1] + noise()
    cand[1, 1] = project(rig, X)[1] + noise()
    base = MultiViewConfig(flips=(), optimise_offsets=False)
    from dataclasses import replace
    pure = select_multiview(cand, rig, replace(base, plausible_cost_ratio=1.0))
    assert AnthropometricConstraints().excess(pure.joints3d) > 0.25  # the ray cost alone takes the wrong one
    assert pure.choice[1] == 0
    sel = select_multiview(cand, rig, base)
    assert sel.choice[1] == 1 and mpjpe(sel.joints3d, X) < 0.02
    assert AnthropometricConstraints().excess(sel.joints3d) == pytest.approx(0.0, abs=0.05)


def test_per_camera_offset_prior(rng):
    """A camera given a tight prior (refined on field lines) keeps a small offset; the others absorb the error."""
    rig = broadcast_rig(3, rng)
    X = walking_poses(rng, 2)[0]
    true = np.array([[0.0, 0.0], [6.0, -5.0], [0.0, 0.0]])
    # camera 0's 2D joints are noisy and biased: a free offset would absorb the bias
    obs = project(rig, X) - true[:, None]
    obs[0] += np.array([2.5, -2.0]) + rng.normal(0, 0.3, (14, 2))
    loose = select_multiview(obs[:, None], rig)
    cfg = MultiViewConfig().with_offset_priors([rig[0].name], 0.5)
    assert cfg.offset_prior_of(rig[0].name) == 0.5 and cfg.offset_prior_of(rig[1].name) == MultiViewConfig().offset_prior_px
    tight = select_multiview(obs[:, None], rig, cfg)
    assert np.linalg.norm(tight.offsets[0]) < 0.5 * np.linalg.norm(loose.offsets[0])
    # adding another camera keeps the first one's prior
    both = cfg.with_offset_priors([rig[2].name])
    assert dict(both.camera_offset_prior_px) == {rig[0].name: 0.5, rig[2].name: 1.5}


@pytest.mark.parametrize("value", [(("cam00", 0.0),), (("cam00",),), "cam00"])
def test_bad_per_camera_offset_prior_raises(value):
    with pytest.raises(InputError, match="camera_offset_prior_px"):
        MultiViewConfig(camera_offset_prior_px=value)
