"""One frame of free-viewpoint video after stage 1: stages 2-4 chained (source 000 Fig. 10, steps 22-28).

Stage 1 (foreground, 2D pose, multi-view selection and offsets) runs over the
whole dataset (:func:`toolkit.silhouettes.pipeline.estimate_dataset`, or a
detector's keypoints); :class:`FrameProcessor` takes one of its frame
estimates and the silhouettes, and runs the rest:

* template fit and body-part segmentation per camera (:func:`toolkit.segmentation.segment_frame`);
* the stage-3 chain (:func:`toolkit.pipeline.stage3.optimize_frame`): seams on
  the fitted template's depth, the 3D joint search on the position score under
  anthropometric constraints, the articulated billboards;
* for comparison, the standard billboards and the visual hull.

A frame where stage 1 found no 3D pose, or a camera without a silhouette, is
not an error: the result says which views were used and why a frame is empty.
A stage-1 pose behind a camera that sees it (a calibration in the wrong
convention: :func:`toolkit.cameras.validate.cameras_behind`) is no pose either:
its frame is :data:`STATUS_BEHIND`, not drawn, and the run's summary counts it.
The frame's config and result types (:class:`~toolkit.rendering.freeviewpoint.FreeViewpointConfig`,
:class:`~toolkit.rendering.freeviewpoint.FrameResult`) stay with the renderer
that draws them.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from toolkit.cameras import Rig
from toolkit.observe import Observer, as_observer
from toolkit.rendering.freeviewpoint import (STATUS_NO_POSE, STATUS_NO_VIEWS, STATUS_OK, FrameResult,
                                             FreeViewpointConfig)
from toolkit.skeleton import SKELETON_14

#: Status of a frame whose stage-1 joints lie behind a source camera that sees them (no camera can).
STATUS_BEHIND = "3D pose behind a camera that sees it (calibration in the wrong convention?)"


class FrameProcessor:
    """Runs stages 2-3 and builds the billboards for one frame at a time.

    Parameters
    ----------
    rig : Rig
        The source cameras stage 1 used (measured, or refined on field lines);
        each frame corrects them by its stage-1 offsets
        (:func:`toolkit.multiview.corrected_rig`) before anything looks at an image.
    config : FreeViewpointConfig
    observer : Observer, optional
    """

    def __init__(self, rig: Rig, config: FreeViewpointConfig = FreeViewpointConfig(),
                 observer: Observer | None = None):
        from toolkit.anthropometry import AnthropometricConstraints
        from toolkit.template import Template

        self.rig = rig
        self.config = config
        self.observer = as_observer(observer)
        self.template = Template(config.template_height_m)
        self.constraints = AnthropometricConstraints()

    def process(self, frame: int, images: dict, masks: list, estimate, plates: dict | None = None) -> FrameResult:
        """Process one frame.

        Stages 2-3 and the billboards run on each camera's images resized so that the person is at
        most ``config.work_height_px`` tall (:mod:`toolkit.pipeline.working_scale`); the result is at
        the cameras' own resolution either way.

        Parameters
        ----------
        frame : int
        images : dict of str -> ndarray (H, W, 3) uint8
            Source images (cameras without a frame may be missing).
        masks : list of (ndarray (H, W) bool or None)
            Stage-1 silhouettes, rig order.
        estimate : toolkit.silhouettes.pipeline.FrameEstimate
        plates : dict of str -> ndarray (H, W, 3) uint8, optional
            The background alone per camera (clean plates).  Segmentation then
            corrects the silhouette's border against it and fills parts of a kit
            that looks like the background (:mod:`toolkit.segmentation.plate`;
            zoo part mIoU from stage-1 silhouettes 0.734 -> 0.783 median,
            docs/stage2_segmentation.md).  Used unless ``config.use_plates`` is False.

        Returns
        -------
        FrameResult
            ``timings["segmentation"]`` includes the seams.
        """
        from toolkit.cameras.validate import cameras_behind
        from toolkit.multiview import corrected_rig
        from toolkit.pipeline.working_scale import WorkingFrame, working_scales

        obs = self.observer
        names = self.rig.names
        timings: dict = {}
        J1 = np.asarray(estimate.joints3d, float)
        rig = corrected_rig(self.rig, estimate.offsets)  # where the joints appear in each image
        empty = {c: np.zeros(self.rig[c].size[::-1], np.uint8) for c in names}
        if not estimate.ok or not np.isfinite(J1).all():
            obs.report("text", name="free_viewpoint/status", text=f"frame {frame}: {STATUS_NO_POSE}", frame=frame)
            return FrameResult(frame, STATUS_NO_POSE, J1, np.full_like(J1, np.nan), rig, empty, timings=timings)
        behind = cameras_behind(self.rig, J1, np.isfinite(np.asarray(estimate.poses2d, float)).all(axis=-1))
        if behind:
            obs.report("text", name="free_viewpoint/status", level="WARN", frame=frame,
                       text=f"frame {frame}: {STATUS_BEHIND}: the joints lie behind {', '.join(behind)}")
            return FrameResult(frame, STATUS_BEHIND, J1, np.full_like(J1, np.nan), rig, empty, timings=timings)
        # stages 2-3 on images where the person is at most work_height_px tall (toolkit.pipeline.working_scale)
        work = WorkingFrame.of(self.rig, working_scales(self.rig, J1, self.config.work_height_px))
        if not work.scaled:
            return self._stages(frame, images, masks, J1, estimate.poses2d, rig, plates, obs)
        wrig = corrected_rig(work.rig, work.offsets(estimate.offsets))
        res = self._stages(frame, work.images(images), work.masks(masks), J1, work.points(estimate.poses2d), wrig,
                           work.images(plates), work.observer(obs),
                           supersample=work.supersample(self.config.supersample), with_hull=False)
        res = work.full_result(res, rig, masks)
        if self.config.baselines and res.ok:  # voxels cost the same at any size: carved by the full silhouettes
            from toolkit.rendering.baselines import visual_hull

            t0 = time.perf_counter()
            hull = visual_hull({c: images.get(c, np.zeros(rig[c].size[::-1] + (3,), np.uint8)) for c in names},
                               {c: res.labels[c] > 0 for c in names}, res.joints, rig)
            res.timings["visual_hull"] = time.perf_counter() - t0
            res = replace(res, hull=hull)
        return res

    def _stages(self, frame: int, images: dict, masks: list, J1: np.ndarray, poses2d: np.ndarray, rig: Rig,
                plates: dict | None, obs, supersample: int | None = None, with_hull: bool = True) -> FrameResult:
        """Stages 2-3, the billboards and the baselines of a frame with a 3D pose (see :meth:`process`);
        ``rig`` the corrected cameras the images, masks and ``poses2d`` (n_cams, 14, 2) are in;
        ``supersample`` the billboards' (default the config's); ``with_hull`` False leaves the visual hull out."""
        from toolkit.pipeline.stage3 import optimize_frame
        from toolkit.rendering.baselines import standard_billboards, visual_hull
        from toolkit.segmentation import segment_frame

        names = rig.names
        timings: dict = {}
        empty = {c: np.zeros(rig[c].size[::-1], np.uint8) for c in names}
        t0 = time.perf_counter()
        labels, depths = {}, {}
        for ci, cam in enumerate(rig):
            m = masks[ci]
            if m is None or cam.name not in images or not np.any(m):
                labels[cam.name] = empty[cam.name]
                obs.report("text", name=f"free_viewpoint/{cam.name}", frame=frame,
                           text=f"frame {frame}: {cam.name} has no silhouette; left out")
                continue
            pose2d = np.asarray(poses2d[ci], float)  # image pixels (stage 1's offsets are in ``cam``)
            per_view = self.config.template_pose == "per_view" and np.isfinite(pose2d).all()
            plate = (plates or {}).get(cam.name) if self.config.use_plates else None
            seg = segment_frame(images[cam.name], m, J1, cam, self.template, joints2d=pose2d if per_view else None, observer=obs, frame=frame, plate=plate)
            labels[cam.name], depths[cam.name] = seg.labels, seg.template_depth
        timings["segmentation"] = time.perf_counter() - t0
        if not depths:
            return FrameResult(frame, STATUS_NO_VIEWS, J1, np.full_like(J1, np.nan), rig, labels, timings=timings)
        imgs = {c: images.get(c, np.zeros(rig[c].size[::-1] + (3,), np.uint8)) for c in names}
        s3 = optimize_frame(imgs, labels, rig, J1, depths=depths, constraints=self.constraints,
                            config=self.config.optimize_config, optimize=self.config.optimize and len(depths) >= 2,
                            billboards=self.config.supersample if supersample is None else supersample,
                            observer=obs, frame=frame)
        timings["segmentation"] += s3.timings["seams"]
        timings.update({k: v for k, v in s3.timings.items() if k != "seams"})
        J = s3.joints
        standard = hull = None
        if self.config.baselines:
            t0 = time.perf_counter()
            sil = {c: labels[c] > 0 for c in names}
            standard = standard_billboards(imgs, sil, J, rig, frame)
            timings["standard_billboards"] = time.perf_counter() - t0
            if with_hull:
                t0 = time.perf_counter()
                hull = visual_hull(imgs, sil, J, rig)
                timings["visual_hull"] = time.perf_counter() - t0
        obs.report("joints3d", joints=J, name="free_viewpoint/joints", skeleton=SKELETON_14, frame=frame)
        return FrameResult(frame, STATUS_OK, J1, J, rig, labels, s3.model, standard, hull, timings, s3.outcome)
