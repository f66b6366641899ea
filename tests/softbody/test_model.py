"""The soft body's kinematics, distance and derivatives against ground truth and finite differences."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.motion import forward_kinematics, generate_motion, inverse_kinematics
from toolkit.softbody import N_PARAMS, SoftBodyModel, SoftBodyParams
from toolkit.softbody.distance import distance, distance_and_jacobian
from toolkit.softbody.init import params_from_pose14

#: Central differences with step 1e-6 on a smooth function of metre-scale inputs:
#: truncation ~1e-12 and round-off ~1e-10, so 1e-7 leaves room and still catches any wrong term.
FD_TOL = 1e-7


def _random_params(model, rng, spread=0.3):
    p = model.default_params((0.2, -0.1, 1.0))
    noise = np.r_[rng.normal(0, spread, 27), rng.normal(0, 0.02, 13), rng.normal(0, 0.1, 7)]
    return SoftBodyParams(p.vector + noise)


def test_joints_match_motion_kinematics():
    """Angles of toolkit.motion map onto the model exactly (same conventions)."""
    prop = BodyProportions.sample(1.68, rng=3)
    model = SoftBodyModel(prop)
    joints = generate_motion("walk", prop, 6, 25.0, rng=1)
    pose = inverse_kinematics(joints)
    fk = forward_kinematics(prop, pose)
    for t in range(6):
        params = params_from_pose14(pose, t, model.lengths_from_proportions(prop))
        np.testing.assert_allclose(model.joints(params), fk[t], atol=1e-12)


def test_joints_jacobian_matches_finite_differences():
    model = SoftBodyModel()
    params = _random_params(model, np.random.default_rng(0))
    jac = model.joints_jacobian(params)
    num = np.zeros_like(jac)
    for k in range(N_PARAMS):
        step = np.zeros(N_PARAMS)
        step[k] = 1e-6
        num[..., k] = (model.joints(SoftBodyParams(params.vector + step))
                       - model.joints(SoftBodyParams(params.vector - step))) / 2e-6
    np.testing.assert_allclose(jac, num, atol=FD_TOL)


@pytest.mark.parametrize("seed", [0, 1])
def test_distance_jacobian_matches_finite_differences(seed):
    """Every column (root, angles, lengths, widths) for points inside, near and far from the body."""
    rng = np.random.default_rng(seed)
    model = SoftBodyModel()
    params = _random_params(model, rng)
    st = model.state(params)
    pts = st.centres[rng.integers(0, model.n_prims, 300)] + rng.normal(0, 0.12, (300, 3))
    d, jac = distance_and_jacobian(model, params, pts)
    np.testing.assert_allclose(d, distance(model, params, pts))
    num = np.zeros_like(jac)
    for k in range(N_PARAMS):
        step = np.zeros(N_PARAMS)
        step[k] = 1e-6
        num[:, k] = (distance(model, SoftBodyParams(params.vector + step), pts)
                     - distance(model, SoftBodyParams(params.vector - step), pts)) / 2e-6
    np.testing.assert_allclose(jac, num, atol=FD_TOL)
    assert np.abs(jac).max() > 0.5  # the derivatives are not trivially zero


def test_distance_is_metric_near_an_isolated_part():
    """Beside the middle of a thigh the distance grows about one to one with the offset.

    The radial distance to an ellipsoid is exact for a sphere only; beside two
    overlapping elongated primitives its slope stays within 10 % of 1.
    """
    model = SoftBodyModel()
    params = model.default_params((0, 0, 1.0))
    st = model.state(params)
    knee, hip = st.nodes[9], st.nodes[8]
    mid = 0.5 * (knee + hip)
    offsets = np.linspace(0.1, 0.35, 6)
    pts = mid + offsets[:, None] * np.array([0.0, 1.0, 0.0])  # forward of the left thigh
    d = distance(model, params, pts)
    np.testing.assert_allclose(np.diff(d), np.diff(offsets), rtol=0.1)
    assert distance(model, params, mid[None])[0] < -0.02


def test_bad_inputs():
    model = SoftBodyModel()
    params = model.default_params()
    with pytest.raises(InputError):
        distance(model, params, np.zeros((3, 2)))
    with pytest.raises(InputError):
        distance(model, params, np.full((1, 3), np.nan))
    with pytest.raises(InputError):
        SoftBodyParams(np.zeros(5))
    with pytest.raises(InputError):
        model.state(params.replace(lengths=-np.ones(13)))
    assert distance(model, params, np.zeros((0, 3))).shape == (0,)
    assert distance_and_jacobian(model, params, np.zeros((0, 3)))[1].shape == (0, N_PARAMS)


def test_params_rotation_vector_roundtrip():
    model = SoftBodyModel()
    rv = np.array([0.3, -0.2, 2.5])
    p = model.default_params().replace(pose=np.r_[rv, np.zeros(24)])
    R = model.state(p).frame_R[0]
    np.testing.assert_allclose(R, Rotation.from_rotvec(rv).as_matrix(), atol=1e-12)
