"""A small range-of-motion trial of labelled markers with exact joints (for the centre tests)."""

from __future__ import annotations

import numpy as np

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.markers.marker_sets import get_marker_set
from toolkit.markers.trajectories import MISSING, TRINOCULAR, MarkerTrajectories
from toolkit.motion.kinematics import Pose14, forward_kinematics


def rom_pose(n_frames: int, rng: np.random.Generator, *, still: bool = False) -> Pose14:
    """Each hip, shoulder (flexion, abduction, rotation), knee and elbow moved in turn; pelvis wandering."""
    p = Pose14.neutral(n_frames, root=[0.0, 0.0, 0.95])
    if still:
        return p
    s = np.linspace(0, 1, n_frames)
    w = 2 * np.pi * s
    hip = np.zeros((n_frames, 2, 3))
    sh = np.zeros((n_frames, 2, 3))
    for side in range(2):
        ph = rng.uniform(0, 2 * np.pi)
        hip[:, side, 0] = 0.5 * np.sin(3 * w + ph) + 0.2
        hip[:, side, 1] = 0.3 * np.sin(5 * w + ph) + 0.15
        hip[:, side, 2] = 0.25 * np.sin(7 * w + ph)
        sh[:, side, 0] = 0.7 * np.sin(2 * w + ph) + 0.3
        sh[:, side, 1] = 0.5 * np.sin(3 * w + ph) + 0.6
        sh[:, side, 2] = 0.3 * np.sin(4 * w + ph)
    knee = 0.6 * (1 - np.cos(4 * w))[:, None] * np.ones((1, 2))
    elbow = 0.7 * (1 - np.cos(5 * w))[:, None] * np.ones((1, 2))
    yaw = 0.3 * np.sin(w)
    root = np.c_[0.05 * np.sin(w), 0.05 * np.cos(w), 0.95 + 0.01 * np.sin(3 * w)]
    return Pose14(root=root, yaw=yaw, pitch=0.05 * np.sin(2 * w), roll=0.03 * np.sin(3 * w), lean=0 * s,
                  twist=0 * s, head_pitch=0 * s, head_roll=0 * s, shoulder=sh, elbow=elbow, hip=hip, knee=knee)


def rom_trial(marker_set: str = "cluster", *, n_frames: int = 300, noise_m: float = 0.0, missing: float = 0.0,
              seed: int = 0, still: bool = False, height: float = 1.75):
    """Labelled trajectories and the true joints (T, 14, 3) of a range-of-motion (or still) trial."""
    rng = np.random.default_rng(seed)
    props = BodyProportions.from_height(height)
    pose = rom_pose(n_frames, rng, still=still)
    joints = forward_kinematics(props, pose)
    mset = get_marker_set(marker_set)
    pos = mset.positions(joints, pose=pose)
    pos = pos + rng.normal(scale=noise_m, size=pos.shape) if noise_m > 0 else pos
    if missing > 0:
        pos[rng.random(pos.shape[:2]) < missing] = np.nan
    seen = np.isfinite(pos).all(axis=-1)
    traj = MarkerTrajectories(mset.labels, pos, np.where(seen, TRINOCULAR, MISSING).astype(np.int8), 100.0,
                              mset.segments, "rom_trial")
    return traj, joints
