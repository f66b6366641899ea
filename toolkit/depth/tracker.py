"""The depth tracker: one depth frame in, 13 control points and a state out (source 001, figure 2).

Per frame: user mask -> normals -> user point cloud (view frame) -> ORUS grid
-> curvature centres and osculating spheres -> radial profile -> initial pose
(when there is no previous skeleton) or local + global fitting from the
predicted skeleton -> hard constraints -> stabilisation -> completion ->
output in world (camera pose known) or camera coordinates.

Per-frame **states**:

``lost`` (0)
    no user in the frame (empty or all-invalid depth, mask too small, a flat
    surface such as a wall: :attr:`TrackerConfig.max_planar_share`) or no
    initial pose could be found; joints are NaN;
``recovering`` (1)
    a skeleton was (re)initialised and has not yet fitted well for
    :attr:`TrackerConfig.confirm_frames` frames, or the fit has been poor;
``tracking`` (2)
    the fit explains the user well.

A skeleton that fits poorly for :attr:`TrackerConfig.reinit_after` frames is
dropped and searched for again.  When tracking, grid bins farther than
:attr:`TrackerConfig.person_gate_m` from the predicted body are left out, so a
second person touching the user is not fitted (bins near both go to the nearer
of the user's body and the other person as last seen); when the user is first found,
two heads side by side split the grid between two people (the frame's
``reason`` says ``"touching"`` in both cases).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from toolkit.cameras import Camera
from toolkit.pointcloud.cloud import ViewFrame, user_cloud
from toolkit.depth.complete import PointKalman, complete
from toolkit.depth.constraints import (
    LengthEstimator,
    enforce_collisions,
    enforce_joint_limits,
    enforce_lengths,
    enforce_velocity,
)
from toolkit.depth.curvature import CONVEX, PLANAR, curvature_centres
from toolkit.depth.energy import FitData, assign, fit_data, support_fraction
from toolkit.depth.fit import GlobalSearch, LocalFit, fit_local
from toolkit.depth.init import (
    head_candidates,
    initial_poses,
    key_points,
    top_contour_peaks,
)
from toolkit.pointcloud.mask import BackgroundModel, user_mask
from toolkit.body.control_points import END_SPHERES, LIMBS, N_POINTS
from toolkit.depth.moves import MoveContext, default_moves
from toolkit.pointcloud.normals import normal_map
from toolkit.depth.orus import build_orus
from toolkit.depth.radial import radial_profile
from toolkit.depth.stabilise import Stabiliser
from toolkit.depth.tracker_state import (LOST, NO_PERSON_FLAT, RECOVERING, STATE_NAMES, TRACKING, FrameResult,
                                         TrackerConfig)
from toolkit.errors import InputError
from toolkit.observe import as_observer
from toolkit.skeleton import SKELETON_13

__all__ = [
    "LOST",
    "NO_PERSON_FLAT",
    "RECOVERING",
    "STATE_NAMES",
    "TRACKING",
    "DepthTracker",
    "FrameResult",
    "TrackResult",
    "TrackerConfig",
    "track_sequence",
]


#: Which primitives support each control point (for the observed flags).
_SUPPORT = {
    0: {"head"},
    1: {"l_upper_arm", "torso"}, 2: {"r_upper_arm", "torso"},
    3: {"l_upper_arm", "l_forearm"}, 4: {"r_upper_arm", "r_forearm"},
    5: {"l_forearm", "l_hand"}, 6: {"r_forearm", "r_hand"},
    7: {"l_thigh", "torso"}, 8: {"r_thigh", "torso"},
    9: {"l_thigh", "l_shank"}, 10: {"r_thigh", "r_shank"},
    11: {"l_shank", "l_foot"}, 12: {"r_shank", "r_foot"},
}
_PRIM_NAMES = tuple(n for n, *_ in LIMBS) + tuple(n for n, *_ in END_SPHERES) + ("torso",)
_SUPPORT_MASK = np.array([[name in _SUPPORT[j] for name in _PRIM_NAMES] for j in range(N_POINTS)])


_CONTROLLER = None


def _single_thread_blas():
    """A context limiting BLAS to one thread (small matrices are much slower multi-threaded on a busy machine)."""
    global _CONTROLLER
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - threadpoolctl comes with scikit-learn
        import contextlib

        return contextlib.nullcontext()
    if _CONTROLLER is None:
        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER.limit(limits=1, user_api="blas")


def _nan13():
    return np.full((N_POINTS, 3), np.nan)


class DepthTracker:
    """Fit and track the 13-point skeleton in a sequence of depth frames.

    Parameters
    ----------
    camera : Camera
        The depth camera (intrinsics; ``cam_from_world`` used if ``pose_known``).
    pose_known : bool
        Whether ``camera.cam_from_world`` is the true pose (gives gravity, the
        ground and world output).
    config : TrackerConfig
    background : BackgroundModel or ndarray of shape (H, W), optional
        Depth of the empty scene for the user mask.
    rng : numpy.random.Generator or int or None
        Seeds the key-point clustering.
    observer : Observer, optional
        Receives the point cloud, ORUS grid, normals, curvature centres and
        spheres, radial profile, energy terms per iteration and skeleton.

    Examples
    --------
    >>> tracker = DepthTracker(camera, background=bg)          # doctest: +SKIP
    >>> for depth in frames:                                   # doctest: +SKIP
    ...     result = tracker.process(depth)
    """

    def __init__(self, camera: Camera, pose_known: bool = True, config: TrackerConfig = TrackerConfig(),
                 background=None, rng=None, observer=None):
        if not isinstance(camera, Camera):
            raise InputError("camera", "a toolkit.cameras.Camera", type(camera).__name__)
        self.camera = camera
        self.frame = ViewFrame.from_camera(camera, pose_known)
        self.config = config
        if background is not None and not isinstance(background, BackgroundModel):
            background = BackgroundModel(np.asarray(background, np.float32))
        if background is not None and background.depth.shape != (camera.size[1], camera.size[0]):
            raise InputError("background", f"a depth map of shape {(camera.size[1], camera.size[0])}",
                             f"shape {background.depth.shape}")
        self.background = background
        self.rng = np.random.default_rng(rng)
        self.observer = observer
        self._obs = as_observer(observer)
        self.dt = 1.0 / config.fps
        self.search = GlobalSearch(default_moves(), config.fit)
        self.stabiliser = Stabiliser(N_POINTS, config.stabiliser)
        self.index = 0
        self._reported_static = False
        self.reset()

    # ---------------------------------------------------------------- state
    def reset(self) -> None:
        """Forget the user (the next frame starts with the initial-pose search)."""
        self.X = None                  # last output skeleton, view frame
        self.observed_prev = np.ones(N_POINTS, bool)
        self.dims = None
        self.lengths = None
        self.kalman = PointKalman(N_POINTS, self.config.completion)
        self.stabiliser.reset()
        self.prev_mask = None
        self.good = 0
        self.poor = 0
        self.touching = 0
        self.other = None              # view-frame bins of a second person touching the user
        self.state = LOST

    @property
    def ground_y(self):
        return self.frame.ground_y

    def _lost(self, reason: str, n_points: int = 0, timings=None) -> FrameResult:
        self.X = None
        self.kalman = PointKalman(N_POINTS, self.config.completion)
        self.stabiliser.reset()
        self.good = self.poor = 0
        self.state = LOST
        self.prev_mask = None
        r = FrameResult(self.index, LOST, _nan13(), _nan13(), np.zeros(N_POINTS, bool), 0.0, 0.0, float("nan"),
                        reason, n_points, timings or {})
        self._report_result(r)
        self.index += 1
        return r

    # ------------------------------------------------------------ one frame
    def process(self, depth: np.ndarray, mask: np.ndarray | None = None) -> FrameResult:
        """Track one depth frame (BLAS limited to one thread meanwhile, see ``TrackerConfig.single_thread_blas``).

        Parameters
        ----------
        depth : ndarray of shape (H, W)
            Float metres, NaN or 0 = no reading (uint16 millimetres are accepted too).
        mask : ndarray of shape (H, W), bool, optional
            The user's pixels, if known.

        Returns
        -------
        FrameResult

        Raises
        ------
        InputError
            If ``depth`` (or ``mask``) does not have the camera's image shape.
        """
        if not self.config.single_thread_blas:
            return self._process(depth, mask)
        with _single_thread_blas():
            return self._process(depth, mask)

    def _process(self, depth, mask) -> FrameResult:
        """Track one frame (:meth:`process`): user cloud, ORUS grid, fit, hard constraints, state.

        Parameters
        ----------
        depth : ndarray of shape (H, W)
            Float metres, NaN or 0 = no reading, or uint16 millimetres.
        mask : ndarray of shape (H, W), bool, or None
            The user's pixels, if known.

        Returns
        -------
        FrameResult
        """
        cfg = self.config
        d = self._depth_metres(depth)
        timings = {}
        t0 = time.thread_time()
        cloud, lost_reason = self._user_cloud(d, mask)
        if cloud is None:
            return self._lost(lost_reason)
        timings["mask_cloud"] = time.thread_time() - t0
        t1 = time.thread_time()
        predicted = None
        if self.X is not None:
            predicted = self.kalman.predict(self.dt)
            centre = predicted.mean(0)
        else:
            centre = cloud.centroid
        grid = build_orus(cloud.points, centre, cfg.orus, cloud.normals)
        grid, curv, data, first, reason = self._user_grid(grid, cloud, predicted)
        if grid is None:
            return self._lost("no user", cloud.n_points, timings)
        if np.mean(curv.label[grid.filled] == PLANAR) > cfg.max_planar_share:  # a wall: nobody to fit
            return self._lost(NO_PERSON_FLAT, cloud.n_points, timings)
        centroid = grid.mean[grid.filled].mean(0)
        # the radial profile serves the initial pose, the global moves and the recording only
        need_profile = self.X is None or self.observer is not None or self._moves_due()
        profile = radial_profile(grid, centroid, cfg.radial) if need_profile else None
        timings["orus_curvature"] = time.thread_time() - t1
        t2 = time.thread_time()
        if self.observer is not None:
            self._report_data(cloud, grid, curv, profile)
        fitted = self._fit_pose(grid, data, first, predicted, profile, centroid, cloud, reason)
        timings["fit"] = time.thread_time() - t2
        if fitted is None:
            return self._lost("no initial pose", cloud.n_points, timings)
        fit, X_fit, X_before, state, reason = fitted
        t3 = time.thread_time()
        Xc, observed, supported, state, reason = self._constrain_and_update(X_fit, X_before, data, fit, predicted,
                                                                            state, reason)
        timings["post"] = time.thread_time() - t3
        timings["total"] = time.thread_time() - t0
        out = self.frame.to_world(Xc) if cfg.output == "world" else self.frame.to_camera(Xc)
        r = FrameResult(self.index, state, out, Xc, observed, fit.energy.explained, supported, fit.energy.total,
                        reason, cloud.n_points, timings)
        self._report_result(r, fit)
        self.index += 1
        return r

    def _depth_metres(self, depth) -> np.ndarray:
        """The depth map checked against the camera's image shape, in float metres.

        Parameters
        ----------
        depth : array-like of shape (H, W)
            Float metres (NaN or 0 = no reading) or uint16 millimetres (0 = no reading).

        Returns
        -------
        ndarray of shape (H, W)
            Float metres, NaN where a uint16 map had 0.

        Raises
        ------
        InputError
            If ``depth`` does not have the camera's image shape, or is neither float nor uint16.
        """
        w, h = self.camera.size
        d = np.asarray(depth)
        if d.shape != (h, w):
            raise InputError("depth", f"a depth map of shape ({h}, {w})", f"shape {d.shape}")
        if d.dtype == np.uint16:
            d = np.where(d > 0, d.astype(np.float32) / 1000.0, np.nan).astype(np.float32)
        elif not np.issubdtype(d.dtype, np.floating):
            raise InputError("depth", "float metres or uint16 millimetres", f"dtype {d.dtype}")
        return d

    def _user_cloud(self, d: np.ndarray, mask):
        """Report the depth map, find the user's pixels and back-project them.

        Parameters
        ----------
        d : ndarray of shape (H, W)
            Float metres, NaN or 0 = no reading.
        mask : ndarray of shape (H, W), bool, or None
            The user's pixels, if known.

        Returns
        -------
        cloud : UserCloud or None
            The user's points in the view frame; None when no user was found.
        lost_reason : str
            Why there is no cloud ("no user" or "no depth"); meaningless with a cloud.
        """
        cfg = self.config
        obs = self._obs
        if self.observer is not None:
            obs.report("depth", camera=self.camera.name, depth=np.nan_to_num(d, nan=0.0), name="depth",
                       frame=self.index)
        um = user_mask(d, self.camera, background=self.background, given=mask, previous=self.prev_mask,
                       config=cfg.mask)
        if not um.found:
            with np.errstate(invalid="ignore"):
                return None, ("no user" if np.any(d > 0) else "no depth")
        self.prev_mask = um.mask
        nmap = normal_map(d, self.camera, um.mask) if cfg.orus.normal_source == "pixels" else None
        cloud = user_cloud(d, um.mask, self.frame, nmap, with_pca=self.X is None)
        return cloud, "no user"

    def _user_grid(self, grid, cloud, predicted):
        """Keep the user's bins of the ORUS grid (a second person touching the user cut off), with curvature.

        Parameters
        ----------
        grid : OrusGrid
            The ORUS grid of the user's cloud.
        cloud : UserCloud
            The user's points.
        predicted : ndarray of shape (N_POINTS, 3) or None
            The control points predicted for this frame, in metres (view frame); None when searching.

        Returns
        -------
        grid : OrusGrid or None
            The user's bins; None when fewer than ``min_bins`` are left (the user is lost).
        curv : CurvatureResult or None
            Curvature centres of ``grid``.
        data : FitData or None
            The fit's data from ``grid`` and ``curv``.
        first : Assignment or None
            The data assignment at ``predicted``, when still valid for ``data``.
        reason : str
            "touching" when a second person was cut off, else "ok".
        """
        cfg = self.config
        reason = "ok"
        if predicted is None:
            keep = self._one_person(grid, cloud)
            if keep is not None:
                reason = "touching"
                self.touching = cfg.touching_memory
                self.other = grid.mean[grid.filled & ~keep]
                grid = replace(grid, filled=grid.filled & keep, occupied=grid.occupied & keep)
        if grid.filled.sum() < cfg.min_bins:
            return None, None, None, None, reason
        curv = curvature_centres(grid, cfg.curvature)
        data = fit_data(grid, curv, self.frame)
        first = None
        if predicted is not None:
            first, far = self._person_gate(grid, data, predicted)
            if far is not None:
                # fit only the user's part (once seen, for touching_memory frames even when the
                # other person's head is not clear)
                reason = "touching"
                keep = grid.filled & ~far
                grid = replace(grid, filled=keep, occupied=grid.occupied & keep)
                if grid.filled.sum() < cfg.min_bins:
                    return None, None, None, None, reason
                curv = curvature_centres(grid, cfg.curvature)
                data = fit_data(grid, curv, self.frame)
                first = None
        return grid, curv, data, first, reason

    def _person_gate(self, grid, data: FitData, predicted: np.ndarray):
        """Tell, from the first data assignment at the prediction, whether a second person touches the user.

        Many bins far from the body with a head of their own are a second person; once seen, they are
        cut off for ``touching_memory`` frames even when the other person's head is not clear.
        Updates ``self.touching`` and ``self.other``.

        Parameters
        ----------
        grid : OrusGrid
            The ORUS grid of the user's cloud.
        data : FitData
            The fit's data from ``grid``.
        predicted : ndarray of shape (N_POINTS, 3)
            The control points predicted for this frame, in metres (view frame).

        Returns
        -------
        first : Assignment
            The data assignment at ``predicted``.
        far : ndarray of shape grid.shape, bool, or None
            The second person's bins; None when there is no second person.
        """
        cfg = self.config
        first = assign(data, predicted, self.dims, cfg.energy)
        near = first.surface_near < cfg.person_gate_m
        if self.touching > 0 and self.other is not None and len(self.other):
            # bins near both people go to the nearer one (the other person as last seen)
            dx = data.surface[:, None, :2] - self.other[None, :, :2]
            d_other = np.sqrt(np.min(np.einsum("bkc,bkc->bk", dx, dx), axis=1))
            near &= first.surface_near < d_other
        n_far = int((~near).sum())
        many = n_far > max(cfg.min_bins // 2, cfg.touching_fraction * len(near))
        if many:
            far = np.zeros(grid.shape, bool)
            far[data.index[~near, 0], data.index[~near, 1]] = True
        if many and (self.touching > 0 or top_contour_peaks(replace(grid, filled=far),
                                                            min_body_m=cfg.min_body_m)):
            self.touching = cfg.touching_memory
            self.other = data.surface[~near]
            return first, far
        self.touching = max(self.touching - 1, 0)
        if self.touching == 0:
            self.other = None
        return first, None

    def _fit_pose(self, grid, data: FitData, first, predicted, profile, centroid: np.ndarray, cloud, reason: str):
        """Fit the control points: the initial pose when searching, else the local fit and global moves.

        Parameters
        ----------
        grid : OrusGrid
            The user's bins.
        data : FitData
            The fit's data.
        first : Assignment or None
            The data assignment at ``predicted``, if still valid.
        predicted : ndarray of shape (N_POINTS, 3) or None
            The control points predicted for this frame, in metres (view frame); None when searching.
        profile : RadialProfile or None
            The radial profile around ``centroid``; computed here when the moves need it.
        centroid : ndarray of shape (3,)
            The mean of the user's bins, in metres (view frame).
        cloud : UserCloud
            The user's points.
        reason : str
            The frame's reason so far.

        Returns
        -------
        (fit, X_fit, X_before, state, reason) or None
            The fit (``LocalFit``), its control points ``(N_POINTS, 3)``, the previous frame's (None
            at initialisation), the state before the hard constraints and the reason; None when no
            initial pose was found.
        """
        cfg = self.config
        if self.X is None:
            fit = self._initialise(grid, profile, cloud, data)
            if fit is None:
                return None
            return fit, fit.X, None, RECOVERING, "init"
        w_prev = np.full(N_POINTS, cfg.prev_weight_tracking if self.state == TRACKING
                         else cfg.prev_weight_recovering)
        w_prev[~self.observed_prev] = cfg.prev_weight_unseen
        fit = fit_local(predicted, data, self.dims, predicted, w_prev, cfg.fit, cfg.energy, cfg.constraints,
                        self.ground_y, self.observer, self.index, first=first)
        if fit.energy.explained < cfg.fit.move_trigger_explained or self._moves_due():
            if profile is None:
                profile = radial_profile(grid, centroid, cfg.radial)
            ctx = MoveContext(profile=profile, grid=grid, data=data, dims=self.dims, frame=self.frame,
                              predicted=predicted, tracker=self, assignment=fit.energy.assignment,
                              data_index=data.index)
            fit, _ = self.search.run(fit, ctx, lambda X0: fit_local(
                X0, data, self.dims, predicted, w_prev, cfg.fit, cfg.energy, cfg.constraints, self.ground_y),
                observer=self.observer, frame=self.index)
        return fit, fit.X, self.X, self.state, reason

    def _constrain_and_update(self, X_fit: np.ndarray, X_before, data: FitData, fit, predicted, state: int,
                              reason: str):
        """Apply the hard constraints, stabilise and complete the pose, update the filter, lengths and state.

        Parameters
        ----------
        X_fit : ndarray of shape (N_POINTS, 3)
            The fitted control points, in metres (view frame).
        X_before : ndarray of shape (N_POINTS, 3) or None
            The previous frame's control points (None at initialisation).
        data : FitData
            The fit's data.
        fit : LocalFit
            The fit.
        predicted : ndarray of shape (N_POINTS, 3) or None
            The control points predicted for this frame.
        state : int
            The state before this frame's quality is known.
        reason : str
            The frame's reason so far.

        Returns
        -------
        Xc : ndarray of shape (N_POINTS, 3)
            The completed control points, in metres (view frame).
        observed : ndarray of shape (N_POINTS,), bool
            Which control points the data saw.
        supported : float
            The fraction of the data supported by the pose.
        state : int
            The frame's state.
        reason : str
            The frame's reason.
        """
        cfg = self.config
        # hard constraints
        X, _ = enforce_velocity(X_fit, X_before, self.dt, cfg.constraints)
        X, _ = enforce_collisions(X, X_before, self.dims, cfg.constraints)
        X = enforce_lengths(X)
        X, _ = enforce_joint_limits(X)
        observed = self._observed(data, fit, X)
        quality_ok, supported = self._quality(data, fit, X)
        # stabilisation and completion
        Xs = self.stabiliser(X, observed)
        Xc = complete(Xs, observed, predicted, self.dims, self.dt, cfg.completion, self.ground_y, self.X)
        if not self.kalman.initialised:
            self.kalman.reset(Xc)
        else:
            self.kalman.update(Xc, observed)
        # states
        if quality_ok:
            self.good += 1
            self.poor = 0
        else:
            self.poor += 1
            self.good = 0
        if state != TRACKING and self.good >= cfg.confirm_frames:
            state = TRACKING
        elif state == TRACKING and not quality_ok:
            state = RECOVERING
            reason = "poor fit" if reason == "ok" else reason
        if quality_ok and state == TRACKING and observed.all():
            self.dims = self.dims.with_lengths(self.lengths.update(Xc, np.ones(len(self.dims.lengths), bool)))
        self.X = Xc
        self.observed_prev = observed
        self.state = state
        if self.poor >= cfg.reinit_after:
            self.X = None           # search again next frame
            self.poor = 0
        return Xc, observed, supported, state, reason

    # ------------------------------------------------------------- helpers
    def _moves_due(self) -> bool:
        return self.index % self.config.fit.move_every == 0

    def _initialise(self, grid, profile, cloud, data: FitData) -> LocalFit | None:
        cfg = self.config
        kp = key_points(grid, profile, None, cfg.init)
        heads = head_candidates(kp, cloud.centroid, cloud.principal_axis, profile, cfg.init, grid)
        if not heads:
            return None
        cut_bottom = cloud.touches_border[3]
        poses = initial_poses(grid, kp, heads, cloud.centroid, cloud.principal_axis, self.ground_y, cut_bottom,
                              cfg.init)
        best = None
        best_dims = None
        init_fit = replace(cfg.fit, outer_iterations=cfg.fit.init_outer_iterations,
                           lm_max_evaluations=cfg.fit.init_lm_max_evaluations,
                           lm_refine_evaluations=cfg.fit.init_lm_max_evaluations)
        for p in poses:
            f = fit_local(p.X, data, p.dims, p.X, np.full(N_POINTS, cfg.prev_weight_recovering), init_fit,
                          cfg.energy, cfg.constraints, self.ground_y, self.observer, self.index, tag="init")
            if best is None or f.energy.total < best.energy.total:
                best, best_dims = f, p.dims
        if self.observer is not None:
            P = self.frame.to_world(kp.positions)
            colors = np.array([[255, 80, 80], [80, 200, 80], [80, 120, 255]], np.uint8)[kp.classes]
            self._obs.report("points3d", points=P, colors=colors, radii=0.03, name="depth/keypoints",
                             frame=self.index)
        self.dims = best_dims
        self.lengths = LengthEstimator(best_dims)
        self.kalman = PointKalman(N_POINTS, cfg.completion)
        self.stabiliser.reset()
        self.good = self.poor = 0
        return best

    def _one_person(self, grid, cloud) -> np.ndarray | None:
        """When the user is first found: bins of one person if two heads stand side by side
        (a second person touching the user), else None.  The person kept is the one whose head is
        nearer the camera's optical axis sideways (the camera is aimed at the user)."""
        cfg = self.config
        peaks = top_contour_peaks(grid, min_body_m=cfg.min_body_m)
        if len(peaks) < 2:
            return None
        a = peaks[0]
        others = [p for p in peaks[1:] if abs(p[0] - a[0]) > cfg.second_head_m and abs(p[1] - a[1]) < 0.3]
        if not others:
            return None
        b = others[0]
        x = grid.bin_centres()[..., 0]
        side_a = np.abs(x - a[0]) <= np.abs(x - b[0])
        # the user is the one the camera is aimed at: the head nearer the optical axis sideways
        # (heights differ between people, the aim does not follow them)
        ca, cb = self.frame.to_camera(a), self.frame.to_camera(b)
        off_a = abs(ca[0] / max(ca[2], 1e-6))
        off_b = abs(cb[0] / max(cb[2], 1e-6))
        return side_a if off_a <= off_b else ~side_a

    def _observed(self, data: FitData, fit: LocalFit, X: np.ndarray) -> np.ndarray:
        """Control points with at least ``support_min_bins`` nearby bins given to their primitives,
        inside the image."""
        a = fit.energy.assignment
        out = np.zeros(N_POINTS, bool)
        if a is None or len(a.surface_prim) == 0:
            return out
        ok = a.surface_prim >= 0
        P = data.surface[ok]
        prim = a.surface_prim[ok]
        Q = P[:, None, :] - X[None]
        D = np.sqrt(np.einsum("bjk,bjk->bj", Q, Q))                      # (B, 13)
        sup = _SUPPORT_MASK[:, prim].T & (D < self.config.support_radius_m)
        out = sup.sum(0) >= self.config.support_min_bins
        uv = self.frame.project(X)
        w, h = self.camera.size
        inside = np.all(np.isfinite(uv), axis=1) & (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & \
            (uv[:, 1] <= h - 1)
        return out & inside

    def _quality(self, data: FitData, fit: LocalFit, X: np.ndarray) -> tuple[bool, float]:
        """Good fit: explains the user's bins (data to model) and the data support the skeleton (model to data)."""
        cfg = self.config
        sup = support_fraction(data, X, cfg.energy)
        return bool(fit.energy.explained >= cfg.good_explained and sup >= cfg.good_support), sup

    # ------------------------------------------------------------ reporting
    def _report_data(self, cloud, grid, curv, profile) -> None:
        obs = self._obs
        i = self.index
        fr = self.frame
        if not self._reported_static:
            from toolkit.cameras import Rig

            obs.report("rig", rig=Rig([self.camera]), path="world/depth_cams")
            obs.report("skeleton", skeleton=SKELETON_13)
            self._reported_static = True
        step = max(1, cloud.n_points // self.config.report_max_points)
        obs.report("points3d", points=fr.to_world(cloud.points[::step]), name="depth/cloud", frame=i,
                   colors=np.full((len(cloud.points[::step]), 3), 170, np.uint8))
        pos, nrm, idx = grid.points("filled")
        lab = curv.label[idx[:, 0], idx[:, 1]]
        palette = np.array([[150, 150, 150], [90, 140, 230], [90, 210, 90], [230, 90, 90]], np.uint8)
        obs.report("points3d", points=fr.to_world(pos), colors=palette[lab], radii=grid.bin_size / 2,
                   name="depth/orus", frame=i)
        okn = np.all(np.isfinite(nrm), axis=1)
        ends = pos[okn] + 0.05 * nrm[okn]
        obs.report("rays", origins=fr.to_world(pos[okn]), ends=fr.to_world(ends), name="depth/normals", frame=i)
        sp = curv.spheres
        obs.report("points3d", points=fr.to_world(sp.centres), radii=sp.radii, name="depth/spheres", frame=i,
                   colors=np.tile(np.array([[240, 200, 60]], np.uint8), (len(sp), 1)))
        obs.report("points3d", points=fr.to_world(sp.centres), radii=0.01, name="depth/curvature_centres",
                   frame=i)
        obs.report("lines3d", strips=[fr.to_world(np.vstack([profile.points, profile.points[:1]]))],
                   name="depth/radial_contour", frame=i)
        obs.report("depth_radial", frame=i, angles_deg=profile.angles_deg, distances=profile.distances,
                   peaks=profile.peaks)
        n_pl = int((curv.label == PLANAR).sum())
        n_cv = int((curv.label == CONVEX).sum())
        obs.report("scalar", name="depth/orus/filled_bins", value=float(grid.filled.sum()), frame=i)
        obs.report("scalar", name="depth/orus/planar_bins", value=float(n_pl), frame=i)
        obs.report("scalar", name="depth/orus/convex_bins", value=float(n_cv), frame=i)

    def _report_result(self, r: FrameResult, fit: LocalFit | None = None) -> None:
        if self.observer is None:
            return
        obs = self._obs
        if np.all(np.isfinite(r.joints_view)):
            obs.report("joints3d", joints=self.frame.to_world(r.joints_view), name="depth/skeleton",
                       skeleton=SKELETON_13, frame=r.index)
        obs.report("scalar", name="depth/state", value=float(r.state), frame=r.index)
        obs.report("text", name="depth/state", text=f"frame {r.index}: {r.state_name} ({r.reason})",
                   frame=r.index)
        if fit is not None:
            for k, v in fit.energy.terms.items():
                obs.report("scalar", name=f"depth/energy/{k}", value=float(v), frame=r.index)
            obs.report("scalar", name="depth/explained", value=float(r.explained), frame=r.index)


@dataclass(frozen=True)
class TrackResult:
    """The frames of a tracked sequence.

    Attributes
    ----------
    frames : list of FrameResult
    coordinates : str
        ``"world"`` or ``"camera"`` (the output coordinates of ``joints``).
    """

    frames: list
    coordinates: str

    @property
    def joints(self) -> np.ndarray:
        """(T, 13, 3) metres, NaN where lost."""
        return np.array([f.joints for f in self.frames]).reshape(-1, N_POINTS, 3)

    @property
    def states(self) -> np.ndarray:
        """(T,) int8 states."""
        return np.array([f.state for f in self.frames], np.int8)

    @property
    def observed(self) -> np.ndarray:
        return np.array([f.observed for f in self.frames], bool).reshape(-1, N_POINTS)

    @property
    def explained(self) -> np.ndarray:
        return np.array([f.explained for f in self.frames])

    @property
    def supported(self) -> np.ndarray:
        return np.array([f.supported for f in self.frames])

    @property
    def reasons(self) -> np.ndarray:
        return np.array([f.reason for f in self.frames])

    def timings(self, stage: str = "total") -> np.ndarray:
        """CPU seconds of one stage per frame (NaN where the stage did not run)."""
        return np.array([f.timings.get(stage, np.nan) for f in self.frames])


def track_sequence(tracker: DepthTracker, frames, independent: bool = False, progress=None) -> TrackResult:
    """Run ``tracker`` over depth frames.

    Parameters
    ----------
    tracker : DepthTracker
    frames : iterable of ndarray (H, W)
        Depth frames in order (metres).
    independent : bool
        Track every frame on its own (the tracker is reset before each one),
        for unrelated frames such as a set of still pictures.
    progress : callable, optional
        Called with each :class:`FrameResult` (e.g. to advance a progress bar).

    Returns
    -------
    TrackResult
    """
    out = []
    for d in frames:
        if independent:
            tracker.reset()
        r = tracker.process(d)
        out.append(r)
        if progress is not None:
            progress(r)
    coords = tracker.config.output if tracker.frame.pose_known else "camera"
    return TrackResult(out, coords)
