"""The constrained joint grid search (source 000 §3.2) on the planar scene."""

from __future__ import annotations

import numpy as np
import pytest

from tests.billboards.planar_scene import make_planar_scene
from toolkit.anthropometry import AnthropometricConstraints
from toolkit.billboards import PositionScorer
from toolkit.errors import InputError
from toolkit.observe import RecordingObserver
from toolkit.optimize import GRID_MIN_STEP_M, OptimizeConfig, optimize_joint, optimize_pose
from toolkit.skeleton import SKELETON_14

WRIST = SKELETON_14.index("l_wrist")
#: Recovery tolerance across the bone: one final grid step (the plank fixes the plane, not the
#: position along the bone, which the displacement leaves alone).
RECOVERY_TOL = GRID_MIN_STEP_M


@pytest.fixture(scope="module")
def scene():
    return make_planar_scene()


@pytest.fixture(scope="module")
def scorer(scene):
    return PositionScorer(scene.images, scene.labels, scene.rig)


def test_grid_search_recovers_displaced_joint(scene, scorer):
    J = scene.joints.copy()
    J[WRIST] += [0.03, -0.035, 0.0]
    obs = RecordingObserver()
    st = optimize_joint(scorer, J, WRIST, observer=obs, frame=0)
    assert st.status == "moved" and st.score > st.start_score
    assert np.linalg.norm((st.position - scene.joints[WRIST])[:2]) <= RECOVERY_TOL
    assert st.n_evaluations > 27
    cand = obs.of_kind("points3d")[0]
    assert cand["name"] == "optimize/candidates/l_wrist" and cand["colors"].shape == (len(cand["points"]), 3)


def test_pose_sweeps_converge_and_respect_constraints(scene, scorer):
    J = scene.joints.copy()
    J[WRIST] += [-0.01, 0.03, 0.0]
    cons = AnthropometricConstraints()
    obs = RecordingObserver()
    # the elbow is left out: moving it within the plank's plane is barely observable here
    order = [WRIST, SKELETON_14.index("r_knee")]
    res = optimize_pose(scorer, J, cons, OptimizeConfig(max_sweeps=3), joint_order=order, observer=obs, frame=0)
    assert cons.is_valid(res.joints)
    pose = J.copy()
    for st in res.steps:  # no accepted position breaks a constraint
        if st.status == "moved":
            assert cons.valid_positions(pose, st.joint, st.position[None])[0][0]
        pose[st.joint] = st.position
    assert np.array_equal(pose, res.joints)
    assert np.linalg.norm((res.joints[WRIST] - scene.joints[WRIST])[:2]) <= RECOVERY_TOL
    assert res.scores.shape == (res.n_sweeps + 1, 14)
    assert res.scores[-1, WRIST] > res.scores[0, WRIST]
    assert res.converged and res.n_sweeps <= 3
    # joints whose bones no camera sees are kept and say why
    knee = [st for st in res.steps if st.joint == SKELETON_14.index("r_knee")][0]
    assert knee.status == "unscorable" and "no camera pair" in knee.reason
    assert np.array_equal(res.joints[SKELETON_14.index("r_knee")], J[SKELETON_14.index("r_knee")])
    assert any(d["name"] == "optimize/score/l_wrist" for d in obs.of_kind("series"))
    assert obs.of_kind("joints3d")
    # the per-joint summary: the wrist moved, the knee could not be scored, the rest was not searched
    out = res.outcomes()
    assert out[WRIST] == "moved" and out[SKELETON_14.index("r_knee")] == "unscorable"
    assert res.outcome_counts() == {"moved": 1, "unscorable": 1, "not searched": 12}


def test_rejected_candidates_score_zero(scene, scorer):
    """A joint that no grid node can move into the allowed range keeps its position."""
    J = scene.joints.copy()
    J[WRIST] = J[SKELETON_14.index("l_elbow")] + [0.0, 0.0, -0.6]  # forearm far too long
    obs = RecordingObserver()
    st = optimize_joint(scorer, J, WRIST, observer=obs)
    assert st.status == "all_invalid" and np.array_equal(st.position, J[WRIST])
    assert "every candidate breaks a constraint" in st.reason
    assert any("bone_length" in d["text"] for d in obs.of_kind("text"))


def test_bad_input(scene, scorer):
    with pytest.raises(InputError, match="joints"):
        optimize_pose(scorer, np.full((14, 3), np.nan))
    with pytest.raises(InputError, match="joint"):
        optimize_joint(scorer, scene.joints, 20)
    with pytest.raises(InputError):
        OptimizeConfig(min_step_m=0.1, initial_step_m=0.05)


def test_joints_scored_in_too_few_views_keep_their_start(scene):
    class OneViewScorer(PositionScorer):
        """Each source camera sees only its own billboard; only the last (virtual) view sees both."""

        def visibility(self, joints, part):
            vis = super().visibility(joints, part)
            vis[:-1] = False
            vis[:len(self.rig), :] = np.eye(len(self.rig), dtype=bool)[:, :vis.shape[1]]
            return vis

    two = make_planar_scene(2, elevations_deg=(-20.0, 15.0))
    J = two.joints.copy()
    J[WRIST] += [0.03, -0.035, 0.0]
    obs = RecordingObserver()
    weak = OneViewScorer(two.images, two.labels, two.rig)
    st = optimize_joint(weak, J, WRIST, observer=obs, frame=0)
    assert st.status == "few_views" and np.array_equal(st.position, J[WRIST])
    assert "1 view" in st.reason and any("fewer than 2" in d["text"] for d in obs.of_kind("text"))
    # min_views = 1 searches anyway; the full scorer (both cameras see both billboards) searches by default
    # (one camera pair: a move needs min_pairs = 1, see test_optimize_decisive.py)
    one_pair = OptimizeConfig(min_pairs=1)
    assert optimize_joint(weak, J, WRIST, config=OptimizeConfig(min_views=1, min_pairs=1)).status == "moved"
    assert optimize_joint(PositionScorer(two.images, two.labels, two.rig), J, WRIST, config=one_pair).status == "moved"
    with pytest.raises(InputError, match="min_views"):
        OptimizeConfig(min_views=0)


def test_prior_pulls_towards_the_start(scene, scorer):
    J = scene.joints.copy()
    J[WRIST] += [0.03, -0.035, 0.0]
    # a weak prior (the default) still lets the search bring the displaced joint most of the way back
    # (measured 4.6 -> 1.8 cm; without the prior to within one grid step)
    before = np.linalg.norm((J[WRIST] - scene.joints[WRIST])[:2])
    st = optimize_joint(scorer, J, WRIST, config=OptimizeConfig(), anchor=J[WRIST].copy())
    assert st.status == "moved" and np.linalg.norm((st.position - scene.joints[WRIST])[:2]) <= 0.5 * before
    # a very strong one keeps it where it started
    st = optimize_joint(scorer, J, WRIST, config=OptimizeConfig(prior_weight=100.0), anchor=J[WRIST].copy())
    assert st.status == "kept" and np.array_equal(st.position, J[WRIST])
    # no anchor (a single joint step outside optimize_pose): no prior
    st = optimize_joint(scorer, J, WRIST, config=OptimizeConfig(prior_weight=100.0))
    assert st.status == "moved"
    with pytest.raises(InputError, match="prior"):
        OptimizeConfig(prior_weight=-1.0)
