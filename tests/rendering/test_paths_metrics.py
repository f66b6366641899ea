import numpy as np
import pytest

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.rendering import birds_eye, interpolate_cameras, orbit_path, psnr, source_path, ssim

#: Pose agreement of interpolated cameras with their end points.
POSE_TOL = 1e-9


def _rig():
    a = Camera.look_at("a", [5.0, 0.0, 2.0], [0.0, 0.0, 1.0], size=(64, 48), focal_px=80)
    b = Camera.look_at("b", [0.0, 5.0, 2.5], [0.0, 0.0, 1.0], size=(64, 48), focal_px=100)
    return Rig((a, b))


def test_orbit_looks_at_target_at_constant_radius():
    target = np.array([1.0, 2.0, 1.0])
    cams = orbit_path(target, 8, radius_m=4.0, height_m=1.5, size=(64, 48), focal_px=50)
    assert len(cams) == 8
    for c in cams:
        assert abs(np.linalg.norm(c.center[:2] - target[:2]) - 4.0) < 1e-9
        uv = c.project(target)
        assert np.allclose(uv, [(64 - 1) / 2, (48 - 1) / 2], atol=1e-6)


def test_interpolation_hits_the_end_cameras_and_the_path_passes_all_sources():
    rig = _rig()
    a, b = rig
    for s, ref in ((0.0, a), (1.0, b)):
        c = interpolate_cameras(a, b, s)
        assert np.allclose(c.cam_from_world, ref.cam_from_world, atol=POSE_TOL)
        assert np.allclose(c.K, ref.K)
    mid = interpolate_cameras(a, b, 0.5)
    assert np.allclose(mid.center, 0.5 * (a.center + b.center))
    path = source_path(rig, 5)
    assert np.allclose(path[0].center, a.center) and np.allclose(path[-1].center, b.center)
    with pytest.raises(InputError, match="s"):
        interpolate_cameras(a, b, 1.5)


def test_birds_eye_is_above_every_camera_and_sees_the_target():
    rig = _rig()
    c = birds_eye(rig, [0.0, 0.0, 1.0])
    assert c.center[2] > rig.centers[:, 2].max()
    assert c.in_image(c.project(np.array([0.0, 0.0, 1.0])))


def test_psnr_and_ssim_known_values():
    rng = np.random.default_rng(0)
    a = rng.integers(0, 256, (32, 32, 3)).astype(np.uint8)
    assert psnr(a, a) == float("inf") and abs(ssim(a, a) - 1.0) < 1e-9
    b = np.clip(a.astype(int) + 10, 0, 255).astype(np.uint8)
    sel = a < 246
    expected = 10 * np.log10(255 ** 2 / 100.0)
    assert abs(psnr(b, a, sel.all(-1)) - expected) < 1e-9
    with pytest.raises(InputError):
        psnr(a, a[:10])


def test_subject_scores_on_hand_made_arrays():
    from toolkit.rendering import subject_scores
    from toolkit.rendering.metrics import SUBJECT_DILATION_PX

    ref = np.zeros((20, 20, 3), np.uint8)
    mask = np.zeros((20, 20), bool)
    mask[8:12, 8:12] = True  # 16 pixels; dilated by 2 px: an 8x8 square of 64 pixels
    img = ref.copy()
    img[0, 0] = 200  # far from the subject: not counted
    img[6, 6] = 40  # on the dilated border: counted (one pixel of 64, all three channels)
    alpha = mask.astype(np.float32)
    alpha[8, 8:12] = 0.5  # not above 0.5: 4 of 16 pixels uncovered
    s = subject_scores(img, ref, mask, alpha)
    assert SUBJECT_DILATION_PX == 2
    assert abs(s["psnr_subject"] - 10 * np.log10(255 ** 2 / (40 ** 2 / 64))) < 1e-9
    assert s["coverage"] == 0.75
    # uint8 opacity (255 = opaque) gives the same coverage; an empty mask gives NaN
    a8 = (mask * 255).astype(np.uint8)
    a8[8, 8:12] = 127  # 127/255 < 0.5
    assert subject_scores(img, ref, mask, a8)["coverage"] == 0.75
    empty = subject_scores(img, ref, np.zeros_like(mask), alpha)
    assert np.isnan(empty["psnr_subject"]) and np.isnan(empty["coverage"])
    assert subject_scores(ref, ref, mask, alpha)["psnr_subject"] == float("inf")
    with pytest.raises(InputError, match="alpha"):
        subject_scores(img, ref, mask, alpha[:10])
    with pytest.raises(InputError, match="gt_mask"):
        subject_scores(img, ref, mask[:10], alpha)


def test_summarise_means_and_worst_coverage():
    from toolkit.rendering.evaluation import summarise

    frames = [{"articulated": {"a": {"psnr": 20.0, "ssim": 0.5, "psnr_subject": 18.0, "coverage": 1.0},
                               "b": {"psnr": float("nan"), "ssim": float("nan"), "psnr_subject": float("nan"),
                                     "coverage": float("nan")}}},  # no subject in view b
              {"articulated": {"a": {"psnr": 30.0, "ssim": 0.7, "psnr_subject": 22.0, "coverage": 0.6}}}]
    s = summarise(frames)["articulated"]
    assert s["n"] == 2 and s["psnr"] == 25.0 and abs(s["ssim"] - 0.6) < 1e-12
    assert s["psnr_subject"] == 20.0 and abs(s["coverage"] - 0.8) < 1e-12 and s["coverage_min"] == 0.6
