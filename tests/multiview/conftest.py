"""Fixtures of the multiview tests (helpers live in multiview_scenes.py)."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def rng():
    return np.random.default_rng(20240607)
