"""Synchronisation by ray geometry: late cameras of a synthetic rig found from their 2D keypoints."""

from __future__ import annotations

import json

import numpy as np
import pytest

from toolkit.anthropometry import BodyProportions
from toolkit.cameras import Camera
from toolkit.detection import sync
from toolkit.detection.sync import find_offsets_geometric, pair_cost_curves
from toolkit.errors import InputError
from toolkit.motion import generate_motion

#: The target of the synchronisation: every offset right to one frame (noise and detector bias on).
ONE_FRAME = 1
#: Frames of the synthetic capture (25 fps) and the largest offset searched.
N_FRAMES, MAX_OFFSET = 90, 20
#: Detector noise (pixels, per keypoint and frame) and bias (pixels, per camera and keypoint: two views
#: placing a joint differently), about what a 2D detector shows at this image size.
NOISE_PX, BIAS_PX = 1.0, 3.0


def _rig(rng: np.random.Generator, n_cams: int) -> dict[str, Camera]:
    """Cameras on a ring of 4-6 m around the walk, 1.2-2.5 m high, 640x480 with a 60 degree view."""
    cams = {}
    for i in range(n_cams):
        a = 2 * np.pi * i / n_cams + rng.uniform(-0.3, 0.3)
        r = rng.uniform(4.0, 6.0)
        eye = [r * np.cos(a), r * np.sin(a), rng.uniform(1.2, 2.5)]
        target = [*rng.uniform(-0.3, 0.3, 2), 1.0]
        cams[f"cam{i + 1:02d}"] = Camera.look_at(f"cam{i + 1:02d}", eye, target, size=(640, 480), fov_x_deg=60.0)
    return cams


def _walk(rng: np.random.Generator, motion: str = "walk") -> np.ndarray:
    """A person's 14 joints ``(N_FRAMES, 14, 3)``, metres, centred on the origin."""
    joints = generate_motion(motion, BodyProportions.from_height(1.75), N_FRAMES, 25.0, rng=rng)
    centre = joints[:, :, :2].reshape(-1, 2).mean(0)
    return joints - [centre[0], centre[1], 0.0]


def _detections(cams: dict, people: list[np.ndarray], late: dict[str, int], rng: np.random.Generator,
                noise_px: float = NOISE_PX, bias_px: float = BIAS_PX) -> dict[str, list[list[np.ndarray]]]:
    """Per camera, per frame the people's ``(14, 3)`` keypoints (pixels, confidence 1), the first
    ``late[c]`` frames cut off (the camera started that late), people in a random order per frame."""
    out = {}
    for name, cam in cams.items():
        bias = [rng.normal(0, bias_px, (14, 2)) for _ in people]
        frames = []
        for t in range(late.get(name, 0), N_FRAMES):
            seen = [np.column_stack([cam.project(p[t]) + b + rng.normal(0, noise_px, (14, 2)), np.ones(14)])
                    for p, b in zip(people, bias)]
            frames.append([seen[i] for i in rng.permutation(len(seen))])
        out[name] = frames
    return out


def _late(rng: np.random.Generator, names: list[str]) -> dict[str, int]:
    """Two cameras started 4-14 frames late (as the real-data benchmark), the others on time."""
    late = {n: 0 for n in names}
    for n in rng.choice(names, size=2, replace=False):
        late[str(n)] = int(rng.integers(4, 15))
    return late


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_two_late_cameras_are_found_within_one_frame(seed):
    rng = np.random.default_rng(seed)
    cams = _rig(rng, 4)
    late = _late(rng, list(cams))
    res = find_offsets_geometric(_detections(cams, [_walk(rng)], late, rng), cams, max_offset=MAX_OFFSET)
    errors = {n: res.offsets[n] - late[n] for n in cams}
    assert max(map(abs, errors.values())) <= ONE_FRAME, (late, res.offsets, res.confidence)
    assert all(res.trusted.values()), res.confidence


def test_exact_without_noise_and_a_synchronised_rig_stays_at_zero():
    rng = np.random.default_rng(3)
    cams = _rig(rng, 4)
    walk = _walk(rng)
    late = {"cam01": 0, "cam02": 9, "cam03": 0, "cam04": 5}
    clean = find_offsets_geometric(_detections(cams, [walk], late, rng, 0.0, 0.0), cams, max_offset=MAX_OFFSET)
    assert clean.offsets == late
    in_sync = find_offsets_geometric(_detections(cams, [walk], {}, rng), cams, max_offset=MAX_OFFSET)
    assert in_sync.offsets == {n: 0 for n in cams}
    assert all(in_sync.trusted.values()), in_sync.confidence


def test_a_late_reference_camera_is_found_too():
    rng = np.random.default_rng(4)
    cams = _rig(rng, 4)
    late = {"cam01": 11, "cam02": 0, "cam03": 6, "cam04": 0}
    people = _detections(cams, [_walk(rng)], late, rng)
    for reference in cams:   # the camera held at 0 in the search does not matter
        res = find_offsets_geometric(people, cams, max_offset=MAX_OFFSET, reference=reference)
        assert max(abs(res.offsets[n] - late[n]) for n in cams) <= ONE_FRAME, (reference, res.offsets)


def test_a_bystander_standing_still_does_not_pull_the_offsets():
    # a still person's rays meet at every lag: only the moving one tells the time
    rng = np.random.default_rng(5)
    cams = _rig(rng, 4)
    walk = _walk(rng)
    still = np.repeat(_walk(rng, "idle")[:1] + [1.5, 1.5, 0.0], N_FRAMES, axis=0)
    late = {"cam01": 0, "cam02": 0, "cam03": 13, "cam04": 7}
    res = find_offsets_geometric(_detections(cams, [walk, still], late, rng), cams, max_offset=MAX_OFFSET)
    assert max(abs(res.offsets[n] - late[n]) for n in cams) <= ONE_FRAME, res.offsets


def test_pair_curves_are_least_at_the_lag_between_the_pair():
    rng = np.random.default_rng(6)
    cams = _rig(rng, 3)
    late = {"cam01": 0, "cam02": 8, "cam03": 3}
    curves = pair_cost_curves(_detections(cams, [_walk(rng)], late, rng, 0.0, 0.0), cams, max_offset=MAX_OFFSET)
    assert set(curves) == {("cam01", "cam02"), ("cam01", "cam03"), ("cam02", "cam03")}
    for (a, b), c in curves.items():
        assert c.shape == (2 * MAX_OFFSET + 1,)
        assert int(np.nanargmin(c)) - MAX_OFFSET == late[a] - late[b]


def test_coordinate_descent_agrees_with_the_exhaustive_search(monkeypatch):
    rng = np.random.default_rng(7)
    cams = _rig(rng, 5)
    late = {"cam01": 0, "cam02": 7, "cam03": 0, "cam04": 4, "cam05": 0}
    people = _detections(cams, [_walk(rng)], late, rng)
    exhaustive = find_offsets_geometric(people, cams, max_offset=8)
    monkeypatch.setattr(sync, "EXHAUSTIVE_LIMIT", 0)
    descent = find_offsets_geometric(people, cams, max_offset=8)
    assert descent.offsets == exhaustive.offsets
    assert max(abs(descent.offsets[n] - late[n]) for n in cams) <= ONE_FRAME, descent.offsets


def test_the_evidence_is_kept_as_json():
    rng = np.random.default_rng(8)
    cams = _rig(rng, 3)
    late = {"cam01": 0, "cam02": 5, "cam03": 0}
    res = find_offsets_geometric(_detections(cams, [_walk(rng)], late, rng), cams, max_offset=MAX_OFFSET)
    doc = json.loads(json.dumps(res.to_json(), allow_nan=False))
    assert doc["method"] == "rays" and doc["offsets"] == res.offsets
    assert len(doc["lags"]) == 2 * MAX_OFFSET + 1
    assert set(doc["pair_curves"]) == {"cam01|cam02", "cam01|cam03", "cam02|cam03"}
    assert all(len(c) == len(doc["lags"]) for c in [*doc["pair_curves"].values(), *doc["curves"].values()])
    # each camera's curve is least where it was put, and the confidence is how much worse two frames away is
    for n in cams:
        curve = np.array([np.inf if v is None else v for v in doc["curves"][n]])
        assert int(np.argmin(curve)) == MAX_OFFSET
        assert doc["confidence"][n] == pytest.approx((doc["second_peaks"][n] - doc["peaks"][n]) / 2, rel=1e-3)


def test_bad_input_is_named():
    rng = np.random.default_rng(9)
    cams = _rig(rng, 3)
    people = _detections(cams, [_walk(rng)], {}, rng)
    with pytest.raises(InputError, match="at least two cameras"):
        find_offsets_geometric({"cam01": people["cam01"]}, cams)
    with pytest.raises(InputError, match="none for"):
        find_offsets_geometric(people, {"cam01": cams["cam01"], "cam02": cams["cam02"]})
    with pytest.raises(InputError, match="max_offset"):
        find_offsets_geometric(people, cams, max_offset=-1)
    with pytest.raises(InputError, match="reference"):
        find_offsets_geometric(people, cams, reference="cam09")
    people["cam02"][4] = [np.zeros((10, 3))]
    with pytest.raises(InputError, match="frame 4"):
        find_offsets_geometric(people, cams)
