"""Fixtures shared by the io tests: real-data location and small synthetic rigs."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.cameras import Camera, Rig

REPO_ROOT = Path(__file__).resolve().parents[2]


def realdata_root() -> Path:
    """``$TOOLKIT_REALDATA`` or ``../shared/realdata`` next to the repository."""
    env = os.environ.get("TOOLKIT_REALDATA")
    return Path(env) if env else REPO_ROOT.parent / "shared" / "realdata"


@pytest.fixture
def pose2sim_demo() -> Path:
    root = realdata_root() / "pose2sim_demo"
    if not root.is_dir():
        pytest.skip(f"real data not found at {root}")
    return root


def random_rig(
    rng: np.random.Generator, n_cams: int = 3, size=(64, 48), dist_lengths=(4, 5, 8), names=None
) -> Rig:
    """Cameras on a circle of radius 3-5 m around the origin looking at a point near (0, 0, 1).

    The focal length (40-80 px at 64 px wide) scales with the width, so that every size gives the same
    fields of view (a 1280-px image with a 60-px focal length would be a 170-degree pinhole camera, which
    the calibration readers refuse).
    """
    cams = []
    for i in range(n_cams):
        a = 2 * np.pi * i / n_cams + rng.uniform(-0.3, 0.3)
        r = rng.uniform(3, 5)
        eye = [r * np.cos(a), r * np.sin(a), rng.uniform(1, 2.5)]
        target = [rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), rng.uniform(0.8, 1.2)]
        n = dist_lengths[i % len(dist_lengths)]
        dist = rng.normal(0, [0.05, 0.01, 1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4][:n])
        cam = Camera.look_at(
            names[i] if names else f"cam{i:02d}",
            eye,
            target,
            size=size,
            focal_px=rng.uniform(40, 80) * size[0] / 64,
            dist=dist,
        )
        K = cam.K.copy()
        K[0, 2] += rng.uniform(-2, 2)
        K[1, 2] += rng.uniform(-2, 2)
        K[1, 1] *= rng.uniform(0.98, 1.02)
        cams.append(cam.replace(K=K))
    return Rig(tuple(cams))


def assert_rigs_equal(a: Rig, b: Rig, tol: float) -> None:
    assert a.names == b.names
    for ca, cb in zip(a, b):
        assert ca.size == cb.size
        np.testing.assert_allclose(cb.K, ca.K, rtol=0, atol=tol)
        assert ca.dist.shape == cb.dist.shape
        np.testing.assert_allclose(cb.dist, ca.dist, rtol=0, atol=tol)
        np.testing.assert_allclose(cb.cam_from_world, ca.cam_from_world, rtol=0, atol=tol)


@pytest.fixture
def make_rig():
    """The :func:`random_rig` factory (fixtures avoid importing ``conftest`` by name)."""
    return random_rig


@pytest.fixture
def rigs_equal():
    """The :func:`assert_rigs_equal` check."""
    return assert_rigs_equal
