"""A small Pose2Sim-like trial made on the fly: tiny videos, OpenPose JSON files, a calibration."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from toolkit.cameras import Camera, Rig
from toolkit.io import write_calibration, write_video

#: Frame size of the tiny videos (width, height): even, as the mp4v encoder needs.
VIDEO_SIZE = (64, 48)
FPS = 25.0


def tiny_rig(n_cams: int = 3, size=VIDEO_SIZE) -> Rig:
    """Cameras ``cam_01`` ... on a circle, 4 m from the origin, looking at (0, 0, 1)."""
    return Rig(tuple(Camera.look_at(f"cam_{i + 1:02d}", [4 * np.cos(a), 4 * np.sin(a), 1.5], [0, 0, 1],
                                    size=size, focal_px=60.0)
                     for i, a in enumerate(np.linspace(0, 2 * np.pi, n_cams, endpoint=False))))


def make_trial(root: Path, *, n_cams: int = 3, n_frames=4, video_size=VIDEO_SIZE, calib_size=VIDEO_SIZE,
               video_names=None, pose_names=None, with_calibration=True, pose_folders=("pose",)) -> Path:
    """``root/Session/P/Trial`` with ``videos/``, the keypoint folders and ``Session/S00_Calibration``.

    ``n_frames`` is one count or one per camera (videos and keypoints alike); videos are
    ``cam01.mp4`` ... and keypoint folders ``cam01_json`` ... unless named.  Returns the trial folder.
    """
    session = root / "Session"
    trial = session / "P00" / "T01"
    counts = [n_frames] * n_cams if np.isscalar(n_frames) else list(n_frames)
    video_names = video_names or [f"cam{i + 1:02d}.mp4" for i in range(n_cams)]
    pose_names = pose_names or [f"cam{i + 1:02d}_json" for i in range(n_cams)]
    if with_calibration:
        write_calibration(session / "S00_Calibration" / "Calib_test.toml", tiny_rig(n_cams, calib_size))
    (trial / "videos").mkdir(parents=True)
    w, h = video_size
    for c, (name, n) in enumerate(zip(video_names, counts)):
        frames = [np.full((h, w, 3), 40 * c + 25 * t, np.uint8) for t in range(n)]
        write_video(trial / "videos" / name, frames, FPS)
    for folder in pose_folders:
        for c, (name, n) in enumerate(zip(pose_names, counts)):
            d = trial / folder / name
            d.mkdir(parents=True)
            for t in range(n):
                kp = np.zeros((25, 3))
                kp[:, :2] = [w / 2 + c, h / 2 + t]
                kp[:, 2] = 0.9
                data = {"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": kp.ravel().tolist()}]}
                (d / f"{name.split('_')[0]}.{t:04d}.json").write_text(json.dumps(data))
    return trial
