"""Building a run's scene model from a dataset's source videos.

:func:`build_scene_model` samples each source camera's frames evenly over the
video, leaves out the people (:func:`_exclusions`: the dataset's keypoints of
every person, and every person the cameras agree on projected from 3D, when it
has keypoints; else the run's own foreground stage), estimates
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


def _detections(dataset, rig: Rig) -> dict | None:
    """Per camera of ``rig``, its detections by frame ``{frame: (P, K, 3)}`` (None without keypoints)."""
    if not dataset.has_keypoints:
        return None
    from toolkit.io.keypoint_files import read_camera_detections

    out = {}
    for cam in rig:
        kp = dataset.keypoint_dir(cam.name)
        if kp is None:
            return None
        try:
            det = read_camera_detections(kp)
        except InputError:
            return None
        out[cam.name] = {int(f): np.asarray(p, float) for f, p in zip(det.frames, det.people)}
    return out


def _people_in_3d(detections: dict, rig: Rig, frames: list) -> dict:
    """Per sampled frame, every person the cameras agree on, their keypoints in 3D ``(K, 3)`` (metres)."""
    from toolkit.multiview.association import associate_frame

    K = next((p.shape[1] for d in detections.values() for p in d.values() if p.ndim == 3 and p.shape[1]), 0)
    out: dict = {}
    if K == 0:  # nobody detected anywhere
        return out
    for t in frames:
        views = [detections[c.name].get(t, np.zeros((0, K, 3))).reshape(-1, K, 3) for c in rig]
        try:
            fa = associate_frame(views, rig)
        except InputError:
            continue
        out[t] = [X for X in fa.joints3d if np.isfinite(X).all(-1).sum() >= 3]
    return out


def _exclusions(dataset, camera, frames: list, images: list, foreground=None, detections=None,
                people3d=None) -> tuple[list, str]:
    """Per sampled frame, the pixels where the camera's people may be, and where that came from.

    With keypoints: every person this camera detected, and every person the cameras agree
    on projected into it (so a person this camera's detector missed in a sample is still
    left out), each as its keypoints' hull grown by a quarter of its height
    (:func:`people_exclusion`).  Without: the run's own foreground stage (the background
    model stage 1 uses: a source camera's clean plate when the dataset has one, else one
    learned over its video), its raw silhouettes grown by :data:`SILHOUETTE_GROW` of the
    image height.
    """
    size = camera.size
    if detections is not None:
        out = []
        for t in frames:
            people = list(detections[camera.name].get(t, np.zeros((0, 0, 3))))
            for X in (people3d or {}).get(t, []):
                uv = camera.project(X)
                people.append(np.concatenate([uv, np.isfinite(uv).all(-1, keepdims=True).astype(float)], -1))
            out.append(people_exclusion(people, size))
        return out, "keypoints"
    from toolkit.foreground import ForegroundConfig, ForegroundExtractor

    plate = dataset.background(camera.name)
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
    detections = _detections(dataset, rig)
    people3d = _people_in_3d(detections, rig, idx) if detections is not None and len(rig) >= 2 else None
    for cam in rig:
        imgs = []
        for t, f in enumerate(dataset.frames(cam.name)):
            if t in want:
                imgs.append(f)
            if t >= idx[-1]:
                break
        masks, how[cam.name] = _exclusions(dataset, cam, idx, imgs, foreground, detections, people3d)
        bgs[cam.name] = estimate_background(imgs, masks)
    proxy, evidence = fit_proxy(rig, bgs, ground_z=ground_z, log=log)
    return SceneModel(rig, bgs, proxy, {**evidence, "people_from": how, "frames_sampled": idx})
