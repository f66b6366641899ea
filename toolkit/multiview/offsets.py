"""Per-view 2D offsets optimised by Levenberg-Marquardt (source 000, §2.1 and claim 6).

For one combination of 2D poses (one per view), every joint gets the 3D point
closest to its rays (:func:`toolkit.cameras.closest_point_to_rays`); one 2D
offset per view, added to that view's joints, is varied to make the rays
agree, which absorbs calibration error.

The unknowns are only the offsets (``2 n_views`` numbers): the 3D points are a
closed-form function of them (the weighted least-squares point of the rays),
so every residual evaluation is a few small linear solves and the Jacobian by
finite differences costs ``2 n_views + 1`` evaluations.

**Gauge.**  Shifting the whole body in 3D by ``t`` moves its image in view
``v`` by almost the same pixel shift ``G_v t`` for every joint (exactly so for
an affine camera), so offsets ``o + G t`` fit the data nearly as well as ``o``:
three of the ``2 n_views`` offset directions are (nearly) unobservable.  With
two views only one direction is left.  Fixing one view's offset at zero
removes two of the three, not the third, and makes the result depend on which
view is chosen.  A zero-mean Gaussian prior on every offset
(:data:`~toolkit.multiview.config.OFFSET_PRIOR_PX`) removes all three: among
offsets that explain the data equally well it picks the smallest, which is
also the maximum a-posteriori estimate when the cameras' errors are
independent.  :func:`offsets_modulo_gauge` compares offsets with that freedom
removed.  For near (studio) cameras the three directions are only *nearly*
flat: perspective lets the 2D joints' own errors (2-5 px) pull every view's
offset the same way by 10-16 px, which moves the body by 5-8 cm.  A second,
tight prior on the gauge component (:data:`~toolkit.multiview.config.GAUGE_PRIOR_PX`,
the offsets projected on the orthonormalised :func:`gauge_basis` at the body's
centre) keeps the body where the rays put it and leaves the other offset
directions to the data.

**Bound.**  ``scipy.optimize.least_squares(method="lm")`` takes no bounds, so the
offsets are parametrised as ``o = B tanh(p / B)`` (``B = max_offset_px``): smooth,
bounded, and the identity for small offsets.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from toolkit.cameras import Rig, camera_with_offset, closest_point_to_rays
from toolkit.errors import InputError
from toolkit.multiview.config import MultiViewConfig

#: Largest |p / B| of the initial point (tanh^-1 is infinite at 1).
_ATANH_CLIP = 0.999
#: Central-difference step of the Jacobian, pixels (residuals are smooth at this scale).
_JAC_STEP = 1e-3
#: Step of the numerical derivative of the undistortion, pixels.
_LINEARISE_STEP_PX = 0.5
#: With lens distortion, linearise again when the offsets moved more than this (pixels) ...
_RELINEARISE_PX = 0.5
#: ... at most this many times.
_MAX_LINEARISATIONS = 3


@dataclass(frozen=True, eq=False)
class OffsetFit:
    """Result of :func:`fit_offsets` for one combination of 2D poses.

    Attributes
    ----------
    offsets : ndarray of shape (n_views, 2)
        Pixels, added to each view's joints (zero for views that took no part).
    joints3d : ndarray of shape (n_joints, 3)
        The point closest to each joint's rays, metres; NaN with fewer than two rays.
    ray_distances : ndarray of shape (n_views, n_joints)
        Distance from each ray to its joint's point, metres; NaN where no ray.
    reprojection_errors : ndarray of shape (n_views, n_joints)
        Pixels between the projected point and the offset-corrected joint.
    cost : float
        Mean ray distance (metres, weighted by the ray weights); ``inf`` when no joint
        was triangulated.
    active : ndarray of shape (n_views,) of bool
        Views whose offset was optimised.
    success : bool
        Whether the optimiser converged (or had nothing to optimise) and a joint was
        triangulated.
    message : str
    nfev : int
        Residual evaluations.
    """

    offsets: np.ndarray
    joints3d: np.ndarray
    ray_distances: np.ndarray
    reprojection_errors: np.ndarray
    cost: float
    active: np.ndarray
    success: bool
    message: str
    nfev: int

    def __bool__(self) -> bool:
        return self.success


def mean_ray_distance(distances: np.ndarray, weights: np.ndarray | None = None, axis=None):
    """Weighted mean of ray distances, ignoring NaN; ``inf`` where none is finite.

    Parameters
    ----------
    distances : ndarray of shape (n_views, ...)
        Metres, NaN for missing rays.
    weights : ndarray of the same shape, optional
    axis : int or tuple, optional
        Axes averaged over (default: all).

    Returns
    -------
    float or ndarray
        Source 000 §2.1 scores a combination by the *summed* ray distances; with
        missing joints a sum favours combinations that triangulate fewer joints,
        so the mean is used.  For complete poses the two rank combinations alike.
    """
    d = np.asarray(distances, float)
    w = np.ones_like(d) if weights is None else np.broadcast_to(np.asarray(weights, float), d.shape)
    ok = np.isfinite(d) & (w > 0)
    num = np.sum(np.where(ok, d * w, 0.0), axis=axis)
    den = np.sum(np.where(ok, w, 0.0), axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.inf)
    return float(out) if np.ndim(out) == 0 else out


def _check_inputs(points2d, rig, weights):
    pts = np.asarray(points2d, float)
    n_views = len(rig)
    if pts.ndim != 3 or pts.shape[0] != n_views or pts.shape[2] != 2:
        raise InputError("points2d", f"an array of shape ({n_views}, n_joints, 2) (one pose per camera)",
                         f"shape {pts.shape}")
    if weights is None:
        w = np.ones(pts.shape[:2])
    else:
        w = np.asarray(weights, float)
        if w.shape != pts.shape[:2]:
            raise InputError("weights", f"an array of shape {pts.shape[:2]}", f"shape {w.shape}")
        if np.any(~np.isfinite(w) & np.isfinite(pts).all(-1)) or np.any(w < 0):
            raise InputError("weights", "finite non-negative weights where joints are given",
                             "negative or non-finite values")
    valid = np.isfinite(pts).all(-1) & (np.nan_to_num(w) > 0)
    return pts, np.where(valid, np.nan_to_num(w), 0.0), valid


def _rays(rig: Rig, uv: np.ndarray):
    o, d = zip(*(c.rays(uv[i]) for i, c in enumerate(rig)))
    return np.stack(o), np.stack(d)


def triangulate_views(rig: Rig, points2d: np.ndarray, weights: np.ndarray | None = None):
    """Rays, closest points and ray distances of one pose per view.

    Parameters
    ----------
    rig : Rig
    points2d : ndarray of shape (n_views, n_joints, 2)
        Pixels, NaN = missing.
    weights : ndarray of shape (n_views, n_joints), optional

    Returns
    -------
    origins, directions : ndarray of shape (n_views, n_joints, 3)
    joints3d : ndarray of shape (n_joints, 3)
        NaN with fewer than two rays.
    distances : ndarray of shape (n_views, n_joints)
        Metres; NaN where no ray or no point.
    """
    o, d = _rays(rig, np.asarray(points2d, float))
    X, dist = closest_point_to_rays(o, d, weights)
    dist = np.where(np.isfinite(X).all(-1)[None], dist, np.nan)
    return o, d, X, dist


def _active_views(valid: np.ndarray, cfg: MultiViewConfig) -> np.ndarray:
    """The views whose offsets are optimised.

    A view's offset is observable only through joints that another view also sees: at least
    ``cfg.min_view_joints`` of them, in two views at least; never the reference view.

    Parameters
    ----------
    valid : ndarray of shape (n_views, n_joints), bool
        Joints seen (finite, weight > 0).
    cfg : MultiViewConfig

    Returns
    -------
    ndarray of shape (n_views,), bool

    Raises
    ------
    InputError
        ``cfg.reference_view`` not a view index.
    """
    n_views = valid.shape[0]
    shared = valid & (valid.sum(axis=0) >= 2)[None]
    active = shared.sum(axis=1) >= cfg.min_view_joints
    if active.sum() < 2:
        active[:] = False
    if cfg.reference_view is not None:
        if cfg.reference_view >= n_views:
            raise InputError("MultiViewConfig.reference_view", f"a view index < {n_views}",
                             repr(cfg.reference_view))
        active[cfg.reference_view] = False
    if not cfg.optimise_offsets:
        active[:] = False
    return active


def _prior_rows(rig: Rig, X0: np.ndarray, act: np.ndarray, cfg: MultiViewConfig) -> tuple[np.ndarray, np.ndarray]:
    """Weights of the offsets' prior and rows of the gauge prior, in the residual's units.

    The offsets' gauge (a 3D translation of the body seen in every active view) is an orthonormal
    basis of its image shifts, with the prior weight of that component (``cfg.gauge_prior_px``).
    For the ray residual both are scaled by each view's pixel footprint (metres per pixel at the body).

    Parameters
    ----------
    rig : Rig
    X0 : ndarray of shape (N, 3)
        Finite joints triangulated at the starting offsets, metres.
    act : ndarray of int, shape (n_active,)
        The active views.
    cfg : MultiViewConfig

    Returns
    -------
    prior_w : ndarray of shape (n_active,)
        Weight of each active view's offset prior.
    gauge_rows : ndarray of shape (3 or 0, 2 * n_active)
        Gauge prior rows (none when fewer than 2 active views or no point).
    """
    n_views = len(rig)
    sig = np.array([cfg.offset_prior_of(rig[int(i)].name) for i in act], float)
    prior_w = np.where(np.isfinite(sig), cfg.keypoint_sigma_px / sig, 0.0)
    if cfg.residual == "ray":
        foot = np.array([np.median(cam.depth_of(X0)) / np.sqrt(cam.K[0, 0] * cam.K[1, 1]) if len(X0) else 1.0
                         for cam in rig])
        prior_w = prior_w * foot[act]

    gauge_rows = np.zeros((0, 2 * len(act)))
    if len(act) >= 2 and len(X0) and np.isfinite(cfg.gauge_prior_px):
        G = gauge_basis(rig, X0.mean(axis=0)).reshape(n_views, 2, 3)[act].reshape(-1, 3)
        if np.isfinite(G).all():
            Q, _ = np.linalg.qr(G)
            wg = cfg.keypoint_sigma_px / cfg.gauge_prior_px
            if cfg.residual == "ray":
                wg = wg * float(np.mean(foot[act]))
            gauge_rows = wg * Q.T

    return prior_w, gauge_rows


def _exact_fit(rig: Rig, pts: np.ndarray, w: np.ndarray, offsets: np.ndarray, active: np.ndarray, converged: bool,
               message: str, nfev: int) -> OffsetFit:
    """The fit's final values with the exact camera model.

    Parameters
    ----------
    rig : Rig
    pts : ndarray of shape (n_views, n_joints, 2)
        Pixels, NaN where not valid.
    w : ndarray of shape (n_views, n_joints)
        Ray weights.
    offsets : ndarray of shape (n_views, 2)
        The optimised offsets, pixels.
    active : ndarray of shape (n_views,), bool
    converged : bool
    message : str
        The optimiser's message.
    nfev : int

    Returns
    -------
    OffsetFit
    """
    uv = pts + offsets[:, None, :]
    _, _, X, dist = triangulate_views(rig, uv, w)
    reproj = np.linalg.norm(np.stack([cam.project(X) for cam in rig]) - uv, axis=-1)
    cost = mean_ray_distance(dist, w)
    ok = converged and np.isfinite(cost)
    if not np.isfinite(cost):
        message = "no joint was seen by two views"
    return OffsetFit(offsets=offsets, joints3d=X, ray_distances=dist, reprojection_errors=reproj,
                     cost=float(cost), active=active, success=bool(ok), message=message, nfev=nfev)


def fit_offsets(points2d: np.ndarray, rig: Rig, config: MultiViewConfig | None = None, *,
                weights: np.ndarray | None = None, initial_offsets: np.ndarray | None = None) -> OffsetFit:
    """Optimise one 2D offset per view so that the joints' rays agree.

    Parameters
    ----------
    points2d : ndarray of shape (n_views, n_joints, 2)
        One pose per view, pixels; NaN for missing joints (a whole NaN view takes no part).
    rig : Rig
        ``n_views`` cameras, in the order of ``points2d``.
    config : MultiViewConfig, optional
        Residual type, bound, prior, reference view, ``optimise_offsets``.
    weights : ndarray of shape (n_views, n_joints), optional
        Non-negative ray weights (e.g. detector confidences); 0 drops a ray.
    initial_offsets : ndarray of shape (n_views, 2), optional
        Starting point (e.g. the previous frame's offsets); zeros by default.

    Returns
    -------
    OffsetFit
        A fit that triangulated no joint comes back with ``success=False`` and
        ``cost=inf``, not as an exception.

    Raises
    ------
    InputError
        Arrays of the wrong shape, negative weights.
    """
    cfg = config or MultiViewConfig()
    pts, w, valid = _check_inputs(points2d, rig, weights)
    n_views, n_joints = pts.shape[:2]
    init = np.zeros((n_views, 2)) if initial_offsets is None else np.asarray(initial_offsets, float)
    if init.shape != (n_views, 2) or not np.all(np.isfinite(init)):
        raise InputError("initial_offsets", f"a finite array of shape ({n_views}, 2)", f"{init.shape}")
    pts = np.where(valid[..., None], pts, np.nan)
    B = cfg.max_offset_px
    init = np.clip(init, -_ATANH_CLIP * B, _ATANH_CLIP * B)

    active = _active_views(valid, cfg)
    act = np.flatnonzero(active)
    base = np.where(active[:, None], 0.0, init)  # fixed offsets of inactive views

    def offsets_of(P):
        """Offsets (nb, n_views, 2) of parameter rows P (nb, 2 * n_active)."""
        O = np.repeat(base[None], len(P), axis=0)
        O[:, act] = B * np.tanh(P.reshape(len(P), -1, 2) / B)
        return O

    lin = _Linearised(rig, pts, init)
    sw = np.sqrt(w)[:, None, :, None]

    def evaluate(O):
        """Normalised coordinates, rays and points for a batch of offsets (nb, n_views, 2)."""
        n = lin.normalised(O)  # (V, nb, J, 2)
        ro, rd = lin.rays(n)
        X, _ = closest_point_to_rays(ro, rd, np.broadcast_to(w[:, None], n.shape[:-1]))
        return n, ro, rd, X

    # pixel footprint per view (metres per pixel at the body), for the ray residual's prior
    _, _, _, X0 = evaluate(init[None])
    X0 = X0[0][np.isfinite(X0[0]).all(-1)]
    prior_w, gauge_rows = _prior_rows(rig, X0, act, cfg)

    def residual_rows(P):
        O = offsets_of(P)
        n, ro, rd, X = evaluate(O)
        if cfg.residual == "ray":  # perpendicular ray-to-point vectors: smooth, unlike their norms
            diff = X[None] - ro
            r = diff - np.sum(diff * rd, axis=-1, keepdims=True) * rd
        else:
            r = lin.reprojection_px(X, n)
        r = np.nan_to_num(sw * r)  # (V, nb, J, c)
        r = np.transpose(r, (1, 0, 2, 3)).reshape(len(P), -1)
        return np.concatenate([r, (O[:, act] * prior_w[None, :, None]).reshape(len(P), -1),
                               O[:, act].reshape(len(P), -1) @ gauge_rows.T], axis=1)

    def residuals(p):
        return residual_rows(p[None])[0]

    def jacobian(p):
        # central differences, every perturbation in one batched evaluation
        E = np.eye(len(p)) * _JAC_STEP
        R = residual_rows(np.concatenate([p + E, p - E]))
        return ((R[:len(p)] - R[len(p):]) / (2 * _JAC_STEP)).T

    nfev, message, converged = 0, "no offsets optimised", True
    offsets = base.copy()
    if len(act):
        p = (B * np.arctanh(init[act] / B)).ravel()
        for _ in range(_MAX_LINEARISATIONS):
            res = least_squares(residuals, p, jac=jacobian, method="lm")
            p = res.x
            offsets = offsets_of(p[None])[0]
            nfev += int(res.nfev)
            message, converged = str(res.message), bool(res.status > 0)
            moved = np.abs(offsets - lin.offsets).max()
            if not lin.distorted or moved < _RELINEARISE_PX:
                break
            lin = _Linearised(rig, pts, offsets)  # lens distortion: linearise again where we are
    return _exact_fit(rig, pts, w, offsets, active, converged, message, nfev)


class _Linearised:
    """Undistorted image coordinates of the shifted joints, linear in the offsets.

    ``n(uv + o) = n(uv + o_lin) + J (o - o_lin)`` with ``J = dn/duv`` at ``uv + o_lin``:
    exact for cameras without distortion (the map is affine), first-order otherwise
    (:func:`fit_offsets` linearises again at its solution while the offsets still move).
    Every evaluation is then a few batched numpy operations over all views.
    """

    def __init__(self, rig: Rig, pts: np.ndarray, offsets: np.ndarray):
        self.offsets = offsets.copy()
        uv = pts + offsets[:, None, :]
        h = _LINEARISE_STEP_PX
        n0 = np.stack([c.undistort_points(uv[i]) for i, c in enumerate(rig)])
        nx = np.stack([c.undistort_points(uv[i] + [h, 0.0]) for i, c in enumerate(rig)])
        ny = np.stack([c.undistort_points(uv[i] + [0.0, h]) for i, c in enumerate(rig)])
        J = np.stack([(nx - n0) / h, (ny - n0) / h], axis=-1)  # (V, J, 2, 2), columns d/du, d/dv
        good = np.isfinite(J).all(axis=(-2, -1)) & (np.abs(np.linalg.det(np.nan_to_num(J))) > 0)
        J = np.where(good[..., None, None], J, np.eye(2))
        self.n0, self.J, self.Jinv = n0, J, np.linalg.inv(J)
        self.R = np.stack([c.R for c in rig])
        self.t = np.stack([c.t for c in rig])
        self.C = np.stack([c.center for c in rig])
        self.distorted = any(c.has_distortion for c in rig)

    def normalised(self, O: np.ndarray) -> np.ndarray:
        """Normalised coordinates (V, nb, J, 2) for offsets O (nb, V, 2)."""
        d = O - self.offsets[None]
        return self.n0[:, None] + np.einsum("vjab,nvb->vnja", self.J, d)

    def rays(self, n: np.ndarray):
        """World rays (origins, unit directions), each (V, nb, J, 3), of normalised coordinates."""
        d_cam = np.concatenate([n, np.ones(n.shape[:-1] + (1,))], axis=-1)
        d = np.einsum("vnjc,vcd->vnjd", d_cam, self.R)  # R^T d_cam
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        return np.broadcast_to(self.C[:, None, None, :], d.shape), d

    def reprojection_px(self, X: np.ndarray, n: np.ndarray) -> np.ndarray:
        """Pixel residuals (V, nb, J, 2) of points X (nb, J, 3) against normalised coordinates n."""
        Xc = np.einsum("vdc,njc->vnjd", self.R, X) + self.t[:, None, None, :]
        proj = Xc[..., :2] / Xc[..., 2:3]
        return np.einsum("vjab,vnjb->vnja", self.Jinv, proj - n)


def gauge_basis(rig: Rig, point: np.ndarray, step_m: float = 1e-3) -> np.ndarray:
    """Pixel shifts of every view caused by translating a 3D point: the offsets' gauge.

    Parameters
    ----------
    rig : Rig
    point : array_like of shape (3,)
        A point on the body (e.g. its centroid), metres.
    step_m : float
        Finite-difference step, metres.

    Returns
    -------
    ndarray of shape (n_views * 2, 3)
        Column ``a`` holds the pixel shifts (view-major, x then y) per metre of
        translation along world axis ``a``.
    """
    X = np.asarray(point, float).reshape(3)
    cols = []
    for a in range(3):
        dX = np.zeros(3)
        dX[a] = step_m
        cols.append(((rig.project(X + dX) - rig.project(X - dX)) / (2 * step_m)).ravel())
    return np.stack(cols, axis=1)


def offsets_modulo_gauge(estimated: np.ndarray, true: np.ndarray, rig: Rig, point: np.ndarray,
                         views: np.ndarray | None = None) -> np.ndarray:
    """Offset errors with the gauge (a 3D translation of the body) removed.

    Parameters
    ----------
    estimated, true : ndarray of shape (n_views, 2)
        Pixels.
    rig : Rig
    point : array_like of shape (3,)
        Body centre, metres, for :func:`gauge_basis`.
    views : ndarray of shape (n_views,) of bool, optional
        Views to compare (default: all).

    Returns
    -------
    ndarray of shape (n_views, 2)
        ``estimated - true - G t`` with ``t`` the least-squares translation; NaN for
        views left out.
    """
    est = np.asarray(estimated, float)
    tru = np.asarray(true, float)
    if est.shape != tru.shape or est.shape != (len(rig), 2):
        raise InputError("offsets_modulo_gauge", f"estimated and true of shape ({len(rig)}, 2)",
                         f"{est.shape} and {tru.shape}")
    use = np.ones(len(rig), bool) if views is None else np.asarray(views, bool)
    G = gauge_basis(rig, point).reshape(len(rig), 2, 3)
    diff = est - tru
    t, *_ = np.linalg.lstsq(G[use].reshape(-1, 3), diff[use].ravel(), rcond=None)
    out = diff - G @ t
    out[~use] = np.nan
    return out


def corrected_rig(rig: Rig, offsets) -> Rig:
    """The cameras stage 1's offsets correct: every image-space consumer takes these.

    The one offset convention (issue 16): stage 1 adds its offsets to the
    detected 2D joints (``poses2d = poses2d_raw + offsets``) so that they meet
    the projections of its 3D joints through the measured cameras; a world
    point therefore appears in camera ``i``'s image at
    ``rig[i].project(X) - offsets[i]``.  Shifting each camera's principal
    point by ``-offsets[i]`` (:func:`toolkit.cameras.camera_with_offset`) makes
    that exact, lens distortion included, so segmentation, the position
    score, the billboards and the renderers take cameras only.

    Parameters
    ----------
    rig : Rig
        The cameras stage 1 used (measured, or refined on field lines).
    offsets : array_like of shape (n_cams, 2)
        Stage 1's offsets of one frame (``offsets.npz``, ``FrameEstimate.offsets``,
        ``MultiViewSelection.offsets``), pixels, rig order; NaN (a view that took
        no part) leaves that camera as it is.

    Returns
    -------
    Rig
        Same names, order and poses; principal points ``c_i - offsets[i]``.

    Raises
    ------
    InputError
        ``offsets`` not of shape (n_cams, 2).
    """
    off = np.asarray(offsets, dtype=np.float64)
    if off.shape != (len(rig), 2):
        raise InputError("corrected_rig: offsets", f"stage-1 pixel offsets of shape ({len(rig)}, 2)",
                         f"shape {off.shape}")
    return Rig(tuple(camera_with_offset(c, o) for c, o in zip(rig, image_offsets(off))))


def image_offsets(joint_offsets: np.ndarray) -> np.ndarray:
    """Convert stage-1 offsets to the shift from a measured camera's projection to the image.

    Stage 1 adds its offsets to the *detected* 2D joints so that they agree
    with the projections of the 3D joints through the measured cameras
    (``poses2d = poses2d_raw + offsets``).  Image-space consumers (template
    projection, billboard texturing, rendering) need the opposite shift: where
    a world point projected through a measured camera actually appears in that
    camera's image, ``image ≈ camera.project(X) + image_offsets``.

    Parameters
    ----------
    joint_offsets : ndarray of shape (..., 2)
        Offsets as stage 1 reports them (``offsets.npz``, ``MultiViewSelection.offsets``), pixels.

    Returns
    -------
    ndarray of shape (..., 2)
        ``-joint_offsets`` with NaN (unused views) replaced by 0.
    """
    return -np.nan_to_num(np.asarray(joint_offsets, dtype=np.float64), nan=0.0)
