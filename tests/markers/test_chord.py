"""Plug-in Gait's chord rule (toolkit.markers.skeleton_fit.chord): exact on a constructed leg, NaN where degenerate."""

import numpy as np

from toolkit.markers.skeleton_fit import J14, anatomical_joints, chord


def _leg(rng, t=20):
    """Knee centres X, hips 0.4 m above them, KNE laterally d away, THI on the lateral side of the thigh."""
    x = rng.normal(size=(t, 3)) * 0.2 + [0, 0, 0.5]
    up = rng.normal(size=(t, 3))
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    lat = np.cross(up, rng.normal(size=(t, 3)))
    lat /= np.linalg.norm(lat, axis=1, keepdims=True)
    d = 0.079
    hip, kne = x + 0.4 * up, x + d * lat
    thi = x + 0.2 * up + 0.12 * lat  # lateral of the hip-knee line
    return x, hip, thi, kne, d


def test_chord_recovers_the_centre_exactly():
    x, hip, thi, kne, d = _leg(np.random.default_rng(3))
    np.testing.assert_allclose(chord(hip, thi, kne, d), x, atol=1e-12)


def test_chord_nan_where_degenerate_or_missing():
    x, hip, thi, kne, d = _leg(np.random.default_rng(4), t=3)
    hip[0] = kne[0] + [0, 0, 0.05]  # the hip closer than the offset
    thi[1] = np.nan
    out = chord(hip, thi, kne, d)
    assert np.isnan(out[:2]).all() and np.isfinite(out[2]).all()


def test_anatomical_knee_and_ankle_use_the_measured_widths():
    t = 5
    pelvis = {"LASI": [0.12, 0.1, 1.0], "RASI": [-0.12, 0.1, 1.0], "LPSI": [0.05, -0.08, 1.02],
              "RPSI": [-0.05, -0.08, 1.02]}
    legs = {"LTHI": [0.16, 0.02, 0.75], "LKNE": [0.15, 0.0, 0.5], "LTIB": [0.15, 0.02, 0.3], "LANK": [0.14, 0.0, 0.08]}
    labels = tuple(pelvis) + tuple(legs)
    pos = np.repeat(np.array([*pelvis.values(), *legs.values()], float)[None], t, axis=0)
    for knee_w, ankle_w in ((0.10, 0.07), (0.144, 0.085)):
        out = anatomical_joints(labels, pos, measurements={"LKneeWidth": knee_w, "LAnkleWidth": ankle_w,
                                                           "MarkerDiameter": 0.016})
        k, a = out[:, J14["l_knee"]], out[:, J14["l_ankle"]]
        np.testing.assert_allclose(np.linalg.norm(k - legs["LKNE"], axis=1), knee_w / 2 + 0.008, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(a - legs["LANK"], axis=1), ankle_w / 2 + 0.008, atol=1e-12)
        assert (k[:, 0] < legs["LKNE"][0]).all()  # medial of the lateral marker (the subject faces +y)
        # a right angle at the knee between the hip and KNE
        hip = out[:, J14["l_hip"]]
        np.testing.assert_allclose(np.sum((hip - k) * (legs["LKNE"] - k), axis=1), 0.0, atol=1e-12)


def test_malleoli_where_given_come_before_the_chord():
    t = 3
    pts = {"LASI": [0.12, 0.1, 1.0], "RASI": [-0.12, 0.1, 1.0], "LPSI": [0.05, -0.08, 1.02], "RPSI": [-0.05, -0.08, 1.02],
           "LTHI": [0.16, 0.02, 0.75], "LKNE": [0.15, 0.0, 0.5], "LTIB": [0.15, 0.02, 0.3], "LANK": [0.14, 0.0, 0.08],
           "LLM": [0.14, 0.0, 0.08], "LMM": [0.07, 0.0, 0.09]}
    pos = np.repeat(np.array(list(pts.values()), float)[None], t, axis=0)
    out = anatomical_joints(tuple(pts), pos, measurements={"LAnkleWidth": 0.085})
    np.testing.assert_allclose(out[:, J14["l_ankle"]], [[0.105, 0.0, 0.085]] * t, atol=1e-12)
