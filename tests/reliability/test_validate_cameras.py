"""Cameras checked against their physical range (toolkit.cameras.validate), by every calibration reader."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from toolkit.cameras import Camera, Rig
from toolkit.cameras.validate import MAX_DISTORTION_SCALE, cameras_behind, check_camera, check_rig
from toolkit.errors import InputError
from toolkit.io.calibration import read_calibration, write_calibration

REALDATA = Path(__file__).resolve().parents[2].parent / "shared" / "realdata"


def ring_rig(n_cams: int = 4, size=(640, 480), dist=None) -> Rig:
    """Cameras on a 4 m circle at 1.5 m height looking at (0, 0, 1) with a 60-degree field of view."""
    return Rig(tuple(Camera.look_at(f"cam{i}", [4 * np.cos(a), 4 * np.sin(a), 1.5], [0, 0, 1], size=size,
                                    fov_x_deg=60, dist=dist)
                     for i, a in enumerate(np.linspace(0, 2 * np.pi, n_cams, endpoint=False))))


def with_pose(rig: Rig, change) -> Rig:
    return Rig(tuple(c.replace(cam_from_world=change(c)) for c in rig))


def flipped_translation(c: Camera) -> np.ndarray:
    T = c.cam_from_world.copy()
    T[:3, 3] *= -1
    return T


def test_a_real_rig_and_strong_barrel_distortion_pass():
    rig = ring_rig(dist=[-0.3, 0.1, 0.001, -0.001, 0.0])   # a wide-angle lens as calibrated in practice
    assert check_rig(rig) is rig


@pytest.mark.parametrize("cx,cy", [(1e9, 239.5), (319.5, -3.0), (700.0, 239.5)])
def test_principal_point_outside_the_image(cx, cy):
    cam = ring_rig()[0]
    K = cam.K.copy()
    K[0, 2], K[1, 2] = cx, cy
    with pytest.raises(InputError, match="principal point") as e:
        check_camera(cam.replace(K=K), "calib.toml: [cam0]")
    assert e.value.where == "calib.toml: [cam0].matrix" and f"{cx:.6g}" in e.value.found


@pytest.mark.parametrize("dist", [[1e6, 0, 0, 0, 0], [-1e6, 0, 0, 0, 0], [0, 0, 1e6, 0, 0], [0, 0, 0, -1e6, 0],
                                  [-2.0, 0, 0, 0, 0]])
def test_distortion_that_folds_or_explodes_the_image(dist):
    with pytest.raises(InputError, match="monotonic") as e:
        check_camera(ring_rig(dist=dist)[0], "c")
    assert e.value.where == "c.distortions"


def test_distortion_scale_bound_is_the_named_constant():
    # k1 > 0 keeps the image monotonic, but past the bound it squeezes the field of view to nothing
    cam = ring_rig()[0]
    r_edge = np.hypot(320, 240) / cam.K[0, 0]
    ok = 0.5 * (MAX_DISTORTION_SCALE - 1) / r_edge ** 2     # the edge reached at half the scale bound
    check_camera(cam.replace(dist=[ok, 0, 0, 0, 0]))
    with pytest.raises(InputError, match="stretch"):
        check_camera(cam.replace(dist=[4 * (MAX_DISTORTION_SCALE ** 3) / r_edge ** 2, 0, 0, 0, 0]))


def test_focal_length_and_size_bounds():
    cam = ring_rig()[0]
    with pytest.raises(InputError, match="field of view"):
        check_camera(cam.replace(K=np.diag([1e9, 1e9, 1.0]) + np.array([[0, 0, 319.5], [0, 0, 239.5], [0, 0, 0]])))
    with pytest.raises(InputError, match="pixels a side"):
        check_camera(cam.replace(size=(100000, 480), K=cam.K))


@pytest.mark.parametrize("n_cams", [2, 3, 4, 8])
def test_flipped_translation(n_cams):
    bad = with_pose(ring_rig(n_cams=n_cams), flipped_translation)
    with pytest.raises(InputError, match="look at together") as e:
        check_rig(bad, "calib.toml")
    assert e.value.where == "calib.toml: rotation/translation" and "behind" in e.value.found


def test_inverse_pose_of_a_real_rig():
    # the Pose2Sim demo's Qualisys rig written as world_from_cam: the point its axes meet at falls out
    # of the pictures (a level ring's axes would become parallel and say nothing: the check on the
    # triangulated joints catches that case, tests/reliability/test_no_output_lost.py)
    files = sorted(REALDATA.glob("pose2sim_demo/**/Calib*.qca.txt"))
    if not files:
        pytest.skip(f"real data not found under {REALDATA}")
    rig = read_calibration(files[0])
    with pytest.raises(InputError, match="outside the image"):
        check_rig(with_pose(rig, lambda c: c.world_from_cam))


def test_parallel_rig_is_not_judged():
    # two cameras side by side looking the same way (a stereo pair): nothing says where the scene is
    cams = tuple(Camera.look_at(f"c{i}", [x, -4, 1.5], [x, 0, 1.5], size=(640, 480), fov_x_deg=60)
                 for i, x in enumerate((0.0, 0.3)))
    check_rig(Rig(cams))
    check_rig(with_pose(Rig(cams), flipped_translation))


def test_points_behind_the_cameras_that_see_them():
    # a level ring written as world_from_cam passes check_rig (its axes become parallel); its joints do not
    rig = ring_rig()
    joints = np.array([[0.0, 0.0, 1.0], [0.2, 0.1, 1.6], [np.nan, 0.0, 1.0]])   # (J, 3) metres; NaN: missing
    seen = np.ones((len(rig), len(joints)), bool)
    assert cameras_behind(rig, joints, seen) == []
    mirrored = 2 * rig[0].center - joints                                        # behind cam0, seen by all
    assert cameras_behind(rig, mirrored, seen)[0] == "cam0"
    seen[0] = False                                                               # cam0 does not see them
    assert "cam0" not in cameras_behind(rig, mirrored, seen)
    with pytest.raises(InputError, match="seen"):
        cameras_behind(rig, joints, seen[:, :2])
    with pytest.raises(InputError, match="points"):
        cameras_behind(rig, joints[:, :2], seen)


@pytest.mark.parametrize("suffix", [".toml", ".yml"])
def test_calibration_readers_refuse_what_no_camera_is(tmp_path, suffix):
    """A calibration file with a principal point 1e9 px away was read (and ran to the end) before."""
    rig = ring_rig()
    K = rig[1].K.copy()
    K[0, 2] = 1e9
    bad = Rig(tuple(c.replace(K=K) if c.name == "cam1" else c for c in rig))
    path = write_calibration(tmp_path / f"calib{suffix}", bad)
    with pytest.raises(InputError, match="principal point") as e:
        read_calibration(path)
    assert str(path) in str(e.value) and "cam1" in str(e.value)
    flipped = write_calibration(tmp_path / f"flipped{suffix}", with_pose(rig, flipped_translation))
    with pytest.raises(InputError, match="behind"):
        read_calibration(flipped)
    huge = write_calibration(tmp_path / f"dist{suffix}", Rig(tuple(c.replace(dist=[-1e6, 1e6, 0, 0, 0]) for c in rig)))
    with pytest.raises(InputError, match="distortion"):
        read_calibration(huge)


def test_real_calibrations_pass():
    files = sorted(REALDATA.glob("**/*.qca.txt")) + sorted(REALDATA.glob("**/Calib*.toml"))
    if not files:
        pytest.skip(f"real data not found under {REALDATA}")
    for f in files:
        assert len(read_calibration(f)) >= 2
