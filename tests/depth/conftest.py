"""Fixtures of the depth-tracking tests: small rendered depth sequences with ground truth."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.motion import generate_motion
from toolkit.body.model import BodyModel
from toolkit.synthetic.depth_sensor import DepthCameraSpec, render_depth_sequence

REPO_ROOT = Path(__file__).resolve().parents[2]


def realdata_root() -> Path:
    """``$TOOLKIT_REALDATA`` or ``../shared/realdata`` next to the repository."""
    env = os.environ.get("TOOLKIT_REALDATA")
    return Path(env) if env else REPO_ROOT.parent / "shared" / "realdata"


@pytest.fixture
def kinect_dir() -> Path:
    root = realdata_root() / "kinect_depth"
    if not root.is_dir():
        pytest.skip(f"real Kinect frames not found at {root}")
    return root


def make_sequence(motion: str, n_frames: int, seed: int, resolution=(320, 240), noise=True, **spec_kw):
    """Render a seeded depth sequence of one person (floor only, Kinect-like noise)."""
    props = BodyProportions.sample(1.75, seed)
    model = BodyModel.sample(props, seed, detail=0.5)
    joints = generate_motion(motion, props, n_frames, 30.0, rng=seed)
    spec = DepthCameraSpec(resolution=resolution, noise=noise, environment=spec_kw.pop("environment", "floor"),
                           **spec_kw)
    seq = render_depth_sequence(spec, model, joints, rng=seed)
    return seq, model, joints


@pytest.fixture(scope="session")
def idle_sequence():
    """12 frames of a person standing quietly, 320 x 240, with sensor noise."""
    return make_sequence("idle", 12, seed=2)[0]


@pytest.fixture(scope="session")
def wave_sequence():
    """36 frames of a person waving, 320 x 240, with sensor noise."""
    return make_sequence("wave", 36, seed=3)[0]


@pytest.fixture(scope="session")
def clean_idle():
    """One noise-free frame of a standing person, 320 x 240, no surroundings."""
    seq, model, joints = make_sequence("idle", 1, seed=4, noise=False, environment="none")
    return seq, model, joints


def mpjpe(est: np.ndarray, gt: np.ndarray) -> float:
    """Mean per-joint position error (metres) over finite estimates."""
    e = np.linalg.norm(np.asarray(est) - np.asarray(gt), axis=-1)
    return float(np.nanmean(e))
