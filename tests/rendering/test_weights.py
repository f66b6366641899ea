import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.rendering import ANGLE_SIGMA, ATTENUATION_SIGMA_M, attenuation, camera_weights, grazing_fade, omega

#: Floating-point agreement of closed-form values.
EXACT = 1e-12


def test_constants_of_the_source():
    assert ANGLE_SIGMA == 0.32 and ATTENUATION_SIGMA_M == 1.0


def test_omega_and_attenuation_closed_form():
    assert omega(0.0) == 1.0
    assert abs(omega(0.32) - np.exp(-0.5)) < EXACT
    assert attenuation(0.0) == 0.0
    assert abs(attenuation(1.0) - (1 - np.exp(-0.5))) < EXACT


def _rig_centres():
    # three cameras on a 5 m ring at 0, 90 and 200 degrees
    a = np.radians([0.0, 90.0, 200.0])
    return np.c_[5 * np.cos(a), 5 * np.sin(a), np.full(3, 1.5)]


def test_virtual_on_a_source_camera_sees_that_camera_alone():
    src = _rig_centres()
    anchors = np.array([[0.0, 0.0, 1.0], [0.2, -0.1, 0.5]])
    w = camera_weights(anchors, src[1], src)
    assert np.all(w.nearest == 1)
    assert np.allclose(w.distance_m, 0.0)
    assert np.allclose(w.weight[:, [0, 2]], 0.0, atol=EXACT)
    assert np.allclose(w.weight[:, 1], 1.0, atol=1e-9)


def test_between_two_cameras_weights_are_symmetric_and_attenuated():
    src = _rig_centres()[:2]
    mid = 0.5 * (src[0] + src[1])
    mid = mid / np.linalg.norm(mid[:2]) * 5.0
    mid[2] = 1.5
    w = camera_weights(np.array([[0.0, 0.0, 1.5]]), mid, src)
    assert abs(w.omega[0, 0] - w.omega[0, 1]) < 1e-9
    d = np.linalg.norm(mid - src[w.nearest[0]])
    assert abs(w.attenuation[0, 1 - w.nearest[0]] - (1 - np.exp(-d * d / 2))) < EXACT
    assert w.attenuation[0, w.nearest[0]] == 1.0


def test_grazing_fade_back_facing_and_at_source():
    src = np.array([[5.0, 0.0, 1.0]])
    p = np.zeros((1, 1, 3))
    n = np.array([[[1.0, 0.0, 0.0]]])
    assert grazing_fade(n, p, src[0], src)[0, 0] == 1.0  # at the source
    assert grazing_fade(n, p, np.array([-5.0, 0.0, 1.0]), src)[0, 0] == 0.0  # from behind
    assert grazing_fade(n, p, np.array([0.01, 5.0, 0.0]), src)[0, 0] == 0.0  # edge-on


def test_back_faces_fade_and_mirrored_angle():
    from toolkit.rendering.weights import back_view_angles

    src = np.array([[5.0, 0.0, 1.0]])
    p = np.zeros((1, 1, 3))
    n = np.array([[[1.0, 0.0, 0.0]]])
    behind = np.array([-5.0, 0.0, 1.0])  # the source mirrored through the plane x = 0
    assert grazing_fade(n, p, behind, src, side="back")[0, 0] == 1.0
    assert grazing_fade(n, p, src[0], src, side="back")[0, 0] == 0.0  # in front: no back face
    # the back face seen from the mirrored source looks like the front from the source: beta = 0
    assert back_view_angles(np.zeros((1, 3)), n, p, behind, src)[0, 0] < EXACT
    # 40 degrees round from the mirrored position: beta = 40 degrees
    a = np.radians(180.0 - 40.0)
    v = np.array([5.0 * np.cos(a), 5.0 * np.sin(a), 0.0])
    src0 = np.array([[5.0, 0.0, 0.0]])
    assert abs(back_view_angles(np.zeros((1, 3)), n, p, v, src0)[0, 0] - np.radians(40.0)) < 1e-9
    with pytest.raises(InputError, match="side"):
        grazing_fade(n, p, src[0], src, side="top")


def test_foreshortening_ratio():
    from toolkit.rendering import foreshortening

    src = np.array([[5.0, 0.0, 1.0]])
    p = np.zeros((1, 1, 3))
    n = np.array([[[-1.0, 0.0, 0.0]]])  # any sign: turned towards the source
    assert abs(foreshortening(n, p, src[0], src)[0, 0] - 1.0) < EXACT  # at the source
    assert abs(foreshortening(n, p, np.array([-5.0, 0.0, 1.0]), src)[0, 0] + 1.0) < EXACT  # mirrored
    a = np.radians(80.0)  # 80 degrees off the normal, the source on it: cos 80
    r = foreshortening(n, p, np.array([5.0 * np.cos(a), 5.0 * np.sin(a), 0.0]), np.array([[5.0, 0.0, 0.0]]))
    assert abs(r[0, 0] - np.cos(a)) < 1e-9


def test_bad_input_is_named():
    with pytest.raises(InputError, match="anchors"):
        camera_weights(np.zeros(3), np.zeros(3), _rig_centres())
    with pytest.raises(InputError, match="virtual_center"):
        camera_weights(np.zeros((1, 3)), np.array([np.nan, 0, 0]), _rig_centres())
