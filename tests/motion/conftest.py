"""Fixtures shared by the motion tests: real-data location and body proportions."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from toolkit.anthropometry.proportions import BodyProportions

REPO_ROOT = Path(__file__).resolve().parents[2]


def realdata_root() -> Path:
    """``$TOOLKIT_REALDATA`` or ``../shared/realdata`` next to the repository."""
    env = os.environ.get("TOOLKIT_REALDATA")
    return Path(env) if env else REPO_ROOT.parent / "shared" / "realdata"


@pytest.fixture
def cmu_dir() -> Path:
    root = realdata_root() / "cmu_mocap"
    if not (root / "01_01.bvh").is_file():
        pytest.skip(f"CMU motion-capture data not found at {root}")
    return root


@pytest.fixture
def person() -> BodyProportions:
    """A person of 1.75 m with individual segment variations."""
    return BodyProportions.sample(1.75, rng=3)
