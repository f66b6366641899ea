"""Fixtures of the foreground tests (helpers live in foreground_scenes.py)."""

from __future__ import annotations

import pytest
from foreground_scenes import moving_figure_video


@pytest.fixture
def figure_video():
    return moving_figure_video(seed=3)
