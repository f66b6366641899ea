"""The posture prior of the initial pose: noisy hips do not tilt or turn the pelvis against the trunk."""

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.softbody import model_from_joints
from toolkit.softbody.init import fit_pose_to_joints
from toolkit.softbody.mesh import sample_surface
from toolkit.softbody.model import TRUNK_POSTURE
from toolkit.softbody.track import TrackConfig, track_sequence

from tests.softbody.conftest import model_walk


@pytest.fixture(scope="module")
def upright():
    """The walk's frame 0 with the trunk neither bent nor twisted against the pelvis, and its joints."""
    model, truth, _, _, _, _ = model_walk(1, 10, seed=0)
    pose = truth[0].pose.copy()
    pose[TRUNK_POSTURE] = 0.0
    p = truth[0].replace(pose=pose)
    return model, p, model.joints(p)


def _hip_line_error_deg(model, p, joints):
    """Angle between the fitted and the true line through the hips."""
    a, b = model.joints(p)[8] - model.joints(p)[11], joints[8] - joints[11]
    return np.degrees(np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1)))


def test_prior_keeps_noisy_hips_level_with_the_trunk(upright):
    """Joints with 3 cm of noise (clicks at 3 m): without the prior the pelvis follows the two noisy hips
    and the trunk bends and twists against it by the noise; with it the hips sit under the trunk."""
    model, _, joints = upright
    rng = np.random.default_rng(3)
    err = {0.0: [], None: []}
    posture = {0.0: [], None: []}
    for _ in range(12):
        noisy = joints + rng.normal(0, 0.03, joints.shape)
        for w in err:
            _, p = model_from_joints(noisy) if w is None else model_from_joints(noisy, posture_weight=w)
            err[w].append(_hip_line_error_deg(model, p, joints))
            posture[w].append(np.degrees(np.abs(p.pose[TRUNK_POSTURE])).max())
    assert np.median(posture[0.0]) > 8.0  # the noise alone bends and twists the trunk
    assert np.median(posture[None]) < 0.5 * np.median(posture[0.0])
    assert np.mean(err[None]) < 0.7 * np.mean(err[0.0])


def test_a_real_bend_still_shows(upright):
    """A trunk really bent 20 degrees sideways and twisted 15: the trunk's joints are met, and the prior's
    price is measured: from exact joints about half the bend and a third of the twist survive (the pelvis
    turns towards the trunk, the hips carry the cost); tracking on the body's own noiseless surface then
    recovers most of the bend and about half the twist (the surface shows a twist against the pelvis only
    weakly).  Without the prior both are exact."""
    model, p, _ = upright
    pose = p.pose.copy()
    pose[TRUNK_POSTURE] = np.radians([20.0, 15.0])
    bent = p.replace(pose=pose)
    joints = model.joints(bent)
    fit = fit_pose_to_joints(model, p, joints, posture_weight=0.2)
    trunk = [0, 1, 2, 3, 4, 5, 6, 7]  # head, neck, shoulders, arms: within 2 cm
    assert np.linalg.norm(model.joints(fit)[trunk] - joints[trunk], axis=-1).max() < 0.02
    bend, twist = np.degrees(fit.pose[TRUNK_POSTURE])
    assert bend > 8.0 and twist > 2.5
    exact = fit_pose_to_joints(model, p, joints, posture_weight=0.0)
    assert 1000 * np.linalg.norm(model.joints(exact) - joints, axis=-1).max() < 1.0
    cloud = sample_surface(model, bent, 300, np.random.default_rng(4))
    track = track_sequence(model, fit, [cloud, cloud])  # the default posture prior
    bend, twist = np.degrees(track.params[-1, TRUNK_POSTURE])
    assert bend > 14.0 and twist > 5.0
    assert 1000 * np.linalg.norm(track.joints[-1] - joints, axis=-1).mean() < 8.0
    free = track_sequence(model, fit, [cloud, cloud], config=TrackConfig(posture_weight=0.0))
    np.testing.assert_allclose(np.degrees(free.params[-1, TRUNK_POSTURE]), [20.0, 15.0], atol=1.0)


def test_bad_posture_weight_is_named():
    from toolkit.pipeline.soft_body import SoftBodyRunConfig
    from toolkit.softbody.global_fit import GlobalFitConfig

    model, truth, joints, _, _, _ = model_walk(1, 10, seed=0)
    with pytest.raises(InputError, match="posture_weight"):
        fit_pose_to_joints(model, truth[0], joints[0], posture_weight=-1.0)
    with pytest.raises(InputError, match="TrackConfig.posture_weight"):
        TrackConfig(posture_weight=float("nan"))
    with pytest.raises(InputError, match="GlobalFitConfig.posture_weight"):
        GlobalFitConfig(posture_weight=-0.1)
    with pytest.raises(InputError, match="init_posture_weight"):
        SoftBodyRunConfig(init_posture_weight=-1.0)


def test_one_flag_sets_the_prior_everywhere(tmp_path):
    """``fit_soft_body.py --posture-weight W`` sets the initial fit's, tracking's and the global fit's
    prior; a --config file's values stay where no flag is given."""
    from recipes.fit_soft_body import config_from_args, parser

    args = parser().parse_args(["data", "--out", str(tmp_path), "--posture-weight", "0"])
    cfg = config_from_args(args)
    assert cfg.init_posture_weight == cfg.track.posture_weight == cfg.fit.posture_weight == 0.0
    toml = tmp_path / "c.toml"
    toml.write_text("init_posture_weight = 0.1\n[track]\nposture_weight = 0.3\n")
    cfg = config_from_args(parser().parse_args(["data", "--out", str(tmp_path), "--config", str(toml)]))
    assert (cfg.init_posture_weight, cfg.track.posture_weight, cfg.fit.posture_weight) == (0.1, 0.3, 0.2)
