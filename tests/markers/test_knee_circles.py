"""Hinge axes from the circles of a child's markers (Plug-in Gait's knee: two shank markers and KNE)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tests.markers.rom_trial import rom_trial
from toolkit.errors import InputError
from toolkit.markers.centres import circle_axis
from toolkit.markers.functional import JointCentresConfig, _fit_joint, joint_centres
from toolkit.markers.rigid import reference_shape, rigid_motions
from toolkit.skeleton import JOINTS_14

J = {n: i for i, n in enumerate(JOINTS_14)}


def pig_knee(n=300, noise=0.0, seed=0, flex_rad=1.6):
    """A thigh (hip centre, THI, KNE on the axis) and a shank (TIB, ANK) hinged at a knee 57 mm medial of KNE.

    Returns parent (T, 3, 3), child (T, 2, 3), the knee (T, 3) and the axis (T, 3) in the world.
    """
    rng = np.random.default_rng(seed)
    knee = np.array([0.0, 0.0, -0.40])  # thigh frame: hip at the origin, x the flexion axis (lateral)
    thigh = np.array([[0.0, 0.0, 0.0], [0.07, 0.006, -0.25], [0.057, 0.0, -0.40]])  # hip, THI, KNE
    shank = np.array([[0.05, 0.008, -0.23], [0.045, -0.001, -0.41]])  # TIB, ANK relative to the knee
    s = np.linspace(0, 1, n)
    flex = 0.5 * flex_rad * (1 - np.cos(6 * np.pi * s))  # 0-92 degrees by default, three times
    rt = Rotation.from_rotvec(np.c_[0.5 * np.sin(4 * np.pi * s), 0.2 * np.cos(2 * np.pi * s), 0.3 * s])
    tt = np.c_[0.2 * s, 0.05 * np.sin(5 * s), 0.9 + 0.02 * s]
    rel = Rotation.from_rotvec(np.c_[-flex, 0 * s, 0 * s])
    parent = np.stack([rt[t].apply(thigh) + tt[t] for t in range(n)])
    child = np.stack([rt[t].apply(knee + rel[t].apply(shank)) + tt[t] for t in range(n)])
    parent = parent + rng.normal(scale=noise, size=parent.shape)
    child = child + rng.normal(scale=noise, size=child.shape)
    return parent, child, rt.apply(knee) + tt, rt.apply([1.0, 0.0, 0.0])


def _fit(parent, child, **kw):
    ref = reference_shape(parent)
    rot, trans, _ = rigid_motions(ref, parent)
    return circle_axis(rot, trans, child, parent_reference=ref, parent_points=parent, **kw)


def test_circle_axis_exact_without_noise():
    parent, child, knee, axis = pig_knee()
    child[10, 0] = np.nan  # a gap
    # anchor: the knee moved along the axis and across it; the centre is its projection onto the axis
    across = np.cross(axis, [0.0, 0.0, 1.0])
    anchor = knee + 0.02 * axis + 0.03 * across / np.linalg.norm(across, axis=1, keepdims=True)
    for iterations in (0, 5):
        fit = _fit(parent, child, anchor=anchor, iterations=iterations)
        assert fit.method == "circle"
        assert np.min(np.abs(np.sum(fit.axis * axis, axis=1))) > 1 - 1e-9
        assert np.max(np.linalg.norm(fit.centre - (knee + 0.02 * axis), axis=1)) < 1e-6
        assert fit.residual_m < 1e-6 and fit.conditioning < 1e-6 and fit.axis_spread_m < 1e-6
        assert 85 < fit.rom_deg[0] < 95  # the flexion range, 92 degrees


def test_circle_axis_bounded_with_noise():
    for noise in (0.0005, 0.002):
        parent, child, knee, axis = pig_knee(n=600, noise=noise, seed=1)
        fit = _fit(parent, child, anchor=knee)
        ang = np.degrees(np.arccos(np.clip(np.abs(np.sum(fit.axis * axis, axis=1)), 0, 1)))
        err = np.mean(np.linalg.norm(fit.centre - knee, axis=1))
        assert np.mean(ang) < 1000 * noise, (noise, np.mean(ang))  # 0.5 deg at 0.5 mm, 2 deg at 2 mm
        assert err < 3 * noise, (noise, err)
        assert fit.residual_m < 2 * noise


def test_circle_axis_bad_input():
    parent, child, _, _ = pig_knee(n=20)
    rot, trans, _ = rigid_motions(reference_shape(parent), parent)
    with pytest.raises(InputError, match="points"):
        circle_axis(rot, trans, child[:, :, :2])
    child[2:] = np.nan
    with pytest.raises(InputError, match="at least 3 frames"):
        circle_axis(rot, trans, child)
    with pytest.raises(InputError, match="parent_reference"):
        circle_axis(rot, trans, pig_knee(n=20)[1], parent_reference=np.zeros((3, 3)), parent_points=parent[:, :2])


def test_plug_in_gait_knees_by_circles_exact_and_bounded():
    traj, truth = rom_trial("plug-in-gait", n_frames=200)
    res = joint_centres(traj)
    for name in ("l_knee", "r_knee"):  # the shank's TIB, ANK and the borrowed KNE lie nearly on a line
        assert res.method[J[name]] == "circle", res.messages
    err = np.linalg.norm(res.joints - truth, axis=-1)
    assert np.max(err[:, [J["l_knee"], J["r_knee"]]]) < 1e-4
    traj, truth = rom_trial("plug-in-gait", n_frames=300, noise_m=0.001, seed=2)
    res = joint_centres(traj)
    err = np.nanmean(np.linalg.norm(res.joints - truth, axis=-1), axis=0)
    for name in ("l_knee", "r_knee"):
        assert res.method[J[name]] == "circle" and err[J[name]] < 0.006, (name, err[J[name]])


def test_circle_fits_keep_the_refusals():
    traj, _ = rom_trial("plug-in-gait", n_frames=200, noise_m=0.001, seed=4)
    res = joint_centres(traj, config=replace(JointCentresConfig(), max_axis_spread_m=1e-6))
    assert res.method[J["l_knee"]] == "template"
    assert any(m.startswith("l_knee") and "does not fix where the axis lies" in m for m in res.messages)
    parent, child, knee, _ = pig_knee(noise=0.0005, flex_rad=0.15)  # a knee bent 9 degrees at most
    fit, why = _fit_joint("hinge", parent, np.concatenate([child, parent[:, 2:]], axis=1), knee,
                          JointCentresConfig(), n_own=2)
    assert fit.method == "circle" and fit.rom_deg[0] < 10 and "functional centres need movement" in why
    parent, child, knee, _ = pig_knee(noise=0.0005)
    fit, why = _fit_joint("hinge", parent, np.concatenate([child, parent[:, 2:]], axis=1), knee,
                          JointCentresConfig(), n_own=2)
    assert fit.method == "circle" and why == ""
    with pytest.raises(InputError, match="max_axis_spread_m"):
        JointCentresConfig(max_axis_spread_m=0.0)
