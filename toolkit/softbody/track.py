"""Frame-to-frame tracking of the soft body's pose in point clouds (source 002, "frame-to-frame tracking").

Per frame, the root and the joint angles (27 values; lengths and widths
fixed) minimise the robust point-to-surface distances of the cloud plus the
coverage block of :mod:`toolkit.softbody.residuals` and a weak pull towards
the start pose (stronger, and towards the previous frame, for parts with few
points of their own; those parts get no coverage block), with ``scipy.optimize.least_squares`` (trust-region
reflective, analytic Jacobian, elbows and knees bounded to ``[0, pi]``).
Each frame starts from the previous one (extrapolated by a damped constant
velocity).  The cloud is first split into the subject's points and other
bodies' (:func:`toolkit.softbody.separate.separate_subject`: points further
than ``gate`` outside the start model, or further than a reach per metaball
(``motion_floor`` plus its motion over the last frame), and the pieces of the
cloud connected to them that are not within ``near_margin`` of it: a second
person touching the subject, the floor; memory of the last frame's other
bodies); only the subject's are fitted.  Every frame gets an explicit state:

* ``"ok"``: fitted, enough points near the fitted surface;
* ``"crowded"``: another body touches more than ``crowded_contact`` of the
  subject's points, or more than ``crowded_undecided`` of them lie between
  the near margin and the gate (another body that could not be told apart):
  where the two meet the separation is a guess (people overlapping in the
  view, a hug); fitted on the subject's points (on the near ones only in the
  second case), the pose is kept and tracking goes on from it, the global fit
  leaves the frame's points out;
* ``"empty"``: fewer than ``min_points`` points in the cloud (or after the
  separation): the pose is carried over;
* ``"lost"``: fitted, but too few points lie near the surface (stray pieces
  within the gate counted as far): the start pose is kept.

Silhouette observations (the source's optional term): with ``silhouette_weight > 0``
and the cameras' masks given per frame, the outline and mask blocks of
:mod:`toolkit.softbody.silhouette` join the fit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from toolkit.errors import InputError
from toolkit.observe import Observer, as_observer
from toolkit.softbody.distance import check_points, distance, primitive_distances
from toolkit.softbody.model import (DOF_NAMES, N_POSE, TRUNK_POSTURE, SoftBodyModel, SoftBodyParams, canonical_pose,
                                    pose_bounds, pose_step)
from toolkit.softbody.residuals import (LOSSES, CoverageSamples, coverage_residuals, coverage_samples, data_residuals,
                                       coverage_margin,
                                       one_blas_thread)
from toolkit.softbody.separate import link_distance, separate_subject
from toolkit.softbody.silhouette import SilhouetteBlock

__all__ = ["TrackConfig", "SoftBodyTrack", "FrameFit", "track_sequence", "track_frame", "FRAME_STATES", "subsample"]

FRAME_STATES = ("ok", "crowded", "empty", "lost")


@dataclass(frozen=True)
class TrackConfig:
    """Settings of frame-to-frame tracking.

    Attributes
    ----------
    loss : str
        Robust loss of the point-to-surface block (``soft_l1``, ``huber``, ``cauchy``, ``linear``).
    f_scale : float
        Distance where that loss turns robust, metres (about the cloud's noise).
    coverage_weight : float
        Weight of the coverage block (model points to their nearest cloud point);
        it refines a first fit made without it (far from the solution its nearest
        neighbours are wrong and it attracts to false minima).
    coverage_scale : float
        Scale of its Cauchy loss, metres: model points further than this from
        the cloud pull only weakly (occluded parts, holes).
    coverage_margin : float
        Model points closer than this to the cloud count as covered, metres;
        raised per frame to twice the cloud's spacing
        (:func:`toolkit.softbody.residuals.coverage_margin`).
    coverage_dirs : int
        Model points per primitive considered for the coverage block.
    viewpoints : tuple of (3,) or None
        Camera centres (metres): coverage only from model points facing one.
    gate : float
        Points further than this outside the start model are not the subject's, metres;
        nor are the points connected to them (neighbours closer than ``link``) that
        lie further than ``near_margin`` outside it.
    near_margin : float
        Points closer than this to the start model's surface are the subject's, metres:
        the model's misfit (about 35 mm at the 99th percentile on synthetic depth
        clouds) plus the error of the motion prediction over one frame.
    link : float
        Smallest neighbour distance of the separation, metres (raised to twice the
        cloud's spacing, :func:`toolkit.softbody.separate.link_distance`).
    crowded_contact : float
        Another body touching more than this fraction of the subject's points:
        state ``"crowded"``.
    crowded_undecided : float
        More than this fraction of the subject's points further than the near margin
        from the start model (another body within the gate that could not be told
        apart): state ``"crowded"``, and only the points within the near margin are
        fitted (the pose follows the subject by at most about that margin per frame).
    regate : int
        Up to this many times, while points kept are further than ``motion_floor``
        beyond the near margin (or too many are undecided): the pose fitted to the
        points within the near margin and the cloud separated again around it, with
        ``motion_floor`` as the reach (the subject's own points that moved come
        near; another body's stay where they are).
    motion_floor, motion_gain : float
        The separation's reach per metaball (how far beyond the near margin its
        surface may be): ``motion_floor`` (metres) plus ``motion_gain`` times the
        metaball's motion over the last frame (what the damped prediction may miss).
    init_reach : float
        The reach in the first frame, metres (the initial pose's error).
    max_points : int
        Points kept per frame (an even subsample, the cloud's order kept).
    min_points : int
        Fewer points (after the gate): state ``"empty"``.
    inlier_distance : float
        A point within this of the fitted surface is an inlier, metres.
    min_inlier_fraction : float
        Fewer inliers than this fraction of the gated points: state ``"lost"``.
    prior_weight : float
        Pull of each angle towards the start pose, metres per radian (and
        metre per metre for the root): keeps unobserved angles (e.g. the axial
        rotation of a straight limb) still.
    unseen_weight : float
        Pull (metres per radian) of the angles of a part with fewer than
        ``part_points`` points towards the previous frame's angles, scaled
        by the missing fraction; such parts also get no coverage block (its
        nearest points belong to other parts: a leg without points folded up
        into the thigh and torso data).
    part_points : int
        Points within ``part_distance`` of a rigid part (and the parts it
        carries) for its angles to count as observed.
    part_distance : float
        A point belongs to the part of its nearest metaball within this, metres.
    predict : float
        Fraction of the last frame-to-frame change added to the start pose.
    max_nfev : int
        Evaluations per frame.
    silhouette_weight : float
        Weight of the silhouette blocks (:mod:`toolkit.softbody.silhouette`) when
        masks are given; 0: not used.
    posture_weight : float
        Pull of the trunk's lateral bend and axial twist against the pelvis
        towards 0, metres per radian (:data:`toolkit.softbody.model.TRUNK_POSTURE`);
        0: none.  The pelvis is buried: a roll or yaw of it against the
        trunk, made up by the hips' angles, changes the surface little, and
        stereo fits bent the trunk 8-28 degrees and twisted it up to 31
        against the pelvis (none in the true poses), one hip 40-50 mm high
        and the other as low.  At 0.2 m/rad (the same prior as the initial
        pose's, :data:`toolkit.softbody.init.POSTURE_WEIGHT`, here and in the
        global fit) the trinocular MPJPE after the global fit went 32.9 ->
        28.5 mm (mean of 16 runs, seeds 13000 and 14000; better in 16 of
        16), and depth 13.2 -> 12.3 mm (8 runs, better in 8); on the fresh
        seeds 15000 and 16000 stereo 26.1 -> 24.1 mm (13 of 16 better) and
        depth 14.2 -> 13.7 mm (docs/benchmarks.md, soft-body section; the earlier runs: its git history).  Its price: on
        noiseless points of a trunk really bent 20 degrees and twisted 15,
        tracking ends at about 16 and 9 degrees (joints 4 mm off): the surface
        shows a twist against the pelvis only weakly.
    hold_step : float
        A fitted frame where a joint moved further than this against the body since the previous tracked
        frame (metres per frame; :func:`toolkit.softbody.confidence.largest_step`) is fitted again with the
        angles of the limbs that jumped held at the start pose (``hold_weight``, metres per radian), and the
        fit whose largest move is smaller kept: a limb with few points of its own (a forearm without
        texture) can jump onto another part's points in one frame.  The true joints of 25-30 fps runs move
        at most 0.19 m per frame against the body.  0: not checked.
    hold_weight : float
        Pull of the held angles towards the start pose, metres per radian.
    """

    loss: str = "soft_l1"
    f_scale: float = 0.02
    coverage_weight: float = 0.3
    coverage_scale: float = 0.05
    coverage_margin: float = 0.03
    coverage_dirs: int = 24
    viewpoints: tuple | None = None
    gate: float = 0.25
    near_margin: float = 0.03
    link: float = 0.04
    crowded_contact: float = 0.1
    crowded_undecided: float = 0.15
    regate: int = 2
    motion_floor: float = 0.06
    motion_gain: float = 1.0
    init_reach: float = 0.15
    max_points: int = 1000
    min_points: int = 30
    inlier_distance: float = 0.05
    min_inlier_fraction: float = 0.3
    prior_weight: float = 0.01
    unseen_weight: float = 0.3
    part_points: int = 10
    part_distance: float = 0.06
    predict: float = 0.5
    max_nfev: int = 40
    silhouette_weight: float = 1.0
    posture_weight: float = 0.2
    hold_step: float = 0.3
    hold_weight: float = 1.0

    def __post_init__(self):
        if self.loss not in LOSSES:
            raise InputError("TrackConfig.loss", f"one of {LOSSES}", repr(self.loss))
        for name in ("f_scale", "coverage_scale", "gate", "near_margin", "link", "inlier_distance"):
            if not getattr(self, name) > 0:
                raise InputError(f"TrackConfig.{name}", "a positive distance in metres", repr(getattr(self, name)))
        if not self.silhouette_weight >= 0:
            raise InputError("TrackConfig.silhouette_weight", "a weight >= 0", repr(self.silhouette_weight))
        for name in ("hold_step", "hold_weight"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise InputError(f"TrackConfig.{name}", "a finite value >= 0", repr(getattr(self, name)))
        if not (np.isfinite(self.posture_weight) and self.posture_weight >= 0):
            raise InputError("TrackConfig.posture_weight", "a finite weight >= 0 (metres per radian)",
                             repr(self.posture_weight))
        if self.near_margin >= self.gate:
            raise InputError("TrackConfig.near_margin", f"a distance below gate ({self.gate} m)",
                             repr(self.near_margin))
        if self.min_points < 1 or self.max_points < self.min_points:
            raise InputError("TrackConfig.max_points/min_points", "1 <= min_points <= max_points",
                             f"{self.min_points}, {self.max_points}")


@dataclass(frozen=True)
class SoftBodyTrack:
    """Tracking result over ``T`` frames.

    Attributes
    ----------
    params : ndarray of shape (T, 47)
        :class:`SoftBodyParams` vectors (lengths and widths as given).
    joints : ndarray of shape (T, 14, 3)
        Metres, world.
    states : tuple of str
        One of :data:`FRAME_STATES` per frame.
    n_points : ndarray of shape (T,) int
        Points used after the separation and the subsample.
    inlier_fraction : ndarray of shape (T,)
        Fraction of those within ``inlier_distance`` of the fitted surface (NaN when empty).
    median_distance : ndarray of shape (T,)
        Median absolute point-to-surface distance, metres (NaN when empty).
    subject : tuple of ndarray of shape (N_t,), bool, optional
        Per frame, the cloud's points taken for the subject's (the others are other
        bodies': :mod:`toolkit.softbody.separate`).
    contact : ndarray of shape (T,), optional
        Fraction of the subject's points that another body touches.
    undecided : ndarray of shape (T,), optional
        Fraction of the subject's points further than the near margin from the start model.
    confidence : ndarray of shape (T,), optional
        Per frame, :func:`toolkit.softbody.confidence.frame_confidence`'s confidence in [0, 1] (with a
        ``confidence`` config given to :func:`track_sequence`).
    trusted : ndarray of shape (T,) bool, optional
        Frames whose confidence does not say ``lost`` (and whose state is not ``empty`` or ``lost``); the
        others' poses are no measurement of the person.
    recovered : ndarray of shape (T,) bool, optional
        Frames found again after a loss by a re-initialisation (:func:`track_sequence`, ``reinit``).
    """

    params: np.ndarray
    joints: np.ndarray
    states: tuple
    n_points: np.ndarray
    inlier_fraction: np.ndarray
    median_distance: np.ndarray
    subject: tuple | None = None
    contact: np.ndarray | None = None
    undecided: np.ndarray | None = None
    confidence: np.ndarray | None = None
    trusted: np.ndarray | None = None
    recovered: np.ndarray | None = None

    def subject_clouds(self, clouds) -> list:
        """The subject's points of each cloud (``clouds`` as tracked), list of (M_t, 3) arrays."""
        if self.subject is None:
            return [np.asarray(c, float).reshape(-1, 3) for c in clouds]
        return [np.asarray(c, float).reshape(-1, 3)[m] for c, m in zip(clouds, self.subject)]

    def frame_params(self, t: int) -> SoftBodyParams:
        return SoftBodyParams(self.params[t])


def subsample(points: np.ndarray, n: int) -> np.ndarray:
    """At most ``n`` points, evenly spread over the array's order (deterministic)."""
    if len(points) <= n:
        return points
    return points[np.linspace(0, len(points) - 1, n).round().astype(int)]


def part_support(model: SoftBodyModel, params: SoftBodyParams, pts: np.ndarray, within: float) -> np.ndarray:
    """Points on each rigid frame of the model, shape (11,) int.

    A point counts for the frame of its nearest metaball (ellipsoidal
    distance) when that distance is below ``within`` metres.
    """
    from toolkit.softbody.model import FRAMES

    if len(pts) == 0:
        return np.zeros(len(FRAMES), int)
    e = primitive_distances(model.state(params), pts)
    k = np.argmin(e, axis=1)
    near = e[np.arange(len(pts)), k] < within
    return np.bincount(model.prim_frame[k[near]], minlength=len(FRAMES))


def _pose_prior_weights(model, st, support: np.ndarray, config: TrackConfig) -> np.ndarray:
    """Per pose entry: ``prior_weight`` plus ``unseen_weight`` times the missing fraction of its parts' points."""
    sub = model.subtree[st.dof_frames] @ support  # points on the frames each DOF moves
    missing = np.clip(1.0 - sub / max(config.part_points, 1), 0.0, 1.0)
    w = config.prior_weight + config.unseen_weight * missing
    w[:6] = config.prior_weight
    return w


def _fit_pose(model, start: SoftBodyParams, pts: np.ndarray, config: TrackConfig,
              coverage_weight: float, anchor: SoftBodyParams | None = None, silhouettes=None,
              hold: np.ndarray | None = None) -> SoftBodyParams:
    cols = np.arange(N_POSE)
    tree = cKDTree(pts)
    margin = coverage_margin(tree, pts, config.coverage_margin)
    support = part_support(model, start, pts, config.part_distance)
    samples = coverage_samples(model, start, n_dirs=config.coverage_dirs, viewpoints=config.viewpoints) \
        if coverage_weight > 0 else None
    if samples is not None:  # coverage only from parts that have points of their own
        keep = support[model.prim_frame[samples.prims]] >= config.part_points
        samples = CoverageSamples(samples.prims[keep], samples.dirs[keep])
    lo, hi = pose_bounds()
    x0 = np.clip(start.pose, lo + 1e-9, hi - 1e-9)
    wp = _pose_prior_weights(model, model.state(start), support, config)
    xa = x0.copy()
    if anchor is not None:  # unseen parts are pulled to the previous frame, not to the extrapolation
        unseen = wp > config.prior_weight
        xa[unseen] = np.clip(anchor.pose, lo + 1e-9, hi - 1e-9)[unseen]
    if hold is not None:   # angles held at the start (a limb that jumped: ``TrackConfig.hold_step``)
        wp = wp + hold
        xa[hold > 0] = x0[hold > 0]
    wc = np.sqrt(coverage_weight)
    posture_jac = np.zeros((len(TRUNK_POSTURE), N_POSE))
    posture_jac[np.arange(len(TRUNK_POSTURE)), TRUNK_POSTURE] = config.posture_weight
    sil = SilhouetteBlock(model, start, silhouettes) if silhouettes and config.silhouette_weight > 0 else None
    cache = {}

    def evaluate(x):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            p = start.replace(pose=x)
            st = model.state(p)
            r, J = data_residuals(model, p, pts, st, cols, config.loss, config.f_scale)
            r, J = [r, wp * (x - xa), config.posture_weight * x[TRUNK_POSTURE]], [J, np.diag(wp), posture_jac]
            if samples is not None:
                rc, Jc = coverage_residuals(model, st, samples, tree, pts, cols, "cauchy", config.coverage_scale,
                                            margin)
                r, J = r + [wc * rc], J + [wc * Jc]
            if sil is not None:
                rs, Js = sil.residuals(p, st, cols)
                r, J = r + [np.sqrt(config.silhouette_weight) * rs], J + [np.sqrt(config.silhouette_weight) * Js]
            cache[key] = (np.concatenate(r), np.vstack(J))
        return cache[key]

    with one_blas_thread():
        res = least_squares(lambda x: evaluate(x)[0], x0, jac=lambda x: evaluate(x)[1], bounds=(lo, hi),
                            method="trf", loss="linear", max_nfev=config.max_nfev, x_scale="jac")
    return start.replace(pose=res.x)


class FrameFit(NamedTuple):
    """One frame's tracking result (:func:`track_frame`).

    Attributes
    ----------
    params : SoftBodyParams
    state : str
        One of :data:`FRAME_STATES`.
    n_points : int
        Points fitted (after the separation and the subsample).
    inlier_fraction, median_distance : float
        NaN when the frame is empty; the inlier fraction counts the points left out
        as doubtful (stray pieces within the gate) as outliers.
    subject : ndarray of shape (N,), bool
        The cloud's points taken for the subject's (fitted, before the subsample).
    other : ndarray of shape (N,), bool
        The cloud's points taken for other bodies'.
    contact : float
        Fraction of them another body touches.
    undecided : float
        Fraction of them further than the near margin from the start model.
    """

    params: SoftBodyParams
    state: str
    n_points: int
    inlier_fraction: float
    median_distance: float
    subject: np.ndarray
    other: np.ndarray
    contact: float
    undecided: float


def track_frame(model: SoftBodyModel, start: SoftBodyParams, cloud, config: TrackConfig = TrackConfig(),
                anchor: SoftBodyParams | None = None, others: np.ndarray | None = None,
                motion: np.ndarray | None = None, silhouettes=None, hold: np.ndarray | None = None) -> FrameFit:
    """Fit the pose of one frame.

    Parameters
    ----------
    model : SoftBodyModel
    start : SoftBodyParams
        Start (the previous frame's pose, or a prediction); the separation of the
        subject's points from other bodies' is made around it.
    cloud : array_like of shape (N, 3)
        Metres, world; may be empty.
    config : TrackConfig
    anchor : SoftBodyParams, optional
        The previous frame's pose: parts without points are pulled to it
        (default: to ``start``).
    others : ndarray of shape (M, 3), optional
        The previous frame's points of other bodies (see :func:`~toolkit.softbody.separate.separate_subject`).
    motion : ndarray of shape (P,), optional
        How far each metaball moved over the last frame, metres; None when unknown (the first
        frame): the separation then allows ``init_reach`` everywhere.
    silhouettes : list of SilhouetteView, optional
        The frame's camera silhouettes (used with ``config.silhouette_weight > 0``).
    hold : ndarray of shape (27,), optional
        Extra pull (metres per radian) of each pose entry towards ``start``.

    Returns
    -------
    FrameFit
    """
    nan = float("nan")
    cloud = check_points(cloud, "cloud")
    link = link_distance(cloud, config.link)
    reach = config.init_reach if motion is None else config.motion_floor + config.motion_gain * np.asarray(motion)
    sep = separate_subject(model, start, cloud, near=config.near_margin, gate=config.gate, link=link, others=others,
                           reach=reach)
    base = start
    for _ in range(config.regate):
        # another body in the cloud and kept points further from the prediction than a still body would be
        # (or many undecided ones): the subject's own that moved (they come near once the pose is fitted to the
        # near points) or the other's (they stay where they are)
        far = sep.other.any() and bool(np.any(sep.keep & (sep.distance >= sep.near + config.motion_floor)))
        if sep.near_points.sum() < config.min_points or (sep.undecided <= config.crowded_undecided and not far):
            break
        base = _fit_pose(model, base, subsample(cloud[sep.near_points], config.max_points), config, 0.0, anchor,
                         silhouettes)
        if sep.other.any():   # fitted to this frame's points: a still body's reach, other bodies being near
            reach = config.motion_floor
        sep = separate_subject(model, base, cloud, near=config.near_margin, gate=config.gate, link=link,
                               others=others, reach=reach)
    mixed = sep.undecided > config.crowded_undecided   # another body within the gate: the near points only
    # stray pieces (within the subject's reach, touching nothing: a hand that moved away from its arm's points,
    # clutter) are fitted as before the separation; when mixed, the undecided points are left out as doubtful
    # and count as outliers
    mine = sep.keep | sep.stray
    keep = sep.near_points if mixed else mine
    doubt = int((mine & ~keep).sum())
    pts = subsample(cloud[keep], config.max_points)
    if len(pts) < config.min_points:
        return FrameFit(start, "empty", len(pts), nan, nan, keep, sep.other, sep.contact, sep.undecided)
    fitted = _fit_pose(model, base, pts, config, 0.0, anchor, silhouettes, hold)
    if config.coverage_weight > 0:
        fitted = _fit_pose(model, fitted, pts, config, config.coverage_weight, anchor if anchor is not None
                           else start, silhouettes, hold)   # held at the first fit's (held) angles
    d = np.abs(distance(model, fitted, pts))
    n_keep = int(keep.sum())
    inl, med = float(np.mean(d < config.inlier_distance)) * n_keep / (n_keep + doubt), float(np.median(d))
    if inl < config.min_inlier_fraction:
        return FrameFit(start, "lost", len(pts), inl, med, keep, sep.other, sep.contact, sep.undecided)
    crowded = mixed or sep.contact > config.crowded_contact
    return FrameFit(fitted, "crowded" if crowded else "ok", len(pts), inl, med, keep, sep.other, sep.contact,
                    sep.undecided)


#: A trusted frame short of full confidence is re-initialised from the frame's own joints when that fit's
#: confidence is higher by more than this (a tracker drifting slowly stays trusted for many frames: a depth
#: walk went from 37 to 62 mm over 13 frames at confidences of 0.68-0.85).
DOUBT_GAIN = 0.05

#: Pose entries of the left and right limbs' swing (flexion) and bend, swapped by the recovery's search:
#: in a walk or a run the limbs swing in turn, and a tracker a step behind holds the wrong leg forward.
_SWING_PAIRS = {g: tuple((DOF_NAMES.index(f"l_{n}"), DOF_NAMES.index(f"r_{n}")) for n in names)
                for g, names in (("arms", ("shoulder_flexion", "elbow")), ("legs", ("hip_flexion", "knee")))}


#: Per joint, the pose entries (name prefixes of :data:`toolkit.softbody.model.DOF_NAMES`) that move it against
#: the body: held when it jumps (``TrackConfig.hold_step``).
_JUMP_HOLDS = {"head": ("head_",), "neck": ("lean", "bend", "twist"), "l_shoulder": ("lean", "bend", "twist"),
               "r_shoulder": ("lean", "bend", "twist"), "l_elbow": ("l_shoulder",),
               "l_wrist": ("l_shoulder", "l_elbow"), "r_elbow": ("r_shoulder",), "r_wrist": ("r_shoulder", "r_elbow"),
               "l_knee": ("l_hip",), "l_ankle": ("l_hip", "l_knee"), "r_knee": ("r_hip",),
               "r_ankle": ("r_hip", "r_knee")}


def _jump_hold(model: SoftBodyModel, params: SoftBodyParams, previous: SoftBodyParams, config: TrackConfig):
    """The joints' moves against the body from ``previous`` (14,) metres, and the hold weights (27,) of the
    pose entries moving those over ``config.hold_step`` (zeros: no jump)."""
    from toolkit.skeleton import SKELETON_14
    from toolkit.softbody.confidence import joint_steps

    move = joint_steps(model.joints(params), model.joints(previous))
    hold = np.zeros(N_POSE)
    for j in np.flatnonzero(move > config.hold_step):
        prefixes = _JUMP_HOLDS.get(SKELETON_14.joint_names[j], ())   # (): a hip, nothing to hold
        hold[[k for k, name in enumerate(DOF_NAMES) if name.startswith(prefixes)]] = config.hold_weight
    return move, hold


def _held_if_jumped(model: SoftBodyModel, f, start: SoftBodyParams, previous: SoftBodyParams, cloud,
                    config: TrackConfig, **frame_args):
    """Fit ``f`` of a frame, or the frame fitted again from ``start`` with the limbs that jumped since
    ``previous`` (the last tracked frame) held (``TrackConfig.hold_step``) when that one moves less.
    ``frame_args``: :func:`track_frame`'s ``anchor``, ``others``, ``motion``, ``silhouettes``.  Returns
    ``(fit, held)``."""
    if config.hold_step <= 0 or f.state not in ("ok", "crowded"):
        return f, False
    move, hold = _jump_hold(model, f.params, previous, config)
    if not hold.any():
        return f, False
    g = track_frame(model, start, cloud, config, hold=hold, **frame_args)
    if g.state not in ("ok", "crowded"):
        return f, False
    moved, _ = _jump_hold(model, g.params, previous, config)
    return (g, True) if moved.max() < move.max() else (f, False)


def _swung(params: SoftBodyParams, groups) -> SoftBodyParams:
    x = params.pose.copy()
    for g in groups:
        for a, b in _SWING_PAIRS[g]:
            x[[a, b]] = x[[b, a]]
    return params.replace(pose=x)


def _recovery_starts(model: SoftBodyModel, last: SoftBodyParams, cloud: np.ndarray, given) -> list:
    """Starts to find the person again from: the poses ``given`` (re-initialisations from the data); then
    the last trusted pose moved so that its joints' centre lies over the cloud's, as it is and with the left
    and right legs' (arms', both) swing swapped.  ``(how, SoftBodyParams)`` each."""
    starts = [("re-initialised", p) for p in given if isinstance(p, SoftBodyParams)]
    if len(cloud):
        shift = np.median(cloud, axis=0) - model.joints(last).mean(axis=0)
        shift[2] = 0.0   # the cloud's centre is biased towards the cameras' side; heights hold
        moved = last.replace(pose=np.r_[last.pose[:3], last.pose[3:6] + shift, last.pose[6:]])
        for groups in ((), ("legs",), ("arms",), ("arms", "legs")):
            starts.append(("search" + "".join(f", {g} swapped" for g in groups), _swung(moved, groups)))
    return starts


def track_sequence(model: SoftBodyModel, params0: SoftBodyParams, clouds, *, config: TrackConfig = TrackConfig(),
                   observer: Observer | None = None, silhouettes=None, confidence=None,
                   reinit=None, recover: bool = True) -> SoftBodyTrack:
    """Track the pose through a sequence of clouds, each frame started from the previous one.

    Parameters
    ----------
    model : SoftBodyModel
    params0 : SoftBodyParams
        Initial state (e.g. from :func:`toolkit.softbody.model_from_joints` on the first frame).
    clouds : sequence of array_like of shape (N_t, 3)
        Metres, world, z up; empty arrays allowed.
    config : TrackConfig
    silhouettes : sequence of (list of SilhouetteView or None), optional
        Per frame, the cameras' silhouettes (:func:`toolkit.softbody.silhouette.silhouette_views`).
    confidence : toolkit.softbody.confidence.ConfidenceConfig, optional
        When given, every fitted frame's confidence is measured
        (:func:`toolkit.softbody.confidence.frame_confidence`); a frame it calls ``lost`` gets the state
        ``"lost"`` (not trusted; the global fit holds it at its tracked pose and leaves its points out),
        after the person was searched for again: from the poses ``reinit(t, last)`` gives (e.g. the
        last trusted pose fitted to a detector's or a depth tracker's joints of the frame), and from the
        last trusted pose moved over the cloud (as it is, and with the left and
        right legs' and arms' swing swapped); of the starts whose fit is trusted the most confident is kept
        (the search stops at one with full confidence), the frame marked ``recovered``.
    reinit : callable, optional
        ``reinit(t, last) -> list of SoftBodyParams`` (``last``: the last trusted pose): starts for the
        search from the frame's own data; used with ``confidence``.
    recover : bool
        Search for the person again in lost frames (with ``confidence``); False: lost frames are only said.
        A trusted frame short of full confidence is also fitted from the ``reinit`` starts, and that fit
        kept when its confidence is higher by more than :data:`DOUBT_GAIN` (marked ``recovered``: its pose
        comes from a re-initialisation).
    observer : Observer, optional
        Receives per frame ``joints3d`` (``softbody/track/joints``) and
        ``scalar`` reports (``softbody/track/inlier_fraction``, ``.../median_distance_m``,
        ``.../other_points``: the points taken for other bodies'; ``.../confidence`` with ``confidence``).

    Returns
    -------
    SoftBodyTrack
    """
    obs = as_observer(observer)
    if not isinstance(params0, SoftBodyParams):
        raise InputError("params0", "a SoftBodyParams", type(params0).__name__)
    if silhouettes is not None and len(silhouettes) != len(clouds):
        raise InputError("silhouettes", f"one entry per cloud ({len(clouds)})", f"{len(silhouettes)}")
    out = np.empty((len(clouds), params0.vector.size))
    fits, conf, trusted, recovered = [], np.full(len(clouds), np.nan), np.zeros(len(clouds), bool), \
        np.zeros(len(clouds), bool)
    # angles kept in their principal ranges (the root's rotation vector far from |r| = 2 pi, where it is singular)
    prev, prev2, others, run = params0.replace(pose=canonical_pose(params0.pose)), None, None, 0   # run: fitted in a row
    last, t_last = prev, None   # the last trusted pose and frame (the start, None until a frame is trusted)
    for t, cloud in enumerate(clouds):
        start = prev
        if prev2 is not None and config.predict > 0:
            start = prev.replace(pose=pose_step(prev.pose, prev2.pose, config.predict))
        # the metaballs' motion over the last frame, known after two fitted frames (not from the start pose)
        motion = None if run < 2 else np.linalg.norm(model.state(prev).centres - model.state(prev2).centres, axis=1)
        views = None if silhouettes is None else silhouettes[t]
        f = track_frame(model, start, cloud, config, anchor=prev, others=others, motion=motion, silhouettes=views)
        if run >= 1:   # a limb that jumped since the last tracked frame: held and fitted again
            f, held = _held_if_jumped(model, f, start, prev, cloud, config, anchor=prev, others=others, motion=motion,
                                      silhouettes=views)
            if held:
                obs.report("text", text=f"frame {t}: a limb jumped, fitted again held", level="INFO", frame=t)
        pts = check_points(cloud, "cloud")
        fitted, said_lost, c = f.state in ("ok", "crowded"), False, None
        if confidence is not None:
            f, c, fitted, said_lost, again = _confident_fit(model, f, cloud, pts, views, t, (last, t_last), config,
                                                            confidence, reinit, recover, obs)
            if again:
                recovered[t] = True
                prev2, run = None, 0   # no motion extrapolated across a re-initialisation
            if c is not None:
                conf[t] = c.confidence
        trusted[t] = fitted
        others = pts[f.other]
        # a frame the confidence calls lost keeps its fit (held, not trusted), one the tracker could not fit
        # the previous pose
        p = f.params.replace(pose=canonical_pose(f.params.pose)) if fitted or said_lost else prev
        if said_lost and c is not None and c.turned:
            p = last   # a body turned round (front and back exchanged) is no start for the next frame
        out[t] = p.vector
        fits.append(f)
        if fitted:
            last, t_last = p, t
        # the motion is extrapolated between two tracked frames only: the start params0 is no frame (its
        # correction by frame 0's fit, e.g. a clicked pose on another branch of the Euler angles, is no motion)
        prev2, prev = (prev if t > 0 and not recovered[t] else None, p) if fitted else (None, p)
        run = run + 1 if fitted else 0
        _report_tracked(obs, model, p, f, t)
    joints = np.stack([model.joints(SoftBodyParams(v)) for v in out]) if len(out) else np.zeros((0, 14, 3))
    return SoftBodyTrack(out, joints, tuple(f.state for f in fits), np.array([f.n_points for f in fits], int),
                         np.array([f.inlier_fraction for f in fits]), np.array([f.median_distance for f in fits]),
                         tuple(f.subject for f in fits), np.array([f.contact for f in fits]),
                         np.array([f.undecided for f in fits]), conf if confidence is not None else None,
                         trusted if confidence is not None else None, recovered if confidence is not None else None)


def _confident_fit(model: SoftBodyModel, f, cloud, pts: np.ndarray, views, t: int, trusted_before: tuple,
                   config: TrackConfig, confidence, reinit, recover: bool, obs) -> tuple:
    """Frame ``t``'s fit ``f`` judged by its confidence, and searched for again where doubtful or lost
    (the steps of :func:`track_sequence` with ``confidence``).  ``trusted_before``: the last trusted pose and
    its frame (None before the first): the motion measure of the confidence for fits that do not come from
    the frame's own joints.

    Returns
    -------
    f : the fit kept (state ``"lost"`` when the confidence calls it lost)
    c : FrameConfidence or None (no fit)
    fitted : bool
        The frame is trusted.
    said_lost : bool
        The frame was fitted but its confidence calls it lost.
    again : bool
        The fit kept comes from a re-initialisation (``recovered``).
    """
    from toolkit.softbody.confidence import frame_confidence

    last, t_last = trusted_before
    previous = None if t_last is None else model.joints(last)

    def judged(g, own_joints=False):   # a fit from the frame's own joints: no motion measure (its heading is)
        return frame_confidence(model, g.params, pts[g.subject], silhouettes=views, viewpoints=config.viewpoints,
                                config=confidence, previous=None if own_joints else previous,
                                frames_since=1 if t_last is None else t - t_last, others=pts[~g.subject],
                                reference=previous)

    fitted, said_lost, again = f.state in ("ok", "crowded"), False, False
    c = judged(f) if fitted else None
    doubtful = c is not None and c.verdict == "trusted" and c.confidence < 1.0
    if recover and doubtful and reinit is not None:
        # trusted but short of full confidence (a slow drift): the frame's own joints tried too, kept
        # when clearly more confident
        for s0 in reinit(t, last):
            g = track_frame(model, s0, cloud, config, anchor=s0, silhouettes=views)
            if g.state not in ("ok", "crowded"):
                continue
            cg = judged(g, own_joints=True)
            if cg.verdict == "trusted" and cg.confidence > c.confidence + DOUBT_GAIN:
                f, c, again = g, cg, True
                obs.report("text", text=f"frame {t}: re-initialised (confidence {c.confidence:.2f})",
                           level="INFO", frame=t)
    if recover and (c is None or c.verdict == "lost") and len(pts) >= config.min_points:
        best = None
        given = [] if reinit is None else reinit(t, last)
        for how, s0 in _recovery_starts(model, last, pts, given):
            g = track_frame(model, s0, cloud, config, anchor=s0, silhouettes=views)
            if g.state not in ("ok", "crowded"):
                continue
            cg = judged(g, own_joints=how == "re-initialised")
            if cg.verdict == "trusted" and (best is None or cg.confidence > best[1].confidence):
                best = (g, cg, how)
            if best is not None and best[1].confidence >= 1.0:
                break   # every measure at its trusted level: no start can do better
        if best is not None:
            f, c, how = best
            again, fitted = True, True
            obs.report("text", text=f"frame {t}: found again ({how}, confidence {c.confidence:.2f})",
                       level="INFO", frame=t)
    if c is not None:
        obs.report("scalar", name="softbody/track/confidence", value=c.confidence, frame=t)
    if fitted and (c is None or c.verdict == "lost"):
        f, fitted, said_lost = f._replace(state="lost"), False, True
    return f, c, fitted, said_lost, again


def _report_tracked(obs, model: SoftBodyModel, p: SoftBodyParams, f, t: int) -> None:
    """Frame ``t``'s reports of :func:`track_sequence`: joints, fit measures, posture, a warning when not ok."""
    obs.report("joints3d", joints=model.joints(p), name="softbody/track/joints", frame=t)
    if f.state != "empty":
        obs.report("scalar", name="softbody/track/inlier_fraction", value=f.inlier_fraction, frame=t)
        obs.report("scalar", name="softbody/track/median_distance_m", value=f.median_distance, frame=t)
    obs.report("scalar", name="softbody/track/other_points", value=float(np.sum(f.other)), frame=t)
    bend, twist = np.degrees(p.pose[TRUNK_POSTURE])  # what the posture prior holds (config.posture_weight)
    obs.report("scalar", name="softbody/posture/trunk_bend_deg", value=float(bend), frame=t)
    obs.report("scalar", name="softbody/posture/trunk_twist_deg", value=float(twist), frame=t)
    if f.state != "ok":
        obs.report("text", text=f"frame {t}: {f.state} ({f.n_points} points, another body touching "
                   f"{100 * f.contact:.0f} % of them)", level="WARN", frame=t)
