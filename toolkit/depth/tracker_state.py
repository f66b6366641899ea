"""Configuration, states and per-frame result of the depth tracker (:mod:`toolkit.depth.tracker`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toolkit.depth.complete import CompletionConfig
from toolkit.depth.constraints import ConstraintConfig
from toolkit.depth.curvature import CurvatureConfig
from toolkit.depth.energy import EnergyConfig
from toolkit.depth.fit import FitConfig
from toolkit.depth.init import InitConfig
from toolkit.pointcloud.mask import MaskConfig
from toolkit.depth.orus import OrusConfig
from toolkit.depth.radial import RadialConfig
from toolkit.depth.stabilise import StabiliserConfig
from toolkit.errors import InputError

__all__ = ["LOST", "NO_PERSON_FLAT", "RECOVERING", "STATE_NAMES", "TRACKING", "FrameResult", "TrackerConfig"]

LOST, RECOVERING, TRACKING = 0, 1, 2
STATE_NAMES = ("lost", "recovering", "tracking")
#: The reason of a lost frame whose depth is a flat surface (a wall), no person (``TrackerConfig.max_planar_share``).
NO_PERSON_FLAT = "no person: a flat surface"


@dataclass(frozen=True)
class TrackerConfig:
    """Settings of the whole tracker (one frozen config per stage inside).

    Attributes
    ----------
    fps : float
        Frame rate (sets ``dt``).
    output : {"world", "camera"}
        Coordinates of the output joints ("world" falls back to camera coordinates
        when the camera pose is unknown).
    min_bins : int
        Fewer filled grid bins than this: no user.
    max_planar_share : float
        A user's grid whose filled bins are more than this share planar
        (:data:`toolkit.depth.curvature.PLANAR`) is a flat surface, such as a
        wall with nobody in front of it, not a person: the frame is lost
        (:data:`NO_PERSON_FLAT`).  Measured: a wall 0.93-1.0 (flat, tilted,
        with 1 cm noise), a person 0.1-0.5 (synthetic sequences with floor
        or studio walls in the grid, real Kinect frames).
    confirm_frames : int
        Good frames before ``recovering`` becomes ``tracking``.
    reinit_after : int
        Poor frames before the skeleton is searched for again.
    good_explained : float
        A fit is good when it explains at least this fraction of the user's bins ...
    good_support : float
        ... and the data support at least this fraction of its samples seen by the
        camera (:func:`toolkit.depth.energy.support_fraction`).
    person_gate_m : float
        Bins farther than this from the predicted body are not the user ...
    touching_fraction : float
        ... when they are more than this fraction of the user's bins and show a
        head of their own (a second person touching the user); otherwise the far
        bins are the user moving away from the prediction and are kept.
    touching_memory : int
        After a second person was seen touching the user, far bins are left out for
        this many frames without asking for their head again.
    second_head_m : float
        When the user is first found, two head candidates at the same height
        at least this far apart sideways are two people; the grid is split
        between them and the better head kept.
    min_body_m : float
        A second person's head has a body under it: the silhouette continues at
        least this far straight down (a raised fist does not).
    support_radius_m : float
        A control point is observed when grid bins given to its primitives lie this close to it ...
    support_min_bins : int
        ... at least this many.
    prev_weight_tracking, prev_weight_recovering, prev_weight_unseen : float
        Weights of the previous-skeleton term (the last for points unseen in the previous frame).
    single_thread_blas : bool
        Limit BLAS to one thread while processing a frame: the fit multiplies
        small matrices, which multi-threaded BLAS slows down by 10-30x on a busy machine.
    report_max_points : int
        At most about this many cloud points are reported to the observer per frame.
    """

    mask: MaskConfig = MaskConfig()
    orus: OrusConfig = OrusConfig(normal_source="pixels")
    curvature: CurvatureConfig = CurvatureConfig()
    radial: RadialConfig = RadialConfig()
    init: InitConfig = InitConfig()
    energy: EnergyConfig = EnergyConfig()
    fit: FitConfig = FitConfig()
    constraints: ConstraintConfig = ConstraintConfig()
    stabiliser: StabiliserConfig = StabiliserConfig()
    completion: CompletionConfig = CompletionConfig()
    fps: float = 30.0
    output: str = "world"
    min_bins: int = 25
    max_planar_share: float = 0.8
    confirm_frames: int = 3
    reinit_after: int = 8
    good_explained: float = 0.9
    good_support: float = 0.8
    person_gate_m: float = 0.12
    touching_fraction: float = 0.2
    second_head_m: float = 0.45
    touching_memory: int = 15
    min_body_m: float = 0.8
    support_radius_m: float = 0.15
    support_min_bins: int = 2
    prev_weight_tracking: float = 0.3
    prev_weight_recovering: float = 0.1
    prev_weight_unseen: float = 1.0
    single_thread_blas: bool = True
    report_max_points: int = 5000

    def __post_init__(self):
        if self.output not in ("world", "camera"):
            raise InputError("TrackerConfig.output", "'world' or 'camera'", repr(self.output))
        if not self.fps > 0:
            raise InputError("TrackerConfig.fps", "a positive frame rate", repr(self.fps))


@dataclass(frozen=True)
class FrameResult:
    """The tracker's answer for one frame.

    Attributes
    ----------
    index : int
    state : int
        :data:`LOST`, :data:`RECOVERING` or :data:`TRACKING`.
    joints : ndarray of shape (13, 3)
        Output coordinates (world or camera), metres; NaN when lost.
    joints_view : ndarray of shape (13, 3)
        The same in the view frame.
    observed : ndarray of shape (13,), bool
        Points supported by this frame's data (the others were completed).
    explained : float
        Fraction of the user's grid bins the skeleton explains.
    supported : float
        Fraction of the skeleton's samples seen by the camera that the data support.
    energy : float
    reason : str
        Why the state is what it is (``"ok"``, ``"no depth"``, ``"no user"``,
        :data:`NO_PERSON_FLAT`, ``"init"``, ``"poor fit"``, ``"touching"``, ...).
    n_points : int
        User points.
    timings : dict
        CPU seconds of the calling thread per stage (``mask_cloud``, ``orus_curvature``,
        ``fit``, ``post``, ``total``); CPU rather than wall time so that other
        processes on the machine do not inflate it.
    """

    index: int
    state: int
    joints: np.ndarray
    joints_view: np.ndarray
    observed: np.ndarray
    explained: float = 0.0
    supported: float = 0.0
    energy: float = float("nan")
    reason: str = "ok"
    n_points: int = 0
    timings: dict = field(default_factory=dict)

    @property
    def state_name(self) -> str:
        return STATE_NAMES[self.state]
