"""Synthetic multi-view scenes with known 3D joints, for the multi-view tests."""

from __future__ import annotations

import numpy as np

from toolkit.anthropometry import BodyProportions
from toolkit.cameras import Camera, Rig
from toolkit.motion import generate_motion

#: Broadcast-like camera distance to the subject, metres.
BROADCAST_DISTANCE_M = 20.0
#: Horizontal field of view of the broadcast cameras, degrees (a player ~150 px tall at 1280 px).
BROADCAST_FOV_DEG = 20.0


def broadcast_rig(n_cams: int, rng: np.random.Generator, distortion: bool = False,
                  distance: float = BROADCAST_DISTANCE_M) -> Rig:
    """Cameras spread over a quarter circle around the origin, 4-10 m high, looking at (0, 0, 1)."""
    cams = []
    for i in range(n_cams):
        a = -0.6 + (np.pi / 2) * i / max(n_cams - 1, 1) + rng.uniform(-0.2, 0.2)
        eye = [distance * np.cos(a), distance * np.sin(a), rng.uniform(4, 10)]
        dist = np.array([rng.uniform(-0.2, 0.2), rng.uniform(-0.05, 0.05), 0, 0, 0]) if distortion else None
        cams.append(Camera.look_at(f"cam{i}", eye, [0, 0, 1], size=(1280, 720), fov_x_deg=BROADCAST_FOV_DEG,
                                   dist=dist))
    return Rig(tuple(cams))


def walking_poses(rng: np.random.Generator, n_frames: int = 10, motion: str = "walk") -> np.ndarray:
    """(n_frames, 14, 3) joints of a walking person centred near the origin, metres."""
    poses = generate_motion(motion, BodyProportions.from_height(1.75), n_frames, 25, rng)
    centre = np.nanmean(poses[:, :, :2], axis=(0, 1))
    return poses - np.array([centre[0], centre[1], 0.0])
