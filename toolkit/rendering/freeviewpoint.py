"""One frame of free-viewpoint video: its options, its result, and its rendering into any view.

:class:`toolkit.pipeline.frame.FrameProcessor` runs stages 2-4 of a frame
(source 000 Fig. 10, steps 22-28: segmentation, the stage-3 chain,
billboards and baselines) with a :class:`FreeViewpointConfig` and returns a
:class:`FrameResult`; :func:`render_views` draws that result into a view with
every method (articulated billboards, standard billboards, visual hull).

A frame where stage 1 found no 3D pose, or a camera without a silhouette, is
not an error: the result says which views were used and why a frame is empty.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toolkit.billboards.model import BillboardModel
from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.observe import Observer
from toolkit.optimize import OptimizeConfig
from toolkit.rendering.baselines import VisualHull
from toolkit.rendering.fans import RENDER_SUPERSAMPLE
from toolkit.segmentation.pipeline import TEMPLATE_POSES

#: Stages 2-3 and the billboards of a frame work on each camera's images resized so that the person's longer
#: side (its 3D joints projected, ears to ankles) is at most this many pixels (:mod:`toolkit.pipeline.working_scale`:
#: a scale of 0.38-0.49 on the Pose2Sim demo, whose joints span 610-790 px); twice the synthetic default scene's
#: person (100-140 px), which stays at full size.
WORK_HEIGHT_PX = 300

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
        multi-view 3D joints projected through the corrected camera
        (``"multiview"``, default: they pool every view's evidence; mean part
        IoU 0.814 from stage 1 on the broadcast benchmark) or stage 1's chosen
        2D pose of that view (``"per_view"``, the source's per-view fit: 0.796).
    use_plates : bool
        Segment with the cameras' background plates when
        :meth:`toolkit.pipeline.frame.FrameProcessor.process` gets them.
    work_height_px : float or None
        Stages 2-3 and the billboards run on each camera's images resized so that the person's
        longer side is at most this many pixels (:data:`WORK_HEIGHT_PX`,
        :mod:`toolkit.pipeline.working_scale`); None or 0: at full resolution.
    """

    optimize: bool = True
    optimize_config: OptimizeConfig = field(default_factory=OptimizeConfig)
    template_height_m: float = 1.75
    supersample: int = RENDER_SUPERSAMPLE
    baselines: bool = True
    template_pose: str = "multiview"
    use_plates: bool = True
    work_height_px: float | None = WORK_HEIGHT_PX

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
    cameras : Rig
        The source cameras corrected by the frame's stage-1 offsets
        (:func:`toolkit.multiview.corrected_rig`; unused views uncorrected): the
        cameras the labels, the billboards and the baselines were made with.
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
    cameras: Rig
    labels: dict
    model: BillboardModel | None = None
    standard: BillboardModel | None = None
    hull: VisualHull | None = None
    timings: dict = field(default_factory=dict)
    optimize: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == STATUS_OK


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


def _person_depth(result: FrameResult, camera) -> float:
    """Distance (metres) from ``camera`` to a person's joints (their median depth); inf without joints."""
    J = np.asarray(result.joints, float)
    ok = np.isfinite(J).all(-1)
    return float(np.median(camera.depth_of(J[ok]))) if ok.any() else float("inf")


def render_views(result, camera, background: np.ndarray, compositor=None,
                 methods=METHODS, observer: Observer | None = None) -> dict:
    """Render one frame's people with each method into ``camera`` over ``background``, with their opacity.

    Parameters
    ----------
    result : FrameResult or sequence of FrameResult
        One person, or several (drawn far to near: each over what is behind it).
    camera : Camera
        Virtual view (no calibration offset).
    background : ndarray of shape (H, W, 3)
        Plate to composite over (uint8 or float 0..255).
    compositor : CpuCompositor, optional
    methods : sequence of str
        Subset of :data:`METHODS`; methods whose model is missing are skipped.
    observer : Observer, optional
        Passed to the articulated rendering (of the first person).

    Returns
    -------
    dict of str -> RenderedView
        The background alone (opacity 0) where no person is drawn (``result.ok`` False).
    """
    results = [result] if isinstance(result, FrameResult) else list(result)
    if len(results) == 1:
        return _render_one(results[0], camera, background, compositor, methods, observer)
    order = sorted(range(len(results)), key=lambda k: -_person_depth(results[k], camera))
    bg = np.asarray(background, np.float32)
    out: dict = {}
    for m in methods:
        img, clear = bg, None
        for k in order:
            v = _render_one(results[k], camera, img, compositor, (m,), observer if k == 0 else None).get(m)
            if v is None:
                continue
            img = v.image.astype(np.float32)
            clear = (1.0 - v.alpha) if clear is None else clear * (1.0 - v.alpha)
        if clear is not None:
            out[m] = RenderedView(np.clip(img + 0.5, 0, 255).astype(np.uint8) if img.dtype != np.uint8 else img,
                                  (1.0 - clear).astype(np.float32))
    return out


def _render_one(result: FrameResult, camera, background: np.ndarray, compositor=None,
                methods=METHODS, observer: Observer | None = None) -> dict:
    """One person's :func:`render_views`."""
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


def render_methods(result, camera, background: np.ndarray, compositor=None,
                   methods=METHODS, observer: Observer | None = None) -> dict:
    """The images of :func:`render_views`: dict of str -> ndarray (H, W, 3) uint8."""
    return {m: v.image for m, v in render_views(result, camera, background, compositor, methods, observer).items()}
