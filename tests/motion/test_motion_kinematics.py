"""Forward/inverse kinematics of the 14-joint skeleton, IK, ground alignment, resampling."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.motion.kinematics import (
    KNEE_MIN_FLEXION,
    Pose14,
    align_to_ground,
    bone_lengths14,
    forward_kinematics,
    inverse_kinematics,
    leg_reach,
    resample,
    sequence_bone_lengths,
    set_bone_lengths,
    two_bone_ik,
)
from toolkit.skeleton import SKELETON_14

#: Exact arithmetic up to float rounding of a few chained rotations, metres or radians.
EXACT = 1e-9
J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}


def random_pose(rng, n):
    def u(a, b, shape=(n,)):
        return rng.uniform(a, b, shape)

    # angles inside the principal ranges of the inverse (abduction within +-90 deg, bends in (0, pi))
    return Pose14(root=u(-1, 1, (n, 3)), yaw=u(-3, 3), pitch=np.zeros(n), roll=u(-0.3, 0.3),
                  lean=u(-0.3, 1.0), twist=u(-0.6, 0.6), head_pitch=u(-0.5, 0.5), head_roll=u(-0.3, 0.3),
                  shoulder=u(-1.4, 1.4, (n, 2, 3)), elbow=u(0.05, 2.5, (n, 2)),
                  hip=u(-1.0, 1.4, (n, 2, 3)), knee=u(0.05, 2.3, (n, 2)))


def standing(p, n=1):
    return Pose14.neutral(n, root=[0.0, 0.0, p.ankle_height + p.shank + p.thigh])


def test_zero_angles_give_the_rest_pose(person):
    j = forward_kinematics(person, standing(person))
    np.testing.assert_allclose(j[0], person.rest_pose(), atol=EXACT)


def test_bone_lengths_are_the_proportions_in_every_frame(person):
    pose = random_pose(np.random.default_rng(0), 300)
    j = forward_kinematics(person, pose)
    np.testing.assert_allclose(sequence_bone_lengths(j), np.tile(bone_lengths14(person), (300, 1)),
                               atol=EXACT)


def test_bone_lengths14_matches_rest_pose(person):
    np.testing.assert_allclose(bone_lengths14(person), SKELETON_14.bone_lengths(person.rest_pose()),
                               atol=EXACT)


def test_inverse_kinematics_reproduces_positions_and_angles(person):
    pose = random_pose(np.random.default_rng(1), 200)
    j = forward_kinematics(person, pose)
    back = inverse_kinematics(j)
    np.testing.assert_allclose(forward_kinematics(person, back), j, atol=EXACT)
    for name in ("yaw", "roll", "lean", "twist", "head_pitch", "head_roll", "shoulder", "elbow", "hip",
                 "knee"):
        np.testing.assert_allclose(getattr(back, name), getattr(pose, name), atol=1e-7, err_msg=name)


def test_inverse_kinematics_absorbs_pelvis_pitch(person):
    pose = random_pose(np.random.default_rng(2), 50)
    tilted = Pose14(**{**pose.__dict__, "pitch": np.full(50, 0.3)})
    j = forward_kinematics(person, tilted)
    back = inverse_kinematics(j)
    assert np.all(back.pitch == 0)
    np.testing.assert_allclose(forward_kinematics(person, back), j, atol=EXACT)


@pytest.mark.parametrize("field, value, joint, axis, sign", [
    ("lean", 0.5, "neck", 1, +1),            # trunk bends forward (+y at zero yaw)
    ("head_pitch", 0.5, "head", 1, +1),      # nod forward
    ("head_roll", 0.5, "head", 0, +1),       # tilt to the right (+x)
    ("roll", 0.2, "r_hip", 2, -1),           # right hip drops
])
def test_trunk_sign_conventions(person, field, value, joint, axis, sign):
    base = forward_kinematics(person, standing(person))[0]
    pose = standing(person)
    pose = Pose14(**{**pose.__dict__, field: np.full(1, value)})
    moved = forward_kinematics(person, pose)[0]
    assert sign * (moved[J[joint], axis] - base[J[joint], axis]) > 0.01


@pytest.mark.parametrize("side, pre, out", [(0, "l_", -1.0), (1, "r_", 1.0)])
def test_limb_sign_conventions(person, side, pre, out):
    base = forward_kinematics(person, standing(person))[0]

    def moved(field, index, value):
        pose = standing(person)
        arr = getattr(pose, field).copy()
        arr[(0, side) + index] = value
        return forward_kinematics(person, Pose14(**{**pose.__dict__, field: arr}))[0]

    assert moved("shoulder", (0,), 0.5)[J[pre + "wrist"], 1] > base[J[pre + "wrist"], 1] + 0.1
    assert out * (moved("shoulder", (1,), 0.5)[J[pre + "wrist"], 0] - base[J[pre + "wrist"], 0]) > 0.1
    assert moved("elbow", (), 1.0)[J[pre + "wrist"], 1] > 0.1            # forearm forward
    assert moved("hip", (0,), 0.5)[J[pre + "ankle"], 1] > 0.1             # thigh forward
    assert out * (moved("hip", (1,), 0.3)[J[pre + "ankle"], 0] - base[J[pre + "ankle"], 0]) > 0.1
    assert moved("knee", (), 1.0)[J[pre + "ankle"], 1] < -0.1             # shank backward
    # internal rotation turns a bent forearm toward the midline (x = 0)
    pose = standing(person)
    el = pose.elbow.copy()
    el[0, side] = np.pi / 2
    sh = pose.shoulder.copy()
    sh[0, side, 2] = 0.5
    w = forward_kinematics(person, Pose14(**{**pose.__dict__, "elbow": el, "shoulder": sh}))[0]
    assert abs(w[J[pre + "wrist"], 0]) < abs(base[J[pre + "wrist"], 0]) - 0.05


def test_yaw_turns_counter_clockwise(person):
    pose = standing(person)
    pose = Pose14(**{**pose.__dict__, "yaw": np.full(1, np.pi / 2)})
    j = forward_kinematics(person, pose)[0]
    # facing +y turned by +90 deg faces -x; the person's left (was -x) is now -y
    assert j[J["l_hip"], 1] < -0.05 and abs(j[J["l_hip"], 0]) < EXACT


def test_pose_shape_errors():
    with pytest.raises(InputError, match="Pose14.knee"):
        p = Pose14.neutral(3)
        Pose14(**{**p.__dict__, "knee": np.zeros((3, 3))})
    with pytest.raises(InputError, match="Pose14.root"):
        Pose14.neutral(3).__class__(**{**Pose14.neutral(3).__dict__, "root": np.zeros(3)})


def test_two_bone_ik_reaches_and_bends_toward_pole():
    rng = np.random.default_rng(3)
    n = 100
    base = rng.normal(0, 1, (n, 3))
    d = rng.normal(0, 1, (n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    target = base + d * rng.uniform(0.05, 0.8, (n, 1))
    pole = rng.normal(0, 1, (n, 3))
    mid, end, reached = two_bone_ik(base, target, 0.42, 0.40, pole)
    assert reached.all()
    np.testing.assert_allclose(end, target, atol=EXACT)
    np.testing.assert_allclose(np.linalg.norm(mid - base, axis=1), 0.42, atol=EXACT)
    np.testing.assert_allclose(np.linalg.norm(end - mid, axis=1), 0.40, atol=EXACT)
    # the middle joint lies on the pole's side of the chain
    u = d
    w = pole - np.sum(pole * u, 1, keepdims=True) * u
    assert np.all(np.sum((mid - base) * w, 1) > 0)


def test_two_bone_ik_pulls_unreachable_targets_along_the_ray():
    base = np.zeros((2, 3))
    target = np.array([[0, 0, -2.0], [0, 0, -0.7]])
    mid, end, reached = two_bone_ik(base, target, 0.4, 0.4, np.array([0, 1.0, 0]), max_reach=[0.75, 0.75])
    assert list(reached) == [False, True]
    np.testing.assert_allclose(end[0], [0, 0, -0.75], atol=EXACT)
    np.testing.assert_allclose(end[1], target[1], atol=EXACT)


def test_leg_reach_matches_knee_flexion(person):
    pose = standing(person)
    pose = Pose14(**{**pose.__dict__, "knee": np.full((1, 2), KNEE_MIN_FLEXION)})
    j = forward_kinematics(person, pose)[0]
    assert np.linalg.norm(j[J["l_ankle"]] - j[J["l_hip"]]) == pytest.approx(leg_reach(person), abs=EXACT)


def test_align_to_ground_sequence_keeps_flight_and_never_penetrates(person):
    rest = person.rest_pose()
    z = np.zeros(100)
    z[40:50] = 0.3 * np.sin(np.linspace(0, np.pi, 10))   # a jump
    z[70] = -0.05                                         # one frame sunk 5 cm (below the 5th percentile)
    j = np.stack([rest + [0, 0, 0.5 + dz] for dz in z])
    out = align_to_ground(j, person.ankle_height)
    low = out[:, [J["l_ankle"], J["r_ankle"]], 2].min(1)
    np.testing.assert_allclose(low, person.ankle_height + np.maximum(z, 0), atol=EXACT)
    per_frame = align_to_ground(j, person.ankle_height, mode="frame")
    np.testing.assert_allclose(per_frame[:, [J["l_ankle"], J["r_ankle"]], 2].min(1), person.ankle_height,
                               atol=EXACT)
    with pytest.raises(InputError, match="mode"):
        align_to_ground(j, person.ankle_height, mode="median")
    with pytest.raises(InputError, match="ankle_height"):
        align_to_ground(j, -1.0)


def test_resample_is_exact_for_linear_motion():
    t = np.arange(121) / 120.0
    j = np.zeros((121, 14, 3))
    j[..., 0] = (2.0 * t)[:, None]
    out = resample(j, 120.0, 25.0)
    assert out.shape == (26, 14, 3)
    np.testing.assert_allclose(out[:, 0, 0], 2.0 * np.arange(26) / 25.0, atol=EXACT)
    with pytest.raises(InputError, match="dst_fps"):
        resample(j, 120.0, 0.0)
    with pytest.raises(InputError, match="joints"):
        resample(np.zeros((5, 3)), 120.0, 25.0)


def test_resample_missing_joint_stays_missing():
    j = np.zeros((3, 14, 3))
    j[1, 5] = np.nan
    out = resample(j, 2.0, 4.0)             # times 0, .25, .5, .75, 1
    assert np.isnan(out[1:4, 5]).all() and np.isfinite(out[[0, 4], 5]).all()


def test_set_bone_lengths_keeps_directions(person):
    j = forward_kinematics(person, random_pose(np.random.default_rng(4), 20))
    other = BodyProportions.from_height(1.6)
    out = set_bone_lengths(j, bone_lengths14(other))
    np.testing.assert_allclose(sequence_bone_lengths(out), np.tile(bone_lengths14(other), (20, 1)), atol=EXACT)
    for a, b in SKELETON_14.bones:
        da = (j[:, b] - j[:, a]) / np.linalg.norm(j[:, b] - j[:, a], axis=-1, keepdims=True)
        db = (out[:, b] - out[:, a]) / np.linalg.norm(out[:, b] - out[:, a], axis=-1, keepdims=True)
        np.testing.assert_allclose(da, db, atol=EXACT)
    with pytest.raises(InputError, match="lengths"):
        set_bone_lengths(j, np.ones(12))
