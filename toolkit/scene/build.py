"""Building a run's scene model from a dataset's source videos.

:func:`build_scene_model` samples each source camera's frames evenly over the
video, leaves out the people (:func:`_exclusions`: the dataset's keypoints of
every person when it has them, else the run's own foreground stage), estimates
each camera's empty view (:func:`toolkit.scene.estimate_background`) and fits
the proxy (:func:`toolkit.scene.fit_proxy`).
"""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.scene.backgrounds import SAMPLES, estimate_background, people_exclusion
from toolkit.scene.fit import fit_proxy
from toolkit.scene.model import SceneModel

__all__ = ["build_scene_model", "SILHOUETTE_GROW"]


#: Silhouettes of the foreground stage are grown by this share of the image height before being left out.
SILHOUETTE_GROW = 0.01


def _exclusions(dataset, camera: str, frames: list, images: list, size: tuple, foreground=None) -> tuple[list, str]:
    """Per sampled frame, the pixels where the camera's people may be, and where that came from.

    From the first of: the dataset's keypoints of that camera (every person detected,
    :func:`people_exclusion`); the run's own foreground stage (the background model stage 1
    uses: a source camera's clean plate when the dataset has one, else one learned over its
    video), its raw silhouettes grown by :data:`SILHOUETTE_GROW` of the image height.
    """
    kp = dataset.keypoint_dir(camera) if dataset.has_keypoints else None
    if kp is not None:
        from toolkit.io.keypoint_files import read_camera_detections

        try:
            det = read_camera_detections(kp)
        except InputError:
            det = None
        if det is not None:
            at = {int(f): i for i, f in enumerate(det.frames)}
            return [people_exclusion(det.people[at[t]], size) if t in at else None for t in frames], "keypoints"
    from toolkit.foreground import ForegroundConfig, ForegroundExtractor

    plate = dataset.background(camera)
    ex = ForegroundExtractor(foreground or ForegroundConfig()).fit([plate] if plate is not None else images)
    r = max(1, int(round(SILHOUETTE_GROW * size[1])))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    out = [cv2.dilate(ex.raw_mask(im).astype(np.uint8), kernel) > 0 for im in images]
    return out, "foreground"


def build_scene_model(dataset, rig: Rig, frames: int, samples: int = SAMPLES, ground_z: float = 0.0,
                      foreground=None, log=None) -> SceneModel:
    """Estimate the scene model of a dataset's source cameras from their own videos.

    Parameters
    ----------
    dataset : toolkit.io.Dataset
    rig : Rig
        The source cameras as the run uses them (a held-out camera left out: none of its
        pixels is read).
    frames : int
        The run's frames ``0 .. frames-1``; ``samples`` of them are read, evenly spread.
    samples : int
    ground_z : float
        Height of the ground plane, metres.
    foreground : toolkit.foreground.ForegroundConfig, optional
        The run's foreground stage (finds the people where there are no keypoints).
    log : callable, optional

    Returns
    -------
    SceneModel
        ``evidence["people_from"]`` says per camera where the people left out came from.
    """
    n = max(1, int(frames))
    idx = sorted(set(np.linspace(0, n - 1, min(samples, n)).round().astype(int).tolist()))
    want = set(idx)
    bgs, how = {}, {}
    for cam in rig:
        imgs = []
        for t, f in enumerate(dataset.frames(cam.name)):
            if t in want:
                imgs.append(f)
            if t >= idx[-1]:
                break
        masks, how[cam.name] = _exclusions(dataset, cam.name, idx, imgs, cam.size, foreground)
        bgs[cam.name] = estimate_background(imgs, masks)
    proxy, evidence = fit_proxy(rig, bgs, ground_z=ground_z, log=log)
    return SceneModel(rig, bgs, proxy, {**evidence, "people_from": how, "frames_sampled": idx})
