"""One frame of free-viewpoint video, every stage chained (source 000 Fig. 10, steps 22-28).

Stage 1 (foreground, 2D pose, multi-view selection and offsets) runs over the
whole dataset in :func:`toolkit.silhouettes.pipeline.estimate_dataset`; this
module takes one of its frame estimates and the silhouettes, and runs the rest:

* template fit and body-part segmentation per camera (:func:`toolkit.segmentation.segment_frame`);
* seams on the fitted template's depth (:func:`toolkit.billboards.detect_seams`);
* the 3D joint optimisation by the position score under anthropometric
  constraints (:func:`toolkit.optimize.optimize_pose`);
* the articulated billboards (:func:`toolkit.rendering.fans.render_billboards`)
  and, for comparison, the standard billboards and the visual hull.

A frame where stage 1 found no 3D pose, or a camera without a silhouette, is
not an error: the result says which views were used and why a frame is empty.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from toolkit.billboards.model import BillboardModel
from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.observe import Observer, as_observer
from toolkit.optimize import OptimizeConfig
from toolkit.rendering.baselines import VisualHull, standard_billboards, visual_hull
from toolkit.rendering.fans import RENDER_SUPERSAMPLE, render_billboards
from toolkit.segmentation.pipeline import TEMPLATE_POSES
from toolkit.skeleton import SKELETON_14

#: ``FrameResult.status`` values.
STATUS_OK = "ok"
STATUS_NO_POSE = "no 3D pose from stage 1"
STATUS_NO_VIEWS = "no camera has a usable silhouette"


@dataclass(frozen=True)
class FreeViewpointConfig:
    """Options of the per-frame chain.

    Parameters
    ----------
    optimize : bool
        Run the 3D joint optimisation (stage 3); else keep stage 1's joints.
    optimize_config : OptimizeConfig
    template_height_m : float
        Stature of the generic template used for segmentation, metres.
    supersample : int
        Texture supersampling of the rendered billboards.
    baselines : bool
        Also build the standard billboards and the visual hull.
    template_pose : {"multiview", "per_view"}
        The 2D pose the template is fitted to exactly in each view: the
        multi-view 3D joints projected through the offset camera
        (``"multiview"``, default: they pool every view's evidence; mean part
        IoU 0.814 from stage 1 on the broadcast benchmark) or stage 1's chosen
        2D pose of that view (``"per_view"``, the source's per-view fit: 0.796).
    use_plates : bool
        Segment with the cameras' background plates when :meth:`FrameProcessor.process` gets them.
    """

    optimize: bool = True
    optimize_config: OptimizeConfig = field(default_factory=OptimizeConfig)
    template_height_m: float = 1.75
    supersample: int = RENDER_SUPERSAMPLE
    baselines: bool = True
    template_pose: str = "multiview"
    use_plates: bool = True

    def __post_init__(self):
        if self.template_pose not in TEMPLATE_POSES:
            raise InputError("FreeViewpointConfig.template_pose", f"one of {TEMPLATE_POSES}", repr(self.template_pose))



@dataclass(frozen=True, eq=False)
class FrameResult:
    """Everything one frame produced.

    Attributes
    ----------
    frame : int
    status : str
        :data:`STATUS_OK` or why the frame is empty.
    joints_stage1 : ndarray of shape (14, 3)
    joints : ndarray of shape (14, 3)
        Final joints (optimised when asked), metres; NaN when none.
    offsets : ndarray of shape (n_cams, 2)
        Stage-1 calibration offsets (0 for unused views), pixels.
    labels : dict of str -> ndarray (H, W) uint8
        Part labels per camera (zeros without a silhouette).
    model : BillboardModel or None
    standard : BillboardModel or None
    hull : VisualHull or None
    timings : dict of str -> float
        Seconds per stage.
    optimize : dict of str -> int
        How the stage-3 search ended for the joints (:meth:`PoseResult.outcome_counts`:
        ``moved``, ``kept``, ``few_views``, ...); empty when it did not run.
    """

    frame: int
    status: str
    joints_stage1: np.ndarray
    joints: np.ndarray
    offsets: np.ndarray
    labels: dict
    model: BillboardModel | None = None
    standard: BillboardModel | None = None
    hull: VisualHull | None = None
    timings: dict = field(default_factory=dict)
    optimize: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == STATUS_OK


class FrameProcessor:
    """Runs stages 2-3 and builds the billboards for one frame at a time.

    Parameters
    ----------
    rig : Rig
        Measured source cameras.
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
        """
        from toolkit.billboards import PositionScorer, detect_seams
        from toolkit.optimize import optimize_pose
        from toolkit.segmentation import segment_frame

        obs = self.observer
        names = self.rig.names
        timings: dict = {}
        J1 = np.asarray(estimate.joints3d, float)
        from toolkit.multiview import image_offsets
        off = image_offsets(estimate.offsets)  # stage 1 corrects the joints; images need the opposite shift
        empty = {c: np.zeros(self.rig[c].size[::-1], np.uint8) for c in names}
        if not estimate.ok or not np.isfinite(J1).all():
            obs.report("text", name="free_viewpoint/status", text=f"frame {frame}: {STATUS_NO_POSE}", frame=frame)
            return FrameResult(frame, STATUS_NO_POSE, J1, np.full_like(J1, np.nan), off, empty, timings=timings)
        t0 = time.perf_counter()
        labels, seams, used = {}, {}, []
        for ci, cam in enumerate(self.rig):
            m = masks[ci]
            if m is None or cam.name not in images or not np.any(m):
                labels[cam.name] = empty[cam.name]
                obs.report("text", name=f"free_viewpoint/{cam.name}", frame=frame,
                           text=f"frame {frame}: {cam.name} has no silhouette; left out")
                continue
            pose2d = np.asarray(estimate.poses2d[ci], float)  # image pixels (the offset is for the joints)
            per_view = self.config.template_pose == "per_view" and np.isfinite(pose2d).all()
            plate = (plates or {}).get(cam.name) if self.config.use_plates else None
            seg = segment_frame(images[cam.name], m, J1, cam, self.template, offset=off[ci],
                                joints2d=pose2d if per_view else None, observer=obs, frame=frame, plate=plate)
            labels[cam.name] = seg.labels
            seams[cam.name] = detect_seams(seg.labels, seg.template_depth, camera=cam.name, observer=obs)
            used.append(cam.name)
        timings["segmentation"] = time.perf_counter() - t0
        if not used:
            return FrameResult(frame, STATUS_NO_VIEWS, J1, np.full_like(J1, np.nan), off, labels, timings=timings)
        imgs = {c: images.get(c, np.zeros(self.rig[c].size[::-1] + (3,), np.uint8)) for c in names}
        J = J1
        outcome: dict = {}
        if self.config.optimize and len(used) >= 2:
            t0 = time.perf_counter()
            scorer = PositionScorer(imgs, labels, self.rig, off, seams)
            found = optimize_pose(scorer, J1, self.constraints, self.config.optimize_config, observer=obs,
                                  frame=frame)
            J, outcome = found.joints, found.outcome_counts()
            timings["optimize"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        model = render_billboards(imgs, labels, J, self.rig, off, seams, supersample=self.config.supersample,
                                  frame=frame, observer=obs)
        timings["billboards"] = time.perf_counter() - t0
        standard = hull = None
        if self.config.baselines:
            t0 = time.perf_counter()
            sil = {c: labels[c] > 0 for c in names}
            standard = standard_billboards(imgs, sil, J, self.rig, off, frame)
            timings["standard_billboards"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            hull = visual_hull(imgs, sil, J, self.rig, off)
            timings["visual_hull"] = time.perf_counter() - t0
        obs.report("joints3d", joints=J, name="free_viewpoint/joints", skeleton=SKELETON_14, frame=frame)
        return FrameResult(frame, STATUS_OK, J1, J, off, labels, model, standard, hull, timings, outcome)


#: Names of the rendering methods, in report order.
METHODS = ("articulated", "standard", "visual_hull")


@dataclass(frozen=True, eq=False)
class RenderedView:
    """One method's rendering of a frame into one view.

    Attributes
    ----------
    image : ndarray of shape (H, W, 3), uint8
        The subject over the background.
    alpha : ndarray of shape (H, W), float32
        Opacity of the subject in [0, 1] (0 everywhere for an empty frame).
    """

    image: np.ndarray
    alpha: np.ndarray


def render_views(result: FrameResult, camera, background: np.ndarray, compositor=None,
                 methods=METHODS, observer: Observer | None = None) -> dict:
    """Render one frame's subject with each method into ``camera`` over ``background``, with its opacity.

    Parameters
    ----------
    result : FrameResult
    camera : Camera
        Virtual view (no calibration offset).
    background : ndarray of shape (H, W, 3)
        Plate to composite over (uint8 or float 0..255).
    compositor : CpuCompositor, optional
    methods : sequence of str
        Subset of :data:`METHODS`; methods whose model is missing are skipped.
    observer : Observer, optional
        Passed to the articulated rendering.

    Returns
    -------
    dict of str -> RenderedView
        The background alone (opacity 0) for an empty frame (``result.ok`` False).
    """
    from toolkit.rendering.baselines import render_points
    from toolkit.rendering.compositor import CpuCompositor

    comp = CpuCompositor() if compositor is None else compositor
    bg = np.asarray(background, np.float32)
    plain = np.clip(bg + 0.5, 0, 255).astype(np.uint8)
    out = {}
    for m in methods:
        if m == "articulated" and result.model is not None:
            r = comp.render(result.model, camera, observer=observer, frame=result.frame)
            out[m] = RenderedView(r.over(bg), r.alpha)
        elif m == "standard" and result.standard is not None:
            r = comp.render(result.standard, camera)
            out[m] = RenderedView(r.over(bg), r.alpha)
        elif m == "visual_hull" and result.hull is not None:
            rgb, a = render_points(result.hull, camera)
            out[m] = RenderedView(np.clip(rgb + (1.0 - a[..., None]) * bg + 0.5, 0, 255).astype(np.uint8), a)
        elif m in METHODS and not result.ok:
            out[m] = RenderedView(plain, np.zeros(plain.shape[:2], np.float32))
    return out


def render_methods(result: FrameResult, camera, background: np.ndarray, compositor=None,
                   methods=METHODS, observer: Observer | None = None) -> dict:
    """The images of :func:`render_views`: dict of str -> ndarray (H, W, 3) uint8."""
    return {m: v.image for m, v in render_views(result, camera, background, compositor, methods, observer).items()}
