"""Rigid subsets, SCoRE / SARA / sphere centres and joint_centres on labelled and unlabelled trials."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tests.markers.rom_trial import rom_trial
from toolkit.errors import InputError
from toolkit.markers.centres import range_of_motion, sara, score, sphere_centre
from toolkit.markers.functional import JointCentresConfig, joint_centres
from toolkit.markers.rigid import check_segments, find_rigid_subsets, reference_shape, rigid_motions
from toolkit.markers.trajectories import MISSING, TRINOCULAR, MarkerTrajectories
from toolkit.observe import RecordingObserver
from toolkit.skeleton import JOINTS_14

J = {n: i for i, n in enumerate(JOINTS_14)}


def two_bodies(rng, n=240, noise=0.0, hinge=False, child_markers=4):
    """Parent and child marker clusters linked at a centre of rotation; returns (parent, child, centre, axis)."""
    c = np.array([0.1, 0.2, 1.0])
    pm = rng.normal(scale=0.06, size=(4, 3)) + [0, 0, 0.2]
    cm = rng.normal(scale=0.05, size=(child_markers, 3)) + [0, 0, -0.25]
    s = np.linspace(0, 6, n)
    rp = Rotation.from_rotvec(np.c_[0.2 * np.sin(s), 0.3 * np.cos(0.7 * s), 0.1 * s])
    tp = np.c_[0.1 * np.sin(s), 0.05 * s, 0.02 * np.cos(s)] + c
    if hinge:
        rel = Rotation.from_rotvec(np.c_[1.0 * np.sin(s), 0 * s, 0 * s])
    else:
        rel = Rotation.from_rotvec(np.c_[0.8 * np.sin(s), 0.6 * np.cos(1.5 * s), 0.3 * np.sin(2.5 * s)])
    parent = np.stack([rp[t].apply(pm) + tp[t] for t in range(n)])
    child = np.stack([(rp[t] * rel[t]).apply(cm) + tp[t] for t in range(n)])
    parent += rng.normal(scale=noise, size=parent.shape)
    child += rng.normal(scale=noise, size=child.shape)
    return parent, child, tp, rp.apply([1.0, 0.0, 0.0]), rp.apply([0.0, 1.0, 0.0])


def motions(pos):
    return rigid_motions(reference_shape(pos), pos)[:2]


def test_kabsch_recovers_a_rigid_motion_with_gaps():
    rng = np.random.default_rng(0)
    ref = rng.normal(scale=0.1, size=(5, 3))
    rot = Rotation.random(20, random_state=1)
    trans = rng.normal(size=(20, 3))
    pos = np.stack([rot[t].apply(ref) + trans[t] for t in range(20)])
    pos[3, :3] = np.nan  # only two markers seen: no motion
    pos[5, 1] = np.nan
    r, t, rms = rigid_motions(ref, pos)
    ok = np.ones(20, bool)
    ok[3] = False
    assert np.all(np.isnan(r[3])) and np.isnan(rms[3])
    np.testing.assert_allclose(r[ok], rot.as_matrix()[ok], atol=1e-9)
    np.testing.assert_allclose(t[ok], trans[ok], atol=1e-9)


def test_score_exact_without_noise_and_bounded_with_noise():
    rng = np.random.default_rng(1)
    parent, child, centre, _, _ = two_bodies(rng)
    parent[7, 0] = np.nan
    fit = score(*motions(parent), *motions(child))
    assert fit.method == "score"
    assert np.max(np.linalg.norm(fit.centre - centre, axis=1)) < 1e-9
    assert fit.residual_m < 1e-9 and fit.rom_deg[0] > 60
    for noise in (0.0005, 0.002):
        p, c, centre, _, _ = two_bodies(np.random.default_rng(2), noise=noise)
        fit = score(*motions(p), *motions(c))
        err = np.mean(np.linalg.norm(fit.centre - centre, axis=1))
        assert err < 4 * noise, (noise, err)
        assert fit.residual_m < 8 * noise


def test_sara_hinge_axis_and_centre_on_it():
    rng = np.random.default_rng(3)
    parent, child, centre, axis, across = two_bodies(rng, hinge=True)
    # the anchor is off the joint along the axis and across it: the centre is its projection onto the axis
    anchor = centre + 0.03 * axis + 0.02 * across
    fit = sara(*motions(parent), *motions(child), anchor=anchor)
    cos = np.abs(np.sum(fit.axis * axis, axis=1))
    assert np.min(cos) > 1 - 1e-9
    expected = centre + 0.03 * axis
    assert np.max(np.linalg.norm(fit.centre - expected, axis=1)) < 1e-6
    assert fit.conditioning < 1e-6  # a hinge: the centre along the axis is not determined by the motion
    rom = range_of_motion(*[motions(x)[0] for x in (parent, child)])
    assert rom[0] > 90 and rom[1] < 1
    p, c, centre, axis, _ = two_bodies(np.random.default_rng(4), hinge=True, noise=0.001)
    fit = sara(*motions(p), *motions(c), anchor=centre)
    ang = np.degrees(np.arccos(np.clip(np.abs(np.sum(fit.axis * axis, axis=1)), 0, 1)))
    assert np.mean(ang) < 2.0
    assert np.mean(np.linalg.norm(fit.centre - centre, axis=1)) < 0.004


def test_sphere_fit_of_two_child_markers():
    rng = np.random.default_rng(5)
    parent, child, centre, _, _ = two_bodies(rng, child_markers=2)
    fit = sphere_centre(*motions(parent), child)
    assert fit.method == "sphere"
    assert np.max(np.linalg.norm(fit.centre - centre, axis=1)) < 1e-7
    with pytest.raises(InputError):
        sphere_centre(*motions(parent), child[:2])


def test_score_needs_frames_with_both_segments():
    rng = np.random.default_rng(6)
    parent, child, _, _, _ = two_bodies(rng, n=10)
    child[2:] = np.nan
    with pytest.raises(InputError, match="at least three frames"):
        score(*motions(parent), *rigid_motions(reference_shape(child[:2]), child)[:2])


def test_rigid_subsets_without_labels_with_gaps():
    rng = np.random.default_rng(7)
    parent, child, _, _, _ = two_bodies(rng, noise=0.0005)
    pos = np.concatenate([child, parent], axis=1)
    pos[rng.random(pos.shape[:2]) < 0.1] = np.nan
    perm = rng.permutation(8)
    rs = find_rigid_subsets(pos[:, perm], threshold_m=0.01)
    found = sorted(sorted(perm[list(s)].tolist()) for s in rs.subsets)
    assert found == [[0, 1, 2, 3], [4, 5, 6, 7]] and rs.leftover == ()
    assert np.all(rs.spread < 0.002)
    flagged = check_segments(pos, {"one": [0, 1, 2, 3, 4]}, tolerance_m=0.01)
    assert flagged == {"one": [4]}


def test_joint_centres_exact_on_a_noise_free_rom_trial():
    traj, truth = rom_trial("cluster", n_frames=200)
    obs = RecordingObserver()
    res = joint_centres(traj, observer=obs)
    assert res.marker_set == "cluster" and abs(res.height_m - 1.75) < 0.01
    for name in ("l_hip", "r_hip", "l_shoulder", "r_shoulder"):
        assert res.method[J[name]] == "score"
    for name in ("l_knee", "r_knee", "l_elbow", "r_elbow"):
        assert res.method[J[name]] == "sara"
    err = np.linalg.norm(res.joints - truth, axis=-1)
    assert np.max(err) < 1e-4, dict(zip(JOINTS_14, err.max(axis=0)))
    assert np.all(res.rom_deg[[J["l_hip"], J["l_knee"], J["l_elbow"]]] > 30)
    assert any("l_hip: score" in d["text"] for d in obs.of_kind("text"))
    assert abs(res.lengths["l_hip-l_knee"] - np.linalg.norm(truth[0, J["l_hip"]] - truth[0, J["l_knee"]])) < 1e-4


def test_joint_centres_noise_and_gaps_bounded():
    traj, truth = rom_trial("cluster", n_frames=200, noise_m=0.001, missing=0.1, seed=3)
    res = joint_centres(traj)
    err = np.nanmean(np.linalg.norm(res.joints - truth, axis=-1), axis=0)
    for name in ("l_hip", "r_hip", "l_knee", "r_knee", "l_shoulder", "r_shoulder", "l_elbow", "r_elbow"):
        assert err[J[name]] < 0.008, (name, err[J[name]])


def test_static_trial_gives_the_scaled_generic_skeleton_and_says_so():
    traj, truth = rom_trial("plug-in-gait", n_frames=60, still=True, noise_m=0.0003, height=1.68)
    res = joint_centres(traj)
    assert set(res.method) <= {"template", "anatomical", "none"}
    assert any("functional centres need movement" in m for m in res.messages)
    assert abs(res.height_m - 1.68) < 0.03
    err = np.linalg.norm(res.joints - truth, axis=-1)
    assert np.nanmean(err) < 0.02


def test_unlabelled_markers_give_subsets_and_centres():
    traj, truth = rom_trial("cluster", n_frames=200, noise_m=0.0003, seed=1)
    keep = [i for i, s in enumerate(traj.segments) if s in ("pelvis", "l_thigh", "l_shank")]
    pos = traj.positions[:, keep]
    anon = MarkerTrajectories(tuple(f"M{i:03d}" for i in range(len(keep))), pos,
                              np.full(pos.shape[:2], TRINOCULAR, np.int8), 100.0, None, "anon")
    res = joint_centres(anon)
    assert not res.labelled and np.all(np.isnan(res.joints))
    segs = np.array(traj.segments)[keep]
    assert sorted(sorted(set(segs[list(s)])) for s in res.subsets.values()) == [["l_shank"], ["l_thigh"], ["pelvis"]]
    assert len(res.fits) == 2 and "no labels" in res.messages[0]
    hip, knee = truth[:, J["l_hip"]], truth[:, J["l_knee"]]

    def miss(fit, x):
        d = x - fit.centre
        if fit.axis is not None:  # a hinge found without labels: where on its axis is not observable
            d = d - np.sum(d * fit.axis, axis=1, keepdims=True) * fit.axis
        return np.mean(np.linalg.norm(d, axis=1))

    errs = sorted(min(miss(f, x) for x in (hip, knee)) for f in res.fits.values())
    assert errs[-1] < 0.01, errs
    assert {f.method for f in res.fits.values()} == {"score", "sara"}


def test_joint_centres_bad_input():
    pos = np.zeros((2, 3, 3))
    traj = MarkerTrajectories(("A", "B", "C"), pos, np.full((2, 3), TRINOCULAR, np.int8), 100.0)
    with pytest.raises(InputError, match="at least 3 frames"):
        joint_centres(traj)
    with pytest.raises(InputError):
        joint_centres(rom_trial("cluster", n_frames=20)[0], config=JointCentresConfig(marker_set="nope"))
    assert MISSING == 0


def test_config_checked():
    with pytest.raises(InputError, match="height_m"):
        JointCentresConfig(height_m=17.0)
    with pytest.raises(InputError, match="subset_threshold_m"):
        JointCentresConfig(subset_threshold_m=-0.01)
