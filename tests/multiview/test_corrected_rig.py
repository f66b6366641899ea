"""Stage 1's offsets as corrected cameras (issue 16 item 3: one offset convention)."""

from __future__ import annotations

import numpy as np
import pytest

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.multiview import corrected_rig, fit_offsets

#: Stage-1 offsets of the test, pixels (x right, y down), one row per camera.
OFFSETS = np.array([[2.5, -1.0], [np.nan, np.nan], [-4.0, 3.5]])


def _rig(dist=np.zeros(5)) -> Rig:
    cams = [Camera.look_at(f"c{i}", [4 * np.cos(a), 4 * np.sin(a), 1.5], [0, 0, 1], size=(640, 360), fov_x_deg=50.0)
            for i, a in enumerate((0.2, 1.8, 3.9))]
    return Rig(tuple(c.replace(dist=np.asarray(dist, float)) for c in cams))


@pytest.mark.parametrize("dist", [np.zeros(5), np.array([-0.12, 0.03, 0.001, -0.002, 0.0])])
def test_points_appear_at_the_projection_minus_the_offset(dist):
    """A point appears in view i at ``rig[i].project(X) - offsets[i]``; a NaN offset leaves the camera."""
    rig = _rig(dist)
    X = np.random.default_rng(3).normal([0, 0, 1], 0.3, (20, 3))
    fixed = corrected_rig(rig, OFFSETS)
    assert fixed.names == rig.names
    for i, (c, f) in enumerate(zip(rig, fixed)):
        want = c.project(X) - np.nan_to_num(OFFSETS[i])
        np.testing.assert_allclose(f.project(X), want, atol=1e-9)
        np.testing.assert_array_equal(f.cam_from_world, c.cam_from_world)
        assert np.array_equal(f.K, c.K) == (i == 1)


def test_fit_offsets_then_corrected_cameras_meet_the_image():
    """Stage 1's offsets of a miscalibrated rig give cameras whose projections are where the joints are."""
    rig = _rig()
    err = np.array([[5.0, -4.0], [-3.0, 6.0], [2.0, 3.0]])  # the images sit at measured projection + err
    X = np.random.default_rng(5).normal([0, 0, 1], 0.3, (14, 3))
    seen = np.stack([c.project(X) + e for c, e in zip(rig, err)])
    fit = fit_offsets(seen, rig)
    assert fit.success
    fixed = corrected_rig(rig, fit.offsets)
    for i, c in enumerate(fixed):
        assert np.abs(c.project(fit.joints3d) - seen[i]).max() < 1.0  # offsets' gauge and prior: ~ a pixel


def test_bad_offsets_are_refused():
    with pytest.raises(InputError, match="corrected_rig"):
        corrected_rig(_rig(), np.zeros((2, 2)))
