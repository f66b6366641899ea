"""The stage-3 chain of one frame, written once: labels -> seams -> position score -> joint search (-> billboards).

Used by the per-frame chain of the free-viewpoint system
(:class:`toolkit.pipeline.frame.FrameProcessor`), the stage-3 run
(:mod:`toolkit.pipeline.optimize_joints`) and
``benchmarks/bench_joint_optimization.py``; they differ only in where the
part labels and the depth for the seams come from (stage 2's template, files
of a stage-2 run, ground truth).

Steps (source 000 §3, docs/stage3_billboards.md):

1. seams from each labelled camera's depth (:func:`toolkit.billboards.detect_seams`);
2. the position score of the frame (:class:`toolkit.billboards.PositionScorer`);
3. the constrained joint search (:func:`toolkit.optimize.optimize_pose`);
4. optionally the articulated billboards at the final joints
   (:func:`toolkit.rendering.fans.render_billboards`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from toolkit.observe import Observer
from toolkit.optimize import OptimizeConfig


@dataclass(frozen=True, eq=False)
class Stage3Result:
    """What the stage-3 chain produced for one frame.

    Attributes
    ----------
    joints : ndarray of shape (14, 3)
        Final joints, metres (the start when the search did not run).
    seams : dict of str -> SeamMap, or None
        Per camera with a depth map; None without depth maps.
    search : PoseResult or None
        The joint search (None when it did not run).
    model : BillboardModel or None
        The billboards at ``joints`` (when asked for).
    timings : dict of str -> float
        Seconds of the steps that ran: ``"seams"``, ``"optimize"``, ``"billboards"``.
    """

    joints: np.ndarray
    seams: dict | None
    search: object | None = None
    model: object | None = None
    timings: dict = field(default_factory=dict)

    @property
    def outcome(self) -> dict:
        """How the search ended per joint (:meth:`PoseResult.outcome_counts`); empty when it did not run."""
        return self.search.outcome_counts() if self.search is not None else {}


def seams_from_depth(labels: dict, depths: dict | None, *, observer: Observer | None = None) -> dict | None:
    """Seams of each camera with a depth map (step 1), or None without depth maps.

    Parameters
    ----------
    labels : dict of str -> ndarray (H, W) uint8
    depths : dict of str -> ndarray (H, W) float, or None
        Metres, NaN unknown.
    observer : Observer, optional

    Returns
    -------
    dict of str -> SeamMap, or None
    """
    from toolkit.billboards import detect_seams

    if not depths:
        return None
    return {c: detect_seams(labels[c], d, camera=c, observer=observer) for c, d in depths.items()}


def optimize_frame(images: dict, labels: dict, rig, joints, *, depths: dict | None = None,
                   constraints=None, config: OptimizeConfig = OptimizeConfig(), optimize: bool = True,
                   billboards: int | None = None, borrow: bool = True, observer: Observer | None = None,
                   frame: int | None = None) -> Stage3Result:
    """Run stage 3 on one frame: seams, position score, joint search, billboards.

    Parameters
    ----------
    images : dict of str -> ndarray (H, W, 3) uint8
        Source image per camera of ``rig``.
    labels : dict of str -> ndarray (H, W) uint8
        Part ids per camera (1-based, 0 background).
    rig : Rig
        The cameras the joints are seen through, corrected by stage 1's offsets
        (:func:`toolkit.multiview.corrected_rig`).
    joints : ndarray of shape (14, 3)
        The start, metres (finite when ``optimize``).
    depths : dict of str -> ndarray (H, W) float, optional
        Depth per camera (metres, NaN unknown: the fitted template's or the
        ground truth's) for the seams; cameras without one get none.  None or
        empty: no seams.
    constraints : AnthropometricConstraints, optional
    config : OptimizeConfig
    optimize : bool
        Run the search (False: keep ``joints``; e.g. fewer than two views).
    billboards : int, optional
        Build the billboards at the final joints with this texture
        supersampling (1: stage 3's own); None: none.
    borrow : bool
        Limbs hidden from a camera borrow their mirror limb's billboard
        (:func:`toolkit.rendering.fans.borrow_occluded`).
    observer : Observer, optional
        Receives the seams, the search and the billboards.
    frame : int, optional

    Returns
    -------
    Stage3Result

    Raises
    ------
    InputError
        Inputs that do not match the rig (from the scorer and the search).
    """
    from toolkit.billboards import PositionScorer
    from toolkit.optimize import optimize_pose

    timings: dict = {}
    t0 = time.perf_counter()
    seams = seams_from_depth(labels, depths, observer=observer)
    timings["seams"] = time.perf_counter() - t0
    J = np.asarray(joints, float)
    search = model = None
    if optimize:
        t0 = time.perf_counter()
        scorer = PositionScorer(images, labels, rig, seams)
        search = optimize_pose(scorer, J, constraints, config, observer=observer, frame=frame)
        J = search.joints
        timings["optimize"] = time.perf_counter() - t0
    if billboards is not None:
        from toolkit.rendering.fans import render_billboards

        t0 = time.perf_counter()
        model = render_billboards(images, labels, J, rig, seams, supersample=billboards, borrow=borrow,
                                  frame=0 if frame is None else frame, observer=observer)
        timings["billboards"] = time.perf_counter() - t0
    return Stage3Result(J, seams, search, model, timings)
