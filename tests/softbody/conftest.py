"""Shared scene of the soft-body tests: a person's walk and points sampled on the model's own surface."""

from __future__ import annotations

import numpy as np

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.motion import generate_motion, inverse_kinematics
from toolkit.softbody import SoftBodyModel, params_from_pose14
from toolkit.softbody.mesh import sample_surface


def model_walk(n_frames: int, n_points: int, seed: int):
    """A 1.72 m person's walk (25 fps) as the soft-body model's parameters, and its surface points.

    Returns
    -------
    model : SoftBodyModel
    truth : list of ndarray (n_frames,)
        Parameters per frame.
    joints : ndarray of shape (n_frames, 14, 3)
        Metres.
    clouds : list of ndarray (n_points, 3)
        Noiseless points of the model's surface per frame, metres.
    lengths : ndarray
        The true lengths, metres.
    rng : numpy.random.Generator
        The generator the points were drawn with (for further noise).
    """
    prop = BodyProportions.sample(1.72, rng=2)
    model = SoftBodyModel(prop)
    joints = generate_motion("walk", prop, n_frames, 25.0, rng=0)
    pose = inverse_kinematics(joints)
    lengths = model.lengths_from_proportions(prop)
    truth = [params_from_pose14(pose, t, lengths) for t in range(n_frames)]
    rng = np.random.default_rng(seed)
    clouds = [sample_surface(model, p, n_points, rng) for p in truth]
    return model, truth, joints, clouds, lengths, rng


def without_hands(model, truth, clouds, rng, noise_m: float) -> list:
    """The clouds less their points nearest the hands' metaballs (stereo finds few there), plus noise.

    Parameters
    ----------
    model : SoftBodyModel
    truth : list of SoftBodyParams
        The pose of each cloud.
    clouds : list of ndarray (N_t, 3)
        Metres.
    rng : numpy.random.Generator
    noise_m : float
        Standard deviation of the Gaussian noise added to every kept point, metres.

    Returns
    -------
    list of ndarray (M_t, 3)
    """
    from toolkit.softbody.distance import primitive_distances
    from toolkit.softbody.model import FRAMES

    forearms = [FRAMES.index("l_forearm"), FRAMES.index("r_forearm")]
    hands = np.flatnonzero(~model.prim_axial & np.isin(model.prim_frame, forearms))
    out = []
    for p, c in zip(truth, clouds):
        c = c[~np.isin(primitive_distances(model.state(p), c).argmin(axis=1), hands)]
        out.append(c + rng.normal(0, noise_m, c.shape))
    return out
