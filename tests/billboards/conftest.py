"""Fixtures of the billboard tests (the scene itself is built in ``planar_scene.py``)."""

from __future__ import annotations

import pytest

from tests.billboards.planar_scene import PlanarScene, make_planar_scene


@pytest.fixture(scope="session")
def planar_scene() -> PlanarScene:
    return make_planar_scene()
