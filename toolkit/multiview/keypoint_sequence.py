"""Triangulating a 2D detector's keypoints over a sequence: trusted labels, offsets that never hurt.

A 2D detector (OpenPose, MMPose, MediaPipe, ...) labels left and right itself
and is usually right, and a lab rig is often calibrated well.  The silhouette
stage's rules (search every left/right flip, optimise free per-frame offsets)
would mirror a correctly labelled person standing still and shift a body by
centimetres to absorb detector noise.  Here, instead:

**Labels** (:func:`decide_flips`).  The labels as given are triangulated; a
view's joints are flipped (``"all"``, ``"arms"`` or ``"legs"``) only when the
evidence is decisive: the flip must cut the reprojection error of the
affected joints (over every view) to at most :data:`FLIP_MAX_RATIO` of what it
was *and* by more than :data:`FLIP_NOISE_FACTOR` times the detector noise of
the sequence (the median reprojection error of the labels as given).  Views
are flipped one at a time (the best first), and never all of them with the
same flip: that is the mirror image of the labels as given, which explains the
rays exactly as well.  With two views, flipping either explains the rays
equally; the one whose 3D result stays closer to the previous frame's is
flipped, else the one with the lower confidence.

**Offsets** (:func:`sequence_offsets`, :func:`offsets_cross_validation`).
Calibration error is static: one 2D offset per camera is estimated over all
frames at once (robust loss, the zero-mean prior of the multi-view stage as the
gauge).  It is kept only when it generalises across joints: offsets estimated
from half of the joints (interleaved folds) must lower the median reprojection
error of the *other* half, triangulated with them, by :data:`OFFSET_CV_MIN_GAIN`
(relative) and :data:`OFFSET_CV_MIN_GAIN_PX`.  A calibration error shifts
every joint of a view alike and passes; a detector's per-joint bias (hips
drawn low in one view, wrists late) does not generalise and is rejected.
Per-frame offsets (the silhouette stage's) remain available
(``offsets="frame"``).

The result says which offsets were used and why, and which views were flipped
in which frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.multiview.config import FLIP_MODES, MultiViewConfig
from toolkit.multiview.offsets import triangulate_views
from toolkit.multiview.selection import flip_permutation, select_multiview
from toolkit.observe import Observer, as_observer
from toolkit.skeleton import SKELETON_14, Skeleton

#: Offset modes: one per camera over the sequence (default), per frame (source 000's), or none.
OFFSET_MODES = ("sequence", "frame", "none")
#: A flip must leave at most this share of the affected joints' reprojection error.
FLIP_MAX_RATIO = 0.5
#: ... and lower it by more than this many times the detector noise (median reprojection error).
FLIP_NOISE_FACTOR = 1.5
#: Flip options whose remaining error is within this share (or one noise unit) of the best are tied.
FLIP_TIE_RATIO = 0.25
#: Sequence offsets are kept when the held-out joints' median reprojection error falls by this share ...
OFFSET_CV_MIN_GAIN = 0.10
#: ... and by at least this many pixels.
OFFSET_CV_MIN_GAIN_PX = 0.3
#: Robust loss scale of the sequence-offset fit, in units of the detector noise.
OFFSET_LOSS_SCALE = 2.0
#: At most this many frames enter the sequence-offset fit (evenly spaced), for speed.
OFFSET_FIT_FRAMES = 200
#: Gauge steps that put the offset-corrected body where the uncorrected one is.
GAUGE_ITERATIONS = 3
#: Smallest detector-noise estimate, pixels (exact synthetic keypoints have none).
MIN_NOISE_PX = 0.25


@dataclass(frozen=True)
class KeypointConfig:
    """Options of :func:`triangulate_keypoint_sequence`.

    Parameters
    ----------
    flips : tuple of str
        Flips tested per view and frame (subset of :data:`~toolkit.multiview.FLIP_MODES`);
        empty: the labels are always kept.
    offsets : {"sequence", "frame", "none"}
        ``"sequence"``: one offset per camera, kept only when it generalises across
        joints; ``"frame"``: per-frame offsets (source 000 §2.1); ``"none"``.
    multiview : MultiViewConfig
        The triangulation's options (robust mode, offset prior and bound, constraints).
    flip_max_ratio, flip_noise_factor : float
        The decisive-flip rule (see the module docstring).
    offset_cv_min_gain, offset_cv_min_gain_px : float
        The rule that keeps sequence offsets.
    """

    flips: tuple[str, ...] = FLIP_MODES
    offsets: str = "sequence"
    multiview: MultiViewConfig = field(default_factory=lambda: MultiViewConfig(flips=()))
    flip_max_ratio: float = FLIP_MAX_RATIO
    flip_noise_factor: float = FLIP_NOISE_FACTOR
    offset_cv_min_gain: float = OFFSET_CV_MIN_GAIN
    offset_cv_min_gain_px: float = OFFSET_CV_MIN_GAIN_PX

    def __post_init__(self):
        bad = [f for f in self.flips if f not in FLIP_MODES]
        if bad:
            raise InputError("KeypointConfig.flips", f"a subset of {FLIP_MODES}", repr(self.flips))
        if self.offsets not in OFFSET_MODES:
            raise InputError("KeypointConfig.offsets", f"one of {OFFSET_MODES}", repr(self.offsets))
        if not 0 < self.flip_max_ratio < 1:
            raise InputError("KeypointConfig.flip_max_ratio", "a value in (0, 1)", repr(self.flip_max_ratio))
        if self.flip_noise_factor < 0 or self.offset_cv_min_gain < 0 or self.offset_cv_min_gain_px < 0:
            raise InputError("KeypointConfig", "non-negative noise factor and gains",
                             f"{self.flip_noise_factor}, {self.offset_cv_min_gain}, {self.offset_cv_min_gain_px}")


@dataclass(frozen=True)
class OffsetDecision:
    """Which offsets a sequence got, and why.

    Attributes
    ----------
    mode : str
        The mode used: ``"sequence"``, ``"frame"`` or ``"none"``.
    offsets : ndarray of shape (n_views, 2)
        The sequence offsets estimated (also when rejected), pixels.
    kept : bool
        Whether they were applied (``mode == "sequence"``).
    heldout_px : tuple of float
        Median reprojection error of the held-out joints without and with offsets.
    reason : str
    """

    mode: str
    offsets: np.ndarray
    kept: bool
    heldout_px: tuple[float, float]
    reason: str


@dataclass(frozen=True)
class KeypointSequence:
    """Result of :func:`triangulate_keypoint_sequence`.

    Attributes
    ----------
    joints3d : ndarray of shape (T, n_joints, 3)
        Metres, NaN without an estimate.
    poses2d_raw : ndarray of shape (n_views, T, n_joints, 2)
        The keypoints used (flips applied), pixels; NaN where dropped.
    poses2d : ndarray of shape (n_views, T, n_joints, 2)
        Offset-corrected.
    offsets : ndarray of shape (T, n_views, 2)
        Pixels added to each view's keypoints; NaN where a view took no part.
    flips : ndarray of shape (T, n_views) of str
        Flip applied per frame and view ("" = labels as given).
    success : ndarray of shape (T,) of bool
    cost : ndarray of shape (T,)
        Mean ray distance, metres.
    reprojection_px : ndarray of shape (T,)
        Median reprojection error of the used rays, pixels.
    violations : list of tuple of str
        Broken anthropometric constraints per frame.
    noise_px : float
        Detector noise of the sequence: the median reprojection error of the labels as given.
    offset_decision : OffsetDecision
    interrupted : bool
        The final triangulation was stopped (Ctrl-C): frames not reached have ``success`` False.
    """

    joints3d: np.ndarray
    poses2d_raw: np.ndarray
    poses2d: np.ndarray
    offsets: np.ndarray
    flips: np.ndarray
    success: np.ndarray
    cost: np.ndarray
    reprojection_px: np.ndarray
    violations: list
    noise_px: float
    offset_decision: OffsetDecision
    interrupted: bool = False

    def flip_counts(self) -> dict:
        """Frames with a flip per view index: ``{view: {mode: frames}}`` (views never flipped left out)."""
        out: dict = {}
        for v in range(self.flips.shape[1]):
            for f in self.flips[:, v]:
                if f:
                    out.setdefault(v, {}).setdefault(str(f), 0)
                    out[v][str(f)] += 1
        return out


def _check(points2d, weights, rig: Rig, skeleton: Skeleton):
    p = np.asarray(points2d, float)
    if p.ndim != 4 or p.shape[-1] != 2 or p.shape[0] != len(rig) or p.shape[2] != skeleton.n_joints:
        raise InputError("points2d", f"an array of shape ({len(rig)}, T, {skeleton.n_joints}, 2)", f"shape {p.shape}")
    if np.isinf(p).any():
        raise InputError("points2d", "finite pixels or NaN", "infinite values")
    w = np.isfinite(p).all(-1).astype(float) if weights is None else np.asarray(weights, float)
    if w.shape != p.shape[:3]:
        raise InputError("weights", f"shape {p.shape[:3]}", f"shape {w.shape}")
    w = np.where(np.isfinite(p).all(-1) & np.isfinite(w), w, 0.0)
    if (w < 0).any():
        raise InputError("weights", "non-negative confidences", f"minimum {w.min()}")
    return np.where((w > 0)[..., None], p, np.nan), w


def _reprojection(rig: Rig, X: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(V, ..., J) pixel distances between ``uv`` (V, ..., J, 2) and the projections of X (..., J, 3)."""
    flat = X.reshape(-1, 3)
    proj = np.stack([cam.project(flat).reshape(X.shape[:-1] + (2,)) for cam in rig])
    return np.linalg.norm(proj - uv, axis=-1)


def triangulate_batch(rig: Rig, uv: np.ndarray, w: np.ndarray):
    """Closest points of many poses at once.

    Parameters
    ----------
    rig : Rig
    uv : ndarray of shape (V, T, J, 2)
    w : ndarray of shape (V, T, J)

    Returns
    -------
    X : ndarray of shape (T, J, 3)
        NaN with fewer than two rays.
    reprojection : ndarray of shape (V, T, J)
        Pixels; NaN where no ray or no point.
    """
    V, T, J = uv.shape[:3]
    _, _, X, _ = triangulate_views(rig, uv.reshape(V, T * J, 2), w.reshape(V, T * J))
    X = X.reshape(T, J, 3)
    e = _reprojection(rig, X, uv)
    return X, np.where(w > 0, e, np.nan)


def decide_flips(points2d: np.ndarray, weights: np.ndarray, rig: Rig, noise_px: float,
                 config: KeypointConfig = KeypointConfig(), skeleton: Skeleton = SKELETON_14,
                 previous_joints3d: np.ndarray | None = None) -> tuple[np.ndarray, list]:
    """The decisive flips of one frame (see the module docstring).

    Parameters
    ----------
    points2d : ndarray of shape (V, J, 2)
    weights : ndarray of shape (V, J)
    rig : Rig
    noise_px : float
        Detector noise of the sequence, pixels.
    config : KeypointConfig
    skeleton : Skeleton
    previous_joints3d : ndarray of shape (J, 3), optional
        The previous frame's joints (decides which of two views to flip).

    Returns
    -------
    points2d : ndarray of shape (V, J, 2)
        With the flips applied (weights follow their joints).
    flips : list of str
        Per view, the flip applied or "".
    """
    pts, w = np.asarray(points2d, float).copy(), np.asarray(weights, float).copy()
    V = len(pts)
    flips = [""] * V
    if not config.flips or (w > 0).any(axis=1).sum() < 2:
        return pts, flips
    perms = {f: flip_permutation(skeleton, f) for f in config.flips}
    used_views = [v for v in range(V) if (w[v] > 0).any()]
    for _ in range(2 * len(used_views)):  # never every view: that is the mirror of the labels as given
        _, e = triangulate_batch(rig, pts[:, None], w[:, None])
        options = []
        for f, perm in perms.items():
            moved = perm != np.arange(len(perm))
            for v in used_views:
                if flips[v] == "all" or flips[v] == f or (w[v, moved] <= 0).all():
                    continue
                if sum(1 for u in used_views if flips[u] == f or u == v) == len(used_views):
                    continue
                p2, w2 = pts.copy(), w.copy()
                p2[v], w2[v] = pts[v, perm], w[v, perm]
                X2, e2 = triangulate_batch(rig, p2[:, None], w2[:, None])
                before = np.nanmean(e[:, 0, moved]) if np.isfinite(e[:, 0, moved]).any() else np.nan
                after = np.nanmean(e2[:, 0, moved]) if np.isfinite(e2[:, 0, moved]).any() else np.nan
                if not (np.isfinite(before) and np.isfinite(after)):
                    continue
                if after > config.flip_max_ratio * before or before - after <= config.flip_noise_factor * noise_px:
                    continue
                total = float(np.nanmean(e2)) if np.isfinite(e2).any() else np.inf  # compares modes fairly
                prev = 0.0
                if previous_joints3d is not None:
                    d = np.linalg.norm(X2[0] - previous_joints3d, axis=-1)
                    prev = float(np.nanmean(d)) if np.isfinite(d).any() else 0.0
                options.append((total, prev, float(np.mean(w[v, moved])), v, f, p2, w2))
        if not options:
            break
        # options explaining the rays alike (two views: flipping either one) are told apart by the
        # previous frame's pose, then by flipping the less confident view
        low = min(o[0] for o in options)
        tied = [o for o in options if o[0] <= low + max(FLIP_TIE_RATIO * low, noise_px)]
        _, _, _, v, f, pts, w = min(tied, key=lambda o: (o[1], o[2], o[0]))
        flips[v] = "all" if flips[v] else f  # arms then legs make the whole flip
    return pts, flips


def sequence_offsets(points2d: np.ndarray, weights: np.ndarray, rig: Rig, noise_px: float,
                     config: MultiViewConfig = MultiViewConfig(flips=()),
                     joints: np.ndarray | None = None) -> np.ndarray:
    """One 2D offset per camera over the whole sequence (robust least squares).

    Parameters
    ----------
    points2d : ndarray of shape (V, T, J, 2)
    weights : ndarray of shape (V, T, J)
    rig : Rig
    noise_px : float
        Scale of the robust loss is ``OFFSET_LOSS_SCALE * noise_px``.
    config : MultiViewConfig
        Its offset prior (the gauge: the smallest offsets that explain the data) and bound.
    joints : ndarray of int, optional
        Only these joints enter the fit (cross-validation folds).

    Returns
    -------
    ndarray of shape (V, 2)
        Pixels added to each view's keypoints.
    """
    V, T = points2d.shape[:2]
    frames = np.unique(np.linspace(0, T - 1, min(T, OFFSET_FIT_FRAMES)).round().astype(int))
    uv, w = points2d[:, frames], weights[:, frames]
    if joints is not None:
        uv, w = uv[:, :, joints], w[:, :, joints]
    seen = (w > 0).sum(axis=0) >= 2  # (T', J) joints with two rays
    w = np.where(seen[None], w, 0.0)
    active = np.array([(w[v] > 0).any() for v in range(V)])
    if active.sum() < 2:
        return np.zeros((V, 2))
    sig = np.array([config.offset_prior_of(cam.name) for cam in rig], float)
    # the prior fixes the gauge (a 3D shift of the body moves every view's joints alike): weighed as in
    # one frame's fit, times the square root of the frames, so that it keeps doing so over a sequence
    prior_w = np.where(np.isfinite(sig), config.keypoint_sigma_px / sig, 0.0) * np.sqrt(len(frames))
    sw = np.sqrt(w)

    def residuals(p):
        O = np.where(active[:, None], p.reshape(V, 2), 0.0)
        shifted = uv + O[:, None, None, :]
        _, e = triangulate_batch(rig, shifted, w)
        r = np.nan_to_num(sw * e)
        return np.concatenate([r.ravel(), (O * prior_w[:, None]).ravel()])

    scale = max(OFFSET_LOSS_SCALE * noise_px, MIN_NOISE_PX)
    res = least_squares(residuals, np.zeros(2 * V), loss="soft_l1", f_scale=scale, diff_step=1e-3,
                        bounds=(-config.max_offset_px, config.max_offset_px))
    O = np.where(active[:, None], res.x.reshape(V, 2), 0.0)
    # The gauge: offsets cannot tell where the body is (a 3D shift moves every view alike), only how
    # its rays agree.  Keep the body where the calibration puts it: shift the offsets along the gauge
    # until the mean position of the joints equals that of the triangulation without offsets.
    X0, _ = triangulate_batch(rig, uv, w)
    for _ in range(GAUGE_ITERATIONS):
        X1, _ = triangulate_batch(rig, uv + O[:, None, None, :], w)
        ok = np.isfinite(X0).all(-1) & np.isfinite(X1).all(-1)
        if not ok.any():
            break
        delta = (X0[ok] - X1[ok]).mean(axis=0)
        if np.linalg.norm(delta) < 1e-5:
            break
        P = X1[ok]
        shift = np.stack([(cam.project(P + delta) - cam.project(P)).mean(axis=0) for cam in rig])
        O = np.where(active[:, None], O + shift, 0.0)
    return O


def offsets_cross_validation(points2d: np.ndarray, weights: np.ndarray, rig: Rig, noise_px: float,
                             config: MultiViewConfig = MultiViewConfig(flips=())) -> tuple[float, float]:
    """Median reprojection error of held-out joints without and with offsets fitted on the others.

    Two interleaved folds of joints (even and odd indices); each fold's offsets are
    fitted on it and judged on the other fold, whose joints are triangulated with them.

    Returns
    -------
    (without, with) : tuple of float
        Pixels, over both folds; NaN when no joint could be held out.
    """
    J = points2d.shape[2]
    folds = [np.arange(0, J, 2), np.arange(1, J, 2)]
    before, after = [], []
    for fit_j, test_j in (folds, folds[::-1]):
        O = sequence_offsets(points2d, weights, rig, noise_px, config, joints=fit_j)
        uv, w = points2d[:, :, test_j], weights[:, :, test_j]
        _, e0 = triangulate_batch(rig, uv, w)
        _, e1 = triangulate_batch(rig, uv + O[:, None, None, :], w)
        before.append(e0[np.isfinite(e0)])
        after.append(e1[np.isfinite(e1)])
    b, a = np.concatenate(before), np.concatenate(after)
    if not len(b) or not len(a):
        return float("nan"), float("nan")
    return float(np.median(b)), float(np.median(a))


def _decide_sequence_flips(pts: np.ndarray, w: np.ndarray, rig: Rig, noise: float, config: KeypointConfig,
                           skeleton: Skeleton, obs, frames: np.ndarray) -> np.ndarray:
    """Decide each frame's left/right flips (decisive ones only) and apply them to ``pts`` and ``w`` in place.

    Parameters
    ----------
    pts : ndarray of shape (n_views, T, n_joints, 2)
        Keypoints, pixels; relabelled in place.
    w : ndarray of shape (n_views, T, n_joints)
        Weights; permuted in place with the keypoints.
    rig : Rig
    noise : float
        Detector noise, pixels.
    config : KeypointConfig
    skeleton : Skeleton
    obs : Observer
        Receives a ``text`` per frame with flips.
    frames : ndarray of shape (T,)
        Frame indices for the reports.

    Returns
    -------
    ndarray of object, shape (T, n_views)
        The flip applied to each view in each frame ("" none).
    """
    V, T = pts.shape[:2]
    flips = np.full((T, V), "", dtype=object)
    prev = None
    for t in range(T):
        p2, f = decide_flips(pts[:, t], w[:, t], rig, noise, config, skeleton, prev)
        if any(f):
            perms = {m: flip_permutation(skeleton, m) for m in set(f) if m}
            for v, m in enumerate(f):
                if m:
                    w[v, t] = w[v, t, perms[m]]
            pts[:, t] = p2
            flips[t] = f
            obs.report("text", name="keypoints/flips", frame=int(frames[t]),
                       text=", ".join(f"{rig[v].name}: {m}" for v, m in enumerate(f) if m))
        Xt, _ = triangulate_batch(rig, pts[:, t:t + 1], w[:, t:t + 1])
        if np.isfinite(Xt[0]).any():
            prev = Xt[0]

    return flips


def _offset_decision(pts: np.ndarray, w: np.ndarray, rig: Rig, noise: float,
                     config: KeypointConfig) -> tuple[OffsetDecision, np.ndarray]:
    """Sequence offsets, kept only when they lower the held-out joints' reprojection error enough.

    Parameters
    ----------
    pts : ndarray of shape (n_views, T, n_joints, 2)
    w : ndarray of shape (n_views, T, n_joints)
    rig : Rig
    noise : float
        Detector noise, pixels.
    config : KeypointConfig

    Returns
    -------
    decision : OffsetDecision
    O_seq : ndarray of shape (n_views, 2)
        The sequence offsets fitted (zeros unless ``config.offsets == "sequence"``), pixels.
    """
    V = pts.shape[0]
    O_seq = np.zeros((V, 2))
    heldout = (float("nan"), float("nan"))
    if config.offsets == "sequence":
        heldout = offsets_cross_validation(pts, w, rig, noise, config.multiview)
        O_seq = sequence_offsets(pts, w, rig, noise, config.multiview)
        gain = heldout[0] - heldout[1]
        kept = bool(np.isfinite(gain) and gain > config.offset_cv_min_gain * heldout[0]
                    and gain > config.offset_cv_min_gain_px)
        reason = (f"held-out joints' median reprojection error {heldout[0]:.2f} px without offsets, "
                  f"{heldout[1]:.2f} px with offsets fitted on the other joints: "
                  + ("they generalise, kept" if kept else
                     f"not lower by {100 * config.offset_cv_min_gain:.0f} % and {config.offset_cv_min_gain_px} px, "
                     "rejected (what they fit is detector noise, not calibration)"))
        decision = OffsetDecision("sequence" if kept else "none", O_seq, kept, heldout, reason)
    elif config.offsets == "frame":
        decision = OffsetDecision("frame", O_seq, False, heldout, "per-frame offsets asked for (offsets='frame')")
    else:
        decision = OffsetDecision("none", O_seq, False, heldout, "no offsets asked for (offsets='none')")
    return decision, O_seq


def triangulate_keypoint_sequence(points2d: np.ndarray, rig: Rig, config: KeypointConfig = KeypointConfig(), *,
                                  weights: np.ndarray | None = None, observer: Observer | None = None,
                                  skeleton: Skeleton = SKELETON_14, frames: np.ndarray | None = None
                                  ) -> KeypointSequence:
    """3D joints of one person from every view's keypoints over a sequence.

    Parameters
    ----------
    points2d : ndarray of shape (n_views, T, n_joints, 2)
        Keypoints in pixels, rig order; NaN = missing.
    rig : Rig
    config : KeypointConfig
    weights : ndarray of shape (n_views, T, n_joints), optional
        Detector confidences (0 drops a keypoint).
    observer : Observer, optional
        Receives, per frame, the multi-view selection's reports (rays, offsets, joints) and
        the flips; once, the offset decision.
    skeleton : Skeleton
    frames : ndarray of shape (T,), optional
        Frame indices for the reports (default 0..T-1).

    Returns
    -------
    KeypointSequence

    Raises
    ------
    InputError
        Arrays of the wrong shape, infinite pixels, negative weights.
    """
    obs = as_observer(observer)
    pts, w = _check(points2d, weights, rig, skeleton)
    V, T, J = pts.shape[:3]
    frames = np.arange(T) if frames is None else np.asarray(frames)

    # detector noise: the labels as given, no offsets
    _, e0 = triangulate_batch(rig, pts, w)
    noise = max(float(np.nanmedian(e0)) if np.isfinite(e0).any() else MIN_NOISE_PX, MIN_NOISE_PX)

    # labels: decisive flips only, frame by frame
    flips = _decide_sequence_flips(pts, w, rig, noise, config, skeleton, obs, frames)

    # offsets
    decision, O_seq = _offset_decision(pts, w, rig, noise, config)
    obs.report("text", name="keypoints/offsets", text=decision.reason + "; offsets (px): " + ", ".join(
        f"{cam.name} ({o[0]:+.1f}, {o[1]:+.1f})" for cam, o in zip(rig, O_seq)))

    # final triangulation, frame by frame (robust mode, constraints, reports)
    fixed = O_seq if decision.kept else np.zeros((V, 2))
    frame_cfg = replace(config.multiview, flips=(), optimise_offsets=config.offsets == "frame")
    joints = np.full((T, J, 3), np.nan)
    raw = np.full((V, T, J, 2), np.nan)
    corr = np.full((V, T, J, 2), np.nan)
    offs = np.full((T, V, 2), np.nan)
    success = np.zeros(T, bool)
    cost = np.full(T, np.nan)
    rep = np.full(T, np.nan)
    viol = [()] * T
    init = fixed
    interrupted = False
    for t in range(T):
        try:
            sel = select_multiview(pts[:, t, None], rig, frame_cfg, weights=w[:, t, None], initial_offsets=init,
                                   observer=observer, frame=int(frames[t]), skeleton=skeleton)
        except KeyboardInterrupt:  # a long run keeps the frames it finished
            interrupted = True
            break
        if sel.success:
            joints[t], raw[:, t], corr[:, t] = sel.joints3d, sel.poses2d_raw, sel.poses2d
            offs[t] = np.where(sel.views_used[:, None], sel.offsets, np.nan)
            success[t], cost[t], viol[t] = True, sel.cost, sel.violations
            r = sel.reprojection_errors
            rep[t] = float(np.nanmedian(r)) if np.isfinite(r).any() else np.nan
            if config.offsets == "frame":
                init = np.where(sel.views_used[:, None], sel.offsets, init)
    return KeypointSequence(joints, raw, corr, offs, flips, success, cost, rep, viol, noise, decision, interrupted)
