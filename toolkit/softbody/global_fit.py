"""Global fit over all frames at once: postures, segment lengths and metaball widths (source 002).

The tracked postures start the fit; the state vector holds every frame's 27
pose values plus the 13 lengths and 7 widths shared by all frames.  Residual
blocks, per frame: the robust point-to-surface distances and the coverage
block of :mod:`toolkit.softbody.residuals`; over frames: a small term
favouring constant angular speed (second differences of the joint angles and
of the root rotation over consecutive frames, as in the source); a pull of
each frame's root (the pelvis, buried in the trunk and thighs) towards the
tracked one; and priors on the shape: widths and lengths near the start
(the lengths of the joints buried in the torso, more strongly, near the
median body's), left and right limbs alike, each limb's split (thigh /
shank, upper arm / forearm) near the median body's ratio, which the surface
of a straight limb does not show, and each arm near its anthropometric share
of the stature chain, which stereo points without hands do not show.  The
data are the same points per frame as tracking's (``max_points`` as
:class:`~toolkit.softbody.track.TrackConfig`'s): a well-tracked pose is then
already an optimum of the global objective's pose part and stays put.
Each frame's residuals depend on its own pose and the shared shape only, so
the Jacobian is assembled as a ``scipy.sparse`` matrix and
``least_squares(method="trf", tr_solver="lsmr")`` solves it without forming a
dense matrix: hundreds of frames stay tractable (a frame of 1000 points adds
about 1 MB of Jacobian entries and their indices).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from toolkit.errors import InputError
from toolkit.observe import Observer, as_observer
from toolkit.softbody.distance import check_points
from toolkit.softbody.model import (LENGTH_NAMES, N_PARAMS, N_POSE, STATURE_CHAIN, SYMMETRIC_LENGTHS, SoftBodyModel,
                                    TRUNK_POSTURE, SoftBodyParams, continuous_poses, pose_bounds)
from toolkit.softbody.residuals import (LOSSES, CoverageSamples, coverage_residuals, coverage_samples, data_residuals, gate_points,
                                        coverage_margin,
                                        one_blas_thread)
from toolkit.softbody.silhouette import SilhouetteBlock
from toolkit.softbody.track import SoftBodyTrack, part_support, subsample

__all__ = ["GlobalFitConfig", "SoftBodyFit", "global_fit"]

_N_SHAPE = N_PARAMS - N_POSE  # 20 shared values: lengths then widths
_ANGLES = np.r_[0:3, 6:N_POSE]  # root rotation and joint angles: the constant-angular-speed term
_SYM = SYMMETRIC_LENGTHS  # left and right limb lengths tied by the symmetry prior
#: Proximal and distal segment of each limb (indices into LENGTH_NAMES) tied by the split prior.
_SPLIT = np.array([[LENGTH_NAMES.index(f"{s}_{a}"), LENGTH_NAMES.index(f"{s}_{b}")]
                   for s in ("l", "r") for a, b in (("upper_arm", "forearm"), ("thigh", "shank"))])
#: Upper arm and forearm of each arm (indices into LENGTH_NAMES) tied to the stature chain by the proportion prior.
_ARMS = np.array([[LENGTH_NAMES.index(f"{s}_upper_arm"), LENGTH_NAMES.index(f"{s}_forearm")] for s in ("l", "r")])
_CHAIN = STATURE_CHAIN  # torso, neck to head, the mean leg: weights on LENGTH_NAMES
#: Lengths ending in a joint buried in the torso (neck, shoulders, hips): seen through the surface only weakly.
_BURIED = np.array([LENGTH_NAMES.index(n) for n in ("neck_to_head", "shoulder_half_width", "shoulder_drop",
                                                      "hip_half_width")])


@dataclass(frozen=True)
class GlobalFitConfig:
    """Settings of the global fit.

    Attributes
    ----------
    loss, f_scale : str, float
        Robust loss of the point-to-surface block and its scale (metres).
    coverage_weight, coverage_scale, coverage_margin, coverage_dirs, viewpoints
        The coverage block, as in :class:`toolkit.softbody.track.TrackConfig`.
    coverage_allowance : bool
        Each coverage sample may stay as far from the cloud as it was in the
        tracked pose (:meth:`toolkit.softbody.residuals.CoverageSamples.allowing`):
        surface the cameras gave no points for (the hands' skin in stereo) is
        not pulled into the nearest points.  Without it the coverage of the
        hands shortened the arms (trinocular scenes: upper arms and forearms
        30-50 mm shorter than at the start).
    gate : float
        Points further than this outside the tracked model are ignored, metres.
    max_points : int
        Points per frame (an even subsample): as many as tracking uses.  With
        300 of about 900 stereo patch centres the tracked poses were no optimum
        of the global objective: it moved them by 3-4 mm (on noisy model points;
        on a trinocular wave 34.7 -> 37.2 mm MPJPE with the shape held) and the
        widths fitted the subsample's noise.
    unseen_weight, part_points, part_distance
        As in :class:`toolkit.softbody.track.TrackConfig`: per frame, the
        angles of parts with fewer than ``part_points`` points are pulled to
        the tracked ones and those parts get no coverage block (a leg
        without points shrank by 17 cm into the thigh's points).
    root_prior_weight : float
        Pull of each frame's root (rotation, radians, and translation, metres)
        towards the tracked root, metres per unit.  The mid-hip point is
        buried: with the lengths free, the pelvis slid 15 cm up into the trunk
        (the thighs 13 cm longer, the trunk leaning against it) on a
        trinocular kick, and fitted the points better in every frame while the
        hips ended 15 cm off.  At 1 m/m a root correction of a few centimetres
        still goes through (on that kick the root rose 29 mm, where tracking
        had the hips 21-25 mm low).
    smooth_weight : float
        Weight of the constant-angular-speed residuals, metres per radian per
        frame squared: small, so that it does not degrade the fit (source 002).
    width_prior_weight : float
        Pull of the widths towards the start values (metres per unit
        multiplier).  The reference radii match the synthetic bodies within
        4 % (:mod:`toolkit.softbody.model`); at 0.02 the stereo noise
        around the thin limbs blew the forearms up to 1.6-1.8 and the elbows
        and wrists moved with them.
    length_prior_weight : float
        Pull of the lengths towards the start (metres per metre): the joints
        buried in the torso (shoulders, hips) are weakly observable from the
        surface alone.
    symmetry_weight : float
        Pull of each left limb length towards the right one (metres per metre;
        0: independent sides).
    split_weight : float
        Pull of each limb's split (upper arm / forearm, thigh / shank) towards
        a reference ratio, on the residual ``proximal - ratio * distal``
        (metres per metre).  The surface of a
        straight limb shows its whole length but not where the elbow or knee
        is: without it the fit slid the knees along straight legs (thighs
        +75 mm, shanks -80 mm on a depth wave).  Bent frames still move the
        split (their surface shows the joint).
    split_reference : {"start", "anthropometric"}
        The reference ratio: the start lengths' (the initial joints mark the
        elbows and knees: clicked, or the depth tracker's) or the median
        body's of the model's stature (:class:`toolkit.anthropometry.BodyProportions`;
        people differ from it by up to 10 %: measured thigh / shank 0.90-1.02
        against 0.98).
    proportion_weight : float
        Pull of each arm's length (upper arm + forearm) towards the
        anthropometric share of the stature chain (torso, neck to head, mean
        leg; :data:`toolkit.anthropometry.STATURE_RATIOS`), on the residual
        ``arm - ratio * chain`` (metres per metre; 0: none).  Stereo clouds
        have almost no points on the hands: nothing in the points holds the
        wrist, the model's hand slides back over the last forearm points at no
        cost and the arms came out 40-76 mm short; the chain is seen densely
        (trunk, legs) and holds them.  People differ from the median ratio by
        a few per cent (about 2-3 cm of arm); where the points are dense
        (depth) they outweigh it.
    buried_prior_weight : float
        Pull of the lengths that end in a joint buried in the torso (neck to
        head, shoulder width and drop, hip width) towards ``buried_reference``,
        replacing ``length_prior_weight`` for them (metres per metre): the
        coverage block otherwise widened the shoulders into the arms' points,
        and the neck slides along the spine at no cost (trunk shorter, neck to
        head longer: the clicked neck's error stayed in both).  At 3 the stereo
        fits still sank the neck into the trunk (seen seed 11000: shoulder
        drop 15-52 mm short, torso 7-70 mm short, neck to head +20 mm); at 10
        (746a094, chosen on seeds 11000 and 12000): stereo bones 15.1 ->
        13.0 mm, MPJPE 24.5 -> 23.8 mm, depth 13.3 -> 12.8 mm (medians of 16
        and 8 runs).  The synthetic bodies' buried lengths lie within 9 mm of
        the reference, people's within about 1 cm.
    buried_reference : {"anthropometric", "start"}
        The buried lengths' reference: the median body's share of the stature
        chain (:class:`toolkit.anthropometry.BodyProportions`) times the chain
        of the lengths being fitted (torso, neck to head, mean leg), so that
        it follows the fitted stature rather than the start's (clicked
        statures were 5-11 cm off); the synthetic bodies differ from it by
        up to 6 % a length (neck to head within 6 mm), people by about as
        much (1 cm of shoulder width).  Or the start's lengths.  Clicked
        shoulders are off by 1.5-3 cm (3 px at 3 m), and with the start's
        reference that error stayed in the fitted lengths (a trinocular
        crouch: both neck-to-shoulder bones +44 mm).
    fit_lengths, fit_widths : bool
        Which shape blocks are free.
    max_nfev : int
        Evaluations of the whole problem.
    silhouette_weight : float
        Weight of the silhouette blocks (:mod:`toolkit.softbody.silhouette`) of the
        frames with masks given; 0: not used.
    posture_weight : float
        Pull of each frame's trunk bend and twist against the pelvis towards
        0, metres per radian (as :class:`toolkit.softbody.track.TrackConfig`,
        whose entry gives the measurements).
    """

    loss: str = "soft_l1"
    f_scale: float = 0.02
    coverage_weight: float = 0.3
    coverage_scale: float = 0.05
    coverage_margin: float = 0.03
    coverage_dirs: int = 16
    coverage_allowance: bool = True
    viewpoints: tuple | None = None
    gate: float = 0.25
    max_points: int = 1000
    unseen_weight: float = 0.3
    part_points: int = 10
    part_distance: float = 0.06
    root_prior_weight: float = 1.0
    smooth_weight: float = 0.02
    width_prior_weight: float = 0.5
    length_prior_weight: float = 0.5
    symmetry_weight: float = 2.0
    split_weight: float = 3.0
    split_reference: str = "anthropometric"
    proportion_weight: float = 1.0
    buried_prior_weight: float = 10.0
    buried_reference: str = "anthropometric"
    fit_lengths: bool = True
    fit_widths: bool = True
    max_nfev: int = 40
    silhouette_weight: float = 1.0
    posture_weight: float = 0.2

    def __post_init__(self):
        if self.loss not in LOSSES:
            raise InputError("GlobalFitConfig.loss", f"one of {LOSSES}", repr(self.loss))
        if self.buried_reference not in ("start", "anthropometric"):
            raise InputError("GlobalFitConfig.buried_reference", "'start' or 'anthropometric'",
                             repr(self.buried_reference))
        if self.split_reference not in ("start", "anthropometric"):
            raise InputError("GlobalFitConfig.split_reference", "'start' or 'anthropometric'",
                             repr(self.split_reference))
        if not (np.isfinite(self.posture_weight) and self.posture_weight >= 0):
            raise InputError("GlobalFitConfig.posture_weight", "a finite weight >= 0 (metres per radian)",
                             repr(self.posture_weight))
        if not (self.f_scale > 0 and self.gate > 0 and self.max_points > 0):
            raise InputError("GlobalFitConfig", "positive f_scale, gate and max_points",
                             f"{self.f_scale}, {self.gate}, {self.max_points}")


@dataclass(frozen=True)
class SoftBodyFit:
    """Result of the global fit.

    Attributes
    ----------
    params : ndarray of shape (T, 47)
        Per-frame parameter vectors (the shape block equal in every frame).
    joints : ndarray of shape (T, 14, 3)
        Metres, world.
    lengths : ndarray of shape (13,)
        Metres, :data:`~toolkit.softbody.LENGTH_NAMES`.
    widths : ndarray of shape (7,)
    states : tuple of str
        The tracking states (frames without points had no data term).
    lengths_history : ndarray of shape (n_iterations + 1, 13)
        The lengths at the start and after each Jacobian evaluation (iteration).
    cost_history : ndarray of shape (n_iterations + 1,)
    success : bool
        ``least_squares`` met a convergence test (False: stopped at ``max_nfev``
        or nothing to fit).
    message : str
    """

    params: np.ndarray
    joints: np.ndarray
    lengths: np.ndarray
    widths: np.ndarray
    states: tuple
    lengths_history: np.ndarray
    cost_history: np.ndarray
    success: bool
    message: str

    def frame_params(self, t: int) -> SoftBodyParams:
        return SoftBodyParams(self.params[t])


class _Problem:
    """Residuals and sparse Jacobian of the global fit."""

    def __init__(self, model, track: SoftBodyTrack, clouds, config: GlobalFitConfig, silhouettes=None):
        self.model, self.config = model, config
        self.sil = {} if silhouettes is None or config.silhouette_weight <= 0 else {
            t: SilhouetteBlock(model, SoftBodyParams(track.params[t]), v) for t, v in enumerate(silhouettes)
            if v and track.states[t] == "ok"}
        self.T = len(track.params)
        self.shape0 = track.params[0, N_POSE:].copy()
        self.free_shape = np.r_[np.full(13, config.fit_lengths), np.full(7, config.fit_widths)]
        self.frames = []  # (t, points, tree, coverage samples, coverage margin)
        self.pose0 = track.params[:, :N_POSE].copy()
        self.unseen_w = np.zeros((self.T, N_POSE))  # pull of poorly seen parts' angles to the tracked ones
        for t in range(self.T):
            # a frame without data of its own (not ok, or no points near the model) is held at its tracked
            # pose: only the constant-angular-speed term tied its angles and nothing its root translation
            # (a stereo walk's 5 crowded frames, left free, drifted 0.4-0.8 m off; tracking had them
            # within 47 mm)
            self.unseen_w[t] = config.unseen_weight
            self.unseen_w[t, :6] = config.root_prior_weight
            if track.states[t] != "ok":
                continue
            p = SoftBodyParams(track.params[t])
            pts = check_points(clouds[t], f"clouds[{t}]")
            pts = subsample(pts[gate_points(model, p, pts, config.gate)], config.max_points)
            if len(pts) == 0:
                continue
            support = part_support(model, p, pts, config.part_distance)
            samples = coverage_samples(model, p, n_dirs=config.coverage_dirs, viewpoints=config.viewpoints) \
                if config.coverage_weight > 0 else None
            if samples is not None:  # coverage only from parts with points of their own (as in tracking)
                keep = support[model.prim_frame[samples.prims]] >= config.part_points
                samples = CoverageSamples(samples.prims[keep], samples.dirs[keep])
            tree = cKDTree(pts)
            if samples is not None and config.coverage_allowance:  # surface without points is not pulled in
                samples = samples.allowing(model.state(p), tree)
            self.frames.append((t, pts, tree, samples, coverage_margin(tree, pts, config.coverage_margin)))
            missing = np.clip(1.0 - (model.subtree[model.state(p).dof_frames] @ support) / max(config.part_points, 1),
                              0.0, 1.0)
            self.unseen_w[t] = config.unseen_weight * missing
            self.unseen_w[t, :6] = config.root_prior_weight
        self.n = self.T * N_POSE + _N_SHAPE
        ref = self.shape0[:13] if config.split_reference == "start" else \
            model.lengths_from_proportions(model.proportions)
        self.split_ratio = ref[_SPLIT[:, 0]] / ref[_SPLIT[:, 1]]
        anth = model.lengths_from_proportions(model.proportions)
        self.arm_ratio = anth[_ARMS].sum(1) / (_CHAIN @ anth)  # (2,) arm length per metre of stature chain
        self.len_w = np.full(13, config.length_prior_weight)
        self.len_w[_BURIED] = config.buried_prior_weight
        # the length prior's residual: length - len_ref - len_chain * (stature chain of the current lengths)
        self.len_ref = self.shape0[:13].copy()
        self.len_chain = np.zeros(13)
        if config.buried_reference == "anthropometric":
            self.len_ref[_BURIED] = 0.0
            self.len_chain[_BURIED] = anth[_BURIED] / (_CHAIN @ anth)

    def unpack(self, z):
        return z[:self.T * N_POSE].reshape(self.T, N_POSE), z[self.T * N_POSE:]

    def evaluate(self, z, with_jac=True):
        poses, shape = self.unpack(z)
        c = self.config
        rows, blocks, res = 0, [], []
        cols_frame = lambda t: np.r_[t * N_POSE + np.arange(N_POSE), self.T * N_POSE + np.arange(_N_SHAPE)]  # noqa
        allc = np.arange(N_PARAMS)
        for t, pts, tree, samples, margin in self.frames:
            p = SoftBodyParams(np.r_[poses[t], shape])
            st = self.model.state(p)
            r, J = data_residuals(self.model, p, pts, st, allc, c.loss, c.f_scale, with_jac)
            rr, JJ = [r], [J]
            if samples is not None:
                rc, Jc = coverage_residuals(self.model, st, samples, tree, pts, allc, "cauchy", c.coverage_scale,
                                            margin, with_jac)
                w = np.sqrt(c.coverage_weight)
                rr.append(w * rc)
                JJ.append(None if Jc is None else w * Jc)
            if t in self.sil:
                rs, Js = self.sil[t].residuals(p, st, allc, with_jac)
                rr.append(np.sqrt(c.silhouette_weight) * rs)
                JJ.append(None if Js is None else np.sqrt(c.silhouette_weight) * Js)
            r = np.concatenate(rr)
            res.append(r)
            if with_jac:
                J = np.vstack(JJ)
                J[:, N_POSE:] *= self.free_shape
                blocks.append((rows, J, cols_frame(t)))
            rows += len(r)
        # constant angular speed: second differences over consecutive frames
        if self.T >= 3 and c.smooth_weight > 0:
            a = poses[:, _ANGLES]
            dd = c.smooth_weight * (a[:-2] - 2 * a[1:-1] + a[2:])
            res.append(dd.ravel())
            n_sm = dd.size
            k = np.arange(len(_ANGLES))
            t = np.arange(self.T - 2)
            r_idx = (t[:, None] * len(_ANGLES) + k[None]).ravel() + rows
            sm = [(r_idx, ((t[:, None] + o) * N_POSE + _ANGLES[None]).ravel(), c.smooth_weight * w)
                  for o, w in ((0, 1.0), (1, -2.0), (2, 1.0))]
            rows += n_sm
        else:
            sm = []
        uw = self.unseen_w.ravel()
        res.append(uw * (poses - self.pose0).ravel())
        unseen_rows = rows + np.arange(uw.size)
        rows += uw.size
        wq = c.posture_weight
        res.append(wq * poses[:, TRUNK_POSTURE].ravel())
        posture_rows = rows + np.arange(self.T * len(TRUNK_POSTURE))
        posture_cols = (np.arange(self.T)[:, None] * N_POSE + TRUNK_POSTURE[None]).ravel()
        rows += len(posture_rows)
        wp = c.width_prior_weight
        res.append(wp * (shape[13:] - self.shape0[13:]))
        prior_rows = rows + np.arange(7)
        rows += 7
        wl = self.len_w if c.fit_lengths else np.zeros(13)
        res.append(wl * (shape[:13] - self.len_ref - self.len_chain * (_CHAIN @ shape[:13])))
        len_rows = rows + np.arange(13)
        rows += 13
        ws = c.symmetry_weight if c.fit_lengths else 0.0
        res.append(ws * (shape[_SYM[:, 0]] - shape[_SYM[:, 1]]))
        sym_rows = rows + np.arange(len(_SYM))
        rows += len(_SYM)
        wr = c.split_weight if c.fit_lengths else 0.0
        res.append(wr * (shape[_SPLIT[:, 0]] - self.split_ratio * shape[_SPLIT[:, 1]]))
        split_rows = rows + np.arange(len(_SPLIT))
        rows += len(_SPLIT)
        wa = c.proportion_weight if c.fit_lengths else 0.0
        res.append(wa * (shape[_ARMS].sum(1) - self.arm_ratio * (_CHAIN @ shape[:13])))
        prop_rows = rows + np.arange(len(_ARMS))
        rows += len(_ARMS)
        r = np.concatenate(res)
        if not with_jac:
            return r, None
        ri, ci, vals = [], [], []
        for r0, J, cols in blocks:
            ri.append(np.repeat(np.arange(r0, r0 + len(J)), J.shape[1]))
            ci.append(np.tile(cols, len(J)))
            vals.append(J.ravel())
        for r_idx, c_idx, v in sm:
            ri.append(r_idx)
            ci.append(c_idx)
            vals.append(np.full(len(r_idx), v))
        ri.append(unseen_rows)
        ci.append(np.arange(uw.size))
        vals.append(uw)
        ri.append(posture_rows)
        ci.append(posture_cols)
        vals.append(np.full(len(posture_rows), wq))
        if c.fit_widths:
            ri.append(prior_rows)
            ci.append(self.T * N_POSE + 13 + np.arange(7))
            vals.append(np.full(7, wp))
        if np.any(wl > 0):
            dl = np.diag(wl) - (wl * self.len_chain)[:, None] * _CHAIN[None]  # (13, 13)
            ri.append(np.repeat(len_rows, 13))
            ci.append(np.tile(self.T * N_POSE + np.arange(13), 13))
            vals.append(dl.ravel())
        if ws > 0:
            for side, sign in ((0, 1.0), (1, -1.0)):
                ri.append(sym_rows)
                ci.append(self.T * N_POSE + _SYM[:, side])
                vals.append(np.full(len(_SYM), sign * ws))
        if wr > 0:
            ri += [split_rows, split_rows]
            ci += [self.T * N_POSE + _SPLIT[:, 0], self.T * N_POSE + _SPLIT[:, 1]]
            vals += [np.full(len(_SPLIT), wr), -wr * self.split_ratio]
        if wa > 0:
            dp = -wa * self.arm_ratio[:, None] * _CHAIN[None]  # (2, 13)
            dp[np.arange(len(_ARMS))[:, None], _ARMS] += wa
            ri.append(np.repeat(prop_rows, 13))
            ci.append(np.tile(self.T * N_POSE + np.arange(13), len(_ARMS)))
            vals.append(dp.ravel())
        J = sp.csr_matrix((np.concatenate(vals), (np.concatenate(ri), np.concatenate(ci))), shape=(rows, self.n))
        return r, J


def global_fit(model: SoftBodyModel, track: SoftBodyTrack, clouds, *, config: GlobalFitConfig = GlobalFitConfig(),
               observer: Observer | None = None, silhouettes=None) -> SoftBodyFit:
    """Refine all postures and the shared lengths and widths against all clouds at once.

    Parameters
    ----------
    model : SoftBodyModel
    track : SoftBodyTrack
        Tracking result: the start of every posture and of the shape (frame 0's lengths and widths).
    clouds : sequence of array_like of shape (N_t, 3)
        The clouds tracked, metres, world.
    config : GlobalFitConfig
    silhouettes : sequence of (list of SilhouetteView or None), optional
        Per frame, the cameras' silhouettes (used with ``config.silhouette_weight > 0``).
    observer : Observer, optional
        Receives ``series`` reports ``softbody/global/lengths/<name>`` (each
        length over the iterations, metres), ``softbody/global/cost`` and a ``text`` summary.

    Returns
    -------
    SoftBodyFit

    Raises
    ------
    InputError
        If ``clouds`` and ``track`` differ in length.
    """
    obs = as_observer(observer)
    if len(clouds) != len(track.params):
        raise InputError("clouds", f"{len(track.params)} clouds (one per tracked frame)", f"{len(clouds)}")
    if silhouettes is not None and len(silhouettes) != len(track.params):
        raise InputError("silhouettes", f"{len(track.params)} entries (one per tracked frame)", f"{len(silhouettes)}")
    if len(track.params) > 1:  # no 2 pi jumps between frames: the constant-speed term acts on differences
        params = track.params.copy()
        params[:, :N_POSE] = continuous_poses(params[:, :N_POSE])
        track = dataclasses.replace(track, params=params)
    prob = _Problem(model, track, clouds, config, silhouettes)
    z0 = np.r_[track.params[:, :N_POSE].ravel(), prob.shape0] if len(track.params) else np.zeros(0)
    hist_len, hist_cost = [], []
    if not prob.frames:
        return _result(model, track, z0, prob, [prob.shape0[:13]], [0.0], False, "no frame with points")
    lo_p, hi_p = pose_bounds()
    lo = np.r_[np.tile(lo_p, prob.T), np.full(13, 0.01), np.full(7, 0.3)]
    hi = np.r_[np.tile(hi_p, prob.T), np.full(13, 1.5), np.full(7, 3.0)]
    z0 = np.clip(z0, lo + 1e-9, hi - 1e-9)
    cache = {}

    def evaluate(z, with_jac=False):
        key = z.tobytes()
        if key not in cache or (with_jac and cache[key][1] is None):
            cache.clear()
            cache[key] = prob.evaluate(z, with_jac)
        return cache[key]

    def jac(z):
        r, J = evaluate(z, True)
        hist_len.append(prob.unpack(z)[1][:13].copy())
        hist_cost.append(0.5 * float(r @ r))
        return J

    with one_blas_thread():
        res = least_squares(lambda z: evaluate(z)[0], z0, jac=jac, bounds=(lo, hi), method="trf",
                            tr_solver="lsmr", loss="linear", x_scale="jac", max_nfev=config.max_nfev)
    r = evaluate(res.x)[0]
    hist_len.append(prob.unpack(res.x)[1][:13].copy())
    hist_cost.append(0.5 * float(r @ r))
    hl = np.array(hist_len)
    for i, name in enumerate(LENGTH_NAMES):
        obs.report("series", name=f"softbody/global/lengths/{name}", values=hl[:, i], static=True)
    obs.report("series", name="softbody/global/cost", values=np.array(hist_cost), static=True)
    obs.report("text", text=f"global fit: {len(prob.frames)} frames with points, {len(hl) - 1} iterations, "
                            f"cost {hist_cost[0]:.4g} -> {hist_cost[-1]:.4g} ({res.message})", static=True)
    return _result(model, track, res.x, prob, hist_len, hist_cost, bool(res.status > 0), str(res.message))


def _result(model, track, z, prob, hist_len, hist_cost, success, message) -> SoftBodyFit:
    poses, shape = prob.unpack(z)
    params = np.hstack([poses, np.tile(shape, (prob.T, 1))])
    joints = np.stack([model.joints(SoftBodyParams(v)) for v in params]) if prob.T else np.zeros((0, 14, 3))
    return SoftBodyFit(params, joints, shape[:13].copy(), shape[13:].copy(), tuple(track.states),
                       np.array(hist_len), np.array(hist_cost), success, message)

