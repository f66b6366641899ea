"""The trinocular camera layout (issue 18): heads of three cameras, and its spec validation."""

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.synthetic.rigs import make_rig
from toolkit.synthetic.spec import parse_spec

BASE = """seed = 1
frames = 2
fps = 25
[subject]
height_m = 1.75
motion = "wave"
[cameras]
layout = "trinocular"
resolution = [160, 120]
"""


def test_heads_of_three_cameras_within_the_baseline():
    rig = make_rig("trinocular", 6, (320, 240), 1.75, np.random.default_rng(0), baseline_m=(0.2, 0.4))
    assert len(rig) == 6
    for k in range(2):
        ref, right, up = rig[3 * k], rig[3 * k + 1], rig[3 * k + 2]
        for other in (right, up):
            b = np.linalg.norm(other.center - ref.center)
            assert 0.2 <= b <= 0.4
            assert np.allclose(other.R, ref.R)  # parallel cameras
        # right is along the reference's x axis, up against its y axis
        assert ref.R[0] @ (right.center - ref.center) > 0.19
        assert -ref.R[1] @ (up.center - ref.center) > 0.19
        d = np.linalg.norm(ref.center[:2])
        assert 2.0 <= d <= 4.0
        assert ref.project(np.array([[0.0, 0.0, 1.0]]))[0, 0] == pytest.approx(ref.width / 2, abs=ref.width / 4)


def test_spec_accepts_heads_and_baseline():
    s = parse_spec(BASE + "count = 3\nheads = 1\nbaseline_m = [0.25, 0.3]\n")
    assert (s.heads, s.baseline_m, s.camera_count) == (1, (0.25, 0.3), 3)
    assert parse_spec(BASE + "count = 6\n").heads == 2


@pytest.mark.parametrize("extra, field", [
    ("count = 4\n", "cameras.count"),
    ("count = 6\nheads = 1\n", "cameras.count"),
    ("count = 3\nbaseline_m = [0.1, 0.3]\n", "cameras.baseline_m"),
    ("count = 3\nbaseline_m = 0.5\n", "cameras.baseline_m"),
    ("count = 3\nheads = 0\n", "cameras.heads"),
    ("count = 3\nheads = \"one\"\n", "cameras.heads"),
])
def test_spec_rejects_bad_trinocular_fields(extra, field):
    with pytest.raises(InputError, match=field):
        parse_spec(BASE + extra)


def test_heads_only_for_trinocular():
    with pytest.raises(InputError, match="cameras.heads"):
        parse_spec(BASE.replace('"trinocular"', '"studio"') + "count = 3\nheads = 1\n")


def test_spacing_is_between_heads():
    s = parse_spec(BASE + "count = 6\nspacing_deg = [80, 100]\n")
    rig = make_rig("trinocular", 6, (160, 120), 1.75, np.random.default_rng(2), spacing_deg=s.spacing_deg)
    a0, a1 = (np.degrees(np.arctan2(rig[k].center[1], rig[k].center[0])) for k in (0, 3))
    assert 79 <= (a1 - a0) % 360 <= 101
    with pytest.raises(InputError, match="spacing_deg"):
        parse_spec(BASE + "count = 9\nspacing_deg = [190, 200]\n")
