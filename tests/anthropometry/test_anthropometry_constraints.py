"""Tests of the anthropometric constraint checker (toolkit.anthropometry.constraints)."""

import time

import numpy as np
import pytest

from toolkit.anthropometry import (
    LIMITS_14,
    AnthropometricConstraints,
    BodyProportions,
    reason_names,
)
from toolkit.anthropometry import constraints as C
from toolkit.errors import InputError
from toolkit.observe import RecordingObserver
from toolkit.skeleton import SKELETON_14

J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}
HEIGHTS = np.linspace(1.52, 1.87, 15)   # the generator's stature range (STATURE_RANGE_M)
SEEDS = range(40)


@pytest.fixture(scope="module")
def checker():
    return AnthropometricConstraints()


@pytest.fixture
def pose():
    """Median person of 1.75 m standing at the origin."""
    return BodyProportions.from_height(1.75).rest_pose()


def kinds(violations):
    return {v.kind for v in violations}


# ------------------------------------------------------------ generated people
def test_every_bone_of_generated_people_is_within_limits(checker):
    poses = np.array([BodyProportions.sample(h, np.random.default_rng(s)).rest_pose()
                      for h in HEIGHTS for s in SEEDS])
    by_pair = {frozenset((lim.joint_a, lim.joint_b)): lim for lim in LIMITS_14}
    lengths = SKELETON_14.bone_lengths(poses)
    for k, (a, b) in enumerate(SKELETON_14.bones):
        lim = by_pair[frozenset((SKELETON_14.joint_names[a], SKELETON_14.joint_names[b]))]
        assert lengths[:, k].min() >= lim.min_m, SKELETON_14.bone_names[k]
        assert lengths[:, k].max() <= lim.max_m, SKELETON_14.bone_names[k]
    codes = checker.first_violation_kind(poses)
    assert np.all(codes == C.OK), reason_names(codes[codes != C.OK])
    assert checker.valid_mask(poses).all()


@pytest.mark.parametrize("h", [1.52, 1.87])
def test_extreme_statures_are_valid_one_by_one(checker, h):
    for s in range(5):
        p = BodyProportions.sample(h, s).rest_pose()
        assert checker.violations(p) == []
        assert checker.is_valid(p)


# ------------------------------------------------------------ each rule
def test_too_long_arm(checker, pose):
    p = pose.copy()
    p[[J["l_elbow"], J["l_wrist"]], 2] -= 0.15          # upper arm 0.33 -> 0.48 m
    v = checker.violations(p)
    bone = [x for x in v if x.kind == "bone_length"]
    assert [x.what.split(" ")[0] for x in bone] == ["l_shoulder-l_elbow"]
    assert bone[0].value == pytest.approx(0.191 * 1.75 + 0.15)
    assert bone[0].value > bone[0].hi
    # the arms now differ by more than 10 % and the straight arm is too long
    assert kinds(v) == {"bone_length", "asymmetric", "joint_distance"}
    assert checker.first_violation_kind(p[None])[0] == C.BONE_LENGTH
    assert not checker.is_valid(p)


def _lengthen_left_shank(pose, factor):
    """Left shank ``factor`` x the right one, ankle height kept (the knee bends forward)."""
    p = pose.copy()
    knee, ankle = p[J["l_knee"]], p[J["l_ankle"]]
    length = factor * np.linalg.norm(knee - ankle)
    drop = knee[2] - ankle[2]
    p[J["l_ankle"]] = ankle + [0.0, np.sqrt(length ** 2 - drop ** 2), 0.0]
    return p


def test_asymmetric_legs(checker, pose):
    p = _lengthen_left_shank(pose, 1.12)
    v = checker.violations(p)
    assert kinds(v) == {"asymmetric"}
    assert len(v) == 1 and "l_knee-l_ankle" in v[0].what and "r_knee-r_ankle" in v[0].what
    assert v[0].value == pytest.approx(0.12)
    assert checker.first_violation_kind(p[None])[0] == C.ASYMMETRIC
    assert checker.is_valid(_lengthen_left_shank(pose, 1.09))
    assert AnthropometricConstraints(check_symmetry=False).is_valid(p)


def test_below_ground(checker, pose):
    lowest_ankle = C.GROUND_CLEARANCE_14[0][1] - C.GROUND_MARGIN_M
    p = pose.copy()
    p[:, 2] -= pose[J["l_ankle"], 2] - lowest_ankle + 0.001  # ankles 1 mm too low
    v = checker.violations(p)
    assert kinds(v) == {"below_ground"}
    assert sorted(x.what for x in v) == ["l_ankle", "r_ankle"]
    assert v[0].lo == pytest.approx(lowest_ankle)
    p[:, 2] += 0.002                                         # 1 mm above the lowest height
    assert checker.is_valid(p)
    # other joints only need to be above the ground less the margin (2 cm)
    knee_z = pose[J["l_knee"], 2]
    near = AnthropometricConstraints(ground_z=knee_z + 0.01)
    assert sorted(x.what for x in near.violations(pose)) == ["l_ankle", "r_ankle"]
    raised = AnthropometricConstraints(ground_z=knee_z + 0.03)
    expected = ["l_ankle", "l_knee", "r_ankle", "r_knee"]
    assert sorted(x.what for x in raised.violations(pose)) == expected
    assert AnthropometricConstraints(ground_z=knee_z + 0.03, check_ground=False).is_valid(pose)


def test_head_too_far_from_hips(checker, pose):
    p = pose.copy()
    upper = [J[n] for n in ("head", "neck", "l_shoulder", "l_elbow", "l_wrist",
                            "r_shoulder", "r_elbow", "r_wrist")]
    p[upper, 2] += 0.10                                      # longer torso, still within its limit
    p[J["head"], 2] = p[J["neck"], 2] + 0.20                 # long neck, still within its limit
    v = checker.violations(p)
    assert kinds(v) == {"joint_distance"}
    assert sorted(x.what.split(" ")[0] for x in v) == ["head-l_hip", "head-r_hip"]
    assert all(x.value > x.hi for x in v)
    assert checker.first_violation_kind(p[None])[0] == C.JOINT_DISTANCE
    assert AnthropometricConstraints(check_distances=False).is_valid(p)


def test_nan_joint(checker, pose):
    p = pose.copy()
    p[J["l_wrist"], 1] = np.nan
    v = checker.violations(p)
    assert [(x.kind, x.what) for x in v] == [("non_finite", "l_wrist")]
    assert checker.first_violation_kind(p[None])[0] == C.NON_FINITE
    assert not checker.is_valid(p)
    p[J["l_elbow"], 2] -= 0.2                     # rules not touching the wrist still apply
    assert kinds(checker.violations(p)) == {"non_finite", "bone_length", "asymmetric"}


def test_violation_text_is_readable(checker, pose):
    p = pose.copy()
    p[[J["l_elbow"], J["l_wrist"]], 2] -= 0.15
    text = [str(x) for x in checker.violations(p)]
    assert text[0] == ("bone_length: l_shoulder-l_elbow (upper arm) = 0.484 m, "
                       "allowed [0.25, 0.41] m")
    assert any(t.startswith("asymmetric: neck-l_shoulder") or "differ by" in t for t in text)
    obs = RecordingObserver()
    checker.violations(p, observer=obs)
    assert obs.of_kind("text")[0]["text"].splitlines() == text


def test_bone_checks_can_be_switched_off(pose):
    p = pose.copy()
    p[[J["l_elbow"], J["l_wrist"]], 2] -= 0.15
    v = AnthropometricConstraints(check_bones=False).violations(p)
    assert kinds(v) == {"asymmetric", "joint_distance"}


# ------------------------------------------------------- vectorised checks
def _random_bases(rng):
    bases = [BodyProportions.sample(h, rng).rest_pose() for h in (1.55, 1.7, 1.85)]
    broken = bases[1].copy()
    broken[J["r_knee"], 2] -= 0.2                            # invalid away from most joints
    nan = bases[2].copy()
    nan[J["r_wrist"]] = np.nan
    return bases + [broken, nan]


def test_valid_positions_agrees_with_valid_mask(checker):
    rng = np.random.default_rng(11)
    seen = set()
    for base in _random_bases(rng):
        for j in range(SKELETON_14.n_joints):
            centre = np.nan_to_num(base[j], nan=1.0)
            pos = centre + rng.normal(0.0, 0.12, (400, 3))
            pos[:5, rng.integers(0, 3)] = np.nan
            pos[5:10, 2] = -0.5
            valid, reasons = checker.valid_positions(base, j, pos)
            cand = np.repeat(base[None], len(pos), axis=0)
            cand[:, j] = pos
            expected = checker.first_violation_kind(cand)
            np.testing.assert_array_equal(reasons, expected)
            np.testing.assert_array_equal(valid, checker.valid_mask(cand))
            seen |= set(expected.tolist())
    assert seen == set(range(len(C.REASONS)))               # every reason was exercised


def test_valid_positions_by_name(checker, pose):
    pos = pose[J["l_elbow"]] + np.array([[0, 0, 0], [0, 0, -0.3]])
    valid, reasons = checker.valid_positions(pose, "l_elbow", pos)
    assert valid.tolist() == [True, False]
    assert reason_names(reasons).tolist() == ["ok", "bone_length"]


def test_speed_of_valid_positions(checker, pose):
    rng = np.random.default_rng(0)
    pos = pose[J["l_elbow"]] + rng.normal(0, 0.1, (1000, 3))
    cand = np.repeat(pose[None], 1000, axis=0)
    cand[:, J["l_elbow"]] = pos

    def best_of(f, repeats=30):
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            f()
            times.append(time.perf_counter() - t0)
        return min(times)

    t_pos = best_of(lambda: checker.valid_positions(pose, J["l_elbow"], pos))
    t_mask = best_of(lambda: checker.valid_mask(cand))
    print(f"\nvalid_positions N=1000: {1e3 * t_pos:.3f} ms; "
          f"valid_mask N=1000: {1e3 * t_mask:.3f} ms")
    assert t_pos < 0.05                                      # loose: about 0.1 ms expected


# ------------------------------------------------------------ bad input
def test_bad_input(checker, pose):
    with pytest.raises(InputError, match="candidates"):
        checker.valid_mask(pose)
    with pytest.raises(InputError, match="joints"):
        checker.violations(pose[:13])
    with pytest.raises(InputError, match="positions"):
        checker.valid_positions(pose, 3, np.zeros((4, 2)))
    with pytest.raises(InputError, match="joint_index"):
        checker.valid_positions(pose, 14, np.zeros((4, 3)))
    with pytest.raises(InputError, match="joint_index"):
        checker.valid_positions(pose, "nose", np.zeros((4, 3)))
    with pytest.raises(InputError, match="symmetric_tolerance"):
        AnthropometricConstraints(symmetric_tolerance=-0.1)
    bad = (LIMITS_14[0].__class__("x", "neck", "nose", 0.1, 0.2, ""),)
    with pytest.raises(InputError, match="limits"):
        AnthropometricConstraints(limits=bad)
    with pytest.raises(InputError, match="codes"):
        reason_names([7])


def test_joint_rules_only_ignores_rules_of_other_joints():
    """A pose breaking an unrelated rule blocks every candidate unless only the joint's rules are checked."""
    import numpy as np

    from toolkit.anthropometry import AnthropometricConstraints, BodyProportions
    from toolkit.skeleton import SKELETON_14
    cons = AnthropometricConstraints()
    pose = BodyProportions.from_height(1.75).rest_pose()
    wr = SKELETON_14.index("l_wrist")
    el = SKELETON_14.index("l_elbow")
    pose[wr] = pose[el] + (pose[wr] - pose[el]) * 1.2   # left forearm 20 % longer: asymmetric
    head = SKELETON_14.index("head")
    cand = pose[head] + np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.0, 0.5]])
    ok_all, _ = cons.valid_positions(pose, head, cand)
    ok_joint, reasons = cons.valid_positions(pose, head, cand, joint_rules_only=True)
    assert not ok_all.any()
    assert ok_joint.tolist() == [True, True, False]   # 0.5 m up breaks the neck-head bone
    assert reasons[2] != 0


def test_excess_measures_how_far_outside_the_rules(checker, pose):
    assert checker.excess(pose) == 0.0
    a, b = pose.copy(), pose.copy()
    a[[J["l_elbow"], J["l_wrist"]], 2] -= 0.15
    b[[J["l_elbow"], J["l_wrist"]], 2] -= 0.40
    ea, eb = checker.excess(a), checker.excess(b)
    bone = [x for x in checker.violations(a) if x.kind == "bone_length"][0]
    assert ea >= (bone.value - bone.hi) / bone.hi > 0
    assert eb > ea
    c = pose.copy()
    c[J["head"], 0] = np.nan
    assert checker.excess(c) >= 1.0
