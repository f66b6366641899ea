"""Skeletons as data."""

import numpy as np
import pytest

from toolkit.anthropometry import BodyProportions
from toolkit.errors import InputError
from toolkit.skeleton import JOINTS_14, SKELETON_13, SKELETON_14, SKELETON_17


def test_fourteen_joint_names_exact():
    assert SKELETON_14.joint_names == ("head", "neck", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow",
                                       "r_wrist", "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle")
    assert JOINTS_14 == SKELETON_14.joint_names
    assert len(SKELETON_14.bones) == 13
    assert SKELETON_14.n_parts == 10


@pytest.mark.parametrize("sk", [SKELETON_13, SKELETON_14, SKELETON_17])
def test_symmetric_pairs_mirror_names(sk):
    names = sk.bone_names
    for a, b in sk.symmetric_bones:
        assert names[a].replace("l_", "X_") == names[b].replace("r_", "X_")
    perm = sk.flip_permutation
    assert sorted(perm) == list(range(sk.n_joints))
    np.testing.assert_array_equal(perm[perm], np.arange(sk.n_joints))


def test_control_point_counts():
    assert SKELETON_13.n_joints == 13 and SKELETON_17.n_joints == 17


def test_part_endpoints_and_lengths():
    p = BodyProportions.from_height(1.75)
    j = p.rest_pose()
    ends = SKELETON_14.part_endpoints(j)
    assert ends.shape == (10, 2, 3)
    torso = SKELETON_14.part_names.index("torso")
    np.testing.assert_allclose(ends[torso, 1], 0.5 * (j[8] + j[11]))
    L = SKELETON_14.bone_lengths(j)
    assert L[SKELETON_14.bone_names.index("l_shoulder-l_elbow")] == pytest.approx(p.upper_arm)
    assert SKELETON_14.parts_of_joint(SKELETON_14.index("l_hip")) == [1, 6]


def test_bad_joint_arrays():
    with pytest.raises(InputError):
        SKELETON_14.part_endpoints(np.zeros((13, 3)))
    with pytest.raises(KeyError):
        SKELETON_14.index("pelvis")
