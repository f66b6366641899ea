"""Shared fixtures: a small rendered database and a small two-camera walking scene."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.cameras import Camera, Rig
from toolkit.motion import generate_motion
from toolkit.silhouettes import BuildConfig, build_database
from toolkit.body.model import BodyModel
from toolkit.synthetic.render import Raycaster

#: A database of walking poses (2 people x 20 poses x 12 views x 2 mirror = 960 entries, ~2 s).
SMALL_BUILD = BuildConfig(motions=("walk",), sequences_per_motion=2, frames_per_sequence=40, frame_stride=2,
                          views_per_pose=12)
SMALL_BUILD_SEED = 11


@pytest.fixture(scope="session")
def walk_db():
    """The small walking database (do not modify: copy with ``subset`` first)."""
    return build_database(SMALL_BUILD, SMALL_BUILD_SEED)


def broadcast_rig(centre_xy, azimuths_deg=(-60.0, 30.0), distance=30.0, height=8.0, size=(480, 270),
                  focal_px=3000.0) -> Rig:
    """Far, elevated cameras around ``centre_xy`` (the subject ~175 px tall)."""
    cams = []
    for i, az in enumerate(azimuths_deg):
        a = np.radians(az)
        eye = [centre_xy[0] + distance * np.cos(a), centre_xy[1] + distance * np.sin(a), height]
        cams.append(Camera.look_at(f"cam{i}", eye, [centre_xy[0], centre_xy[1], 1.0], size=size, focal_px=focal_px))
    return Rig(tuple(cams))


class WalkScene:
    """A person walking (seed different from the database's), seen by a rig, with exact masks."""

    def __init__(self, n_frames=6, azimuths_deg=(-60.0, 30.0), seed=5):
        rng = np.random.default_rng(seed)
        props = BodyProportions.sample(1.75, rng)
        self.model = BodyModel.sample(props, rng, detail=0.4)
        self.joints = generate_motion("walk", props, n_frames, 25.0, rng)
        self.rig = broadcast_rig(self.joints[0, 1, :2], azimuths_deg)
        caster = Raycaster()
        self.masks = [[caster.cast(cam, [self.model.mesh(j)])[1] > 0 for cam in self.rig] for j in self.joints]


@pytest.fixture(scope="session")
def walk_scene():
    return WalkScene()


@pytest.fixture(scope="session")
def walk_scene3():
    return WalkScene(n_frames=3, azimuths_deg=(-60.0, 30.0, 120.0), seed=6)
