"""A tiny synthetic dataset generated once per test session."""

from __future__ import annotations

from pathlib import Path

import pytest

from toolkit.synthetic import generate_scene, parse_spec

TINY_SPEC = """
seed = 11
frames = 3
fps = 25
[subject]
height_m = 1.75
motion = "walk"
[cameras]
count = 2
layout = "broadcast"
resolution = [320, 180]
calibration_error_px = 4.0
[novel]
count = 1
"""


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("tiny") / "scene"
    generate_scene(parse_spec(TINY_SPEC, "tiny.toml"), out, progress=False).close()
    return out
