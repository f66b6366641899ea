"""A dataset at another image resolution: videos, calibration, keypoints and masks resized together.

Near cameras in full HD see a person 1000-1500 px tall (the Pose2Sim demo: portrait
1080x1920 at 2-3 m); every stage's cost grows with the subject's pixel count while
its accuracy does not need more than a few hundred pixels.  :func:`resample_dataset`
writes a copy at ``factor`` times the resolution: frames resized with area
averaging, cameras by :meth:`toolkit.cameras.Camera.scaled` (the pixel-centre
convention kept), OpenPose keypoints' pixel coordinates scaled, masks and clean
plates resized.  Ground truth is not copied (scale the synthetic scene instead).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np

from toolkit.errors import InputError

__all__ = ["resample_dataset"]

#: OpenPose JSON keys holding (x, y, c) triples in pixels.
_OPENPOSE_KEYS = ("pose_keypoints_2d", "face_keypoints_2d", "hand_left_keypoints_2d", "hand_right_keypoints_2d")


def _scale_openpose(data, factor: float, where: str):
    if not isinstance(data, dict) or not isinstance(data.get("people"), list):
        raise InputError(where, "an OpenPose JSON object with a 'people' list (only OpenPose keypoints are "
                                "resampled)", type(data).__name__)
    for p in data["people"]:
        for k in _OPENPOSE_KEYS:
            v = p.get(k) if isinstance(p, dict) else None
            if isinstance(v, list) and len(v) % 3 == 0:
                a = np.asarray(v, float).reshape(-1, 3)
                seen = a[:, 2] > 0
                a[seen, :2] = (a[seen, :2] + 0.5) * factor - 0.5
                p[k] = [float(x) for x in a.ravel()]
    return data


def resample_dataset(src, dst: str | os.PathLike, factor: float, max_frames: int | None = None):
    """Write ``src`` (a :class:`toolkit.io.Dataset`) at ``factor`` times its resolution into ``dst``.

    Parameters
    ----------
    src : toolkit.io.Dataset
    dst : path-like
        New dataset folder (must not hold a dataset already).
    factor : float
        In (0, 1] (e.g. 0.5 halves width and height).
    max_frames : int, optional
        Keep only the first frames.

    Returns
    -------
    toolkit.io.Dataset
        The new dataset, opened.

    Raises
    ------
    InputError
        A factor outside (0, 1], an existing ``dst/calibration.toml``, keypoints that are not OpenPose JSON.
    """
    from toolkit.cameras import Rig
    from toolkit.io.atomic import atomic_write_png, atomic_write_text
    from toolkit.io.dataset import Dataset
    from toolkit.io.frames import frame_filename
    from toolkit.io.writer import DatasetWriter

    if not 0 < factor <= 1:
        raise InputError("factor", "a scale in (0, 1]", repr(factor))
    dst = Path(dst)
    if (dst / "calibration.toml").exists():
        raise InputError(str(dst), "a new folder", "it holds a dataset already")
    n = src.frames_to_process(max_frames)
    rig = Rig(tuple(c.scaled(factor) for c in src.rig))

    def resize(img, cam, interp):
        return cv2.resize(np.asarray(img), tuple(cam.size), interpolation=interp)

    with DatasetWriter(dst, src.fps) as w:
        w.write_calibration(rig)
        for cam, new in zip(src.rig, rig):
            for t in range(n):
                w.write_frame(new.name, t, resize(src.frame(cam.name, t), new, cv2.INTER_AREA))
            plate = src.background(cam.name)
            if plate is not None:
                atomic_write_png(dst / "background" / f"{new.name}.png", resize(plate, new, cv2.INTER_AREA))
    for cam, new in zip(src.rig, rig):
        if src.has_masks:
            for t in range(n):
                m = src.mask(cam.name, t)
                if m is not None:
                    atomic_write_png(dst / "masks" / new.name / frame_filename(t),
                                     (resize(m.astype(np.uint8) * 255, new, cv2.INTER_AREA) >= 128).astype(np.uint8)
                                     * 255)
        kdir = src.keypoint_dir(cam.name) if src.has_keypoints else None
        if kdir is not None:
            from toolkit.io.openpose import frame_files

            for f, num in zip(*frame_files(kdir, "keypoint JSON files, one per frame")):
                if int(num) >= n:
                    continue
                try:
                    data = json.loads(Path(f).read_text())
                except ValueError as e:
                    raise InputError(str(f), "a JSON file", f"unreadable: {e}")
                atomic_write_text(dst / "keypoints" / new.name / Path(f).name,
                                  json.dumps(_scale_openpose(data, factor, str(f))))
    if (Path(src.root) / "import.json").exists():
        info = json.loads((Path(src.root) / "import.json").read_text())
        info["resampled"] = {"from": str(Path(src.root).resolve()), "factor": factor, "frames": n}
        atomic_write_text(dst / "import.json", json.dumps(info, indent=2) + "\n")
    return Dataset.open(dst)
