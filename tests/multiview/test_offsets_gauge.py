"""The offsets' gauge with near (studio) cameras: offsets must not move the body (issue 13).

Four cameras 4 m from the subject all around it (the zoo's studio ring), the
true calibration, and 2D joints with independent errors of a few pixels (as
the silhouette database's candidates have).  Without the gauge prior the
offsets of every view drifted the same way by several pixels and moved the
3D body by centimetres; with it they stay small and the joints stay where the
rays put them.
"""

from __future__ import annotations

import numpy as np

from tests.multiview.multiview_scenes import walking_poses
from toolkit.cameras import Camera, Rig
from toolkit.multiview import MultiViewConfig
from toolkit.multiview.offsets import fit_offsets

#: 2D joint error of the test poses, pixels (the database's candidates are off by 2-5 px at 270 px).
JOINT_NOISE_PX = 3.0
#: Bounds with the default gauge prior (measured over 8 frames: mean |offset| 0.32-0.66 px,
#: MPJPE 14.6-20.2 mm) ...
MAX_MEAN_OFFSET_PX, MAX_MPJPE_M = 1.5, 0.030
#: ... and how much worse it was without it (measured: mean |offset| 2.35 px against 0.48,
#: MPJPE 29.1 mm against 16.7, up to 50.7 mm).
MIN_DRIFT_WITHOUT_PX, MIN_MPJPE_GAIN_M = 1.0, 0.006


def studio_ring(n_cams: int = 4, distance: float = 4.0) -> Rig:
    cams = []
    for i in range(n_cams):
        a = 2 * np.pi * i / n_cams + 0.3
        eye = [distance * np.cos(a), distance * np.sin(a), 1.6 + 0.3 * (i % 2)]
        cams.append(Camera.look_at(f"cam{i}", eye, [0, 0, 0.95], size=(960, 540), fov_x_deg=65.0))
    return Rig(tuple(cams))


def test_offsets_keep_the_body_in_place_with_near_cameras():
    rng = np.random.default_rng(13)
    rig = studio_ring()
    poses = walking_poses(rng, 8)
    drift_with, drift_without, errors, errors_without = [], [], [], []
    for X in poses:
        p2 = np.stack([cam.project(X) for cam in rig]) + rng.normal(0, JOINT_NOISE_PX, (len(rig), len(X), 2))
        fit = fit_offsets(p2, rig)
        loose = fit_offsets(p2, rig, MultiViewConfig(gauge_prior_px=np.inf))
        drift_with.append(np.abs(fit.offsets).mean())
        drift_without.append(np.abs(loose.offsets).mean())
        errors.append(np.nanmean(np.linalg.norm(fit.joints3d - X, axis=-1)))
        errors_without.append(np.nanmean(np.linalg.norm(loose.joints3d - X, axis=-1)))
    assert max(drift_with) <= MAX_MEAN_OFFSET_PX, f"mean |offset| {np.round(drift_with, 2)}"
    assert max(errors) <= MAX_MPJPE_M, f"MPJPE {np.round(errors, 3)} m"
    assert np.mean(drift_without) - np.mean(drift_with) >= MIN_DRIFT_WITHOUT_PX, \
        f"without the gauge prior {np.round(drift_without, 2)}, with it {np.round(drift_with, 2)}"
    assert np.mean(errors_without) - np.mean(errors) >= MIN_MPJPE_GAIN_M
