"""The fitting energy of the depth tracker (source 001, step 230) as stacked residual blocks.

The energy of a skeleton ``X`` (13 control points, view frame) is a sum of
squared residuals, in blocks:

``surface``
    distance to the object: each filled bin of the orthographic grid is given
    to the nearest primitive of the body model (limb capsules, head / hand /
    foot spheres, the torso's elliptic cylinder); its residual is its distance
    to that primitive's axis minus the primitive's radius, i.e. the distance
    between the bin's osculating sphere of the model's radius and the skeleton;
``centres``
    distance to the object measured by the curvature centres: each osculating
    sphere centre is given to the nearest limb axis or end sphere, residual =
    its distance to that axis;
``contour``
    the skeleton lies behind the visible surface and inside the silhouette:
    for the control points and the limb midpoints, the distance outside the
    grid's silhouette (distance transform) and how far in front of the surface
    they are (only where the camera sees them);
``previous``
    distance to the previous (predicted) skeleton;
``rest``
    a weak pull of the hands and feet towards where they hang when relaxed
    (below the shoulders along the torso, below the hips), so that limbs the
    data say little about hang rather than wander (``rest_sigma_m``);
``length``, ``topology``, ``collision``, ``ground``
    the constraints of :mod:`toolkit.depth.constraints`.

Residuals are divided by their standard deviations (:class:`EnergyConfig`), so
the energy is dimensionless.  Data farther than ``gate_m`` from every
primitive are *unexplained*: they get no residual in the local minimisation
but cost ``(gate_m / sigma)^2`` each when energies of different skeletons are
compared (the global step), so a skeleton that explains more of the user wins.
Within ``gate_m`` a Huber weight keeps outliers from dominating.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import cv2
import numpy as np

from toolkit.pointcloud.cloud import ViewFrame
from toolkit.depth.constraints import ConstraintConfig, constraint_residuals
from toolkit.depth.curvature import PLANAR, CurvatureResult
from toolkit.body.control_points import (
    HEAD,
    L_ELBOW,
    L_FOOT,
    L_HAND,
    L_HIP,
    L_KNEE,
    L_SHOULDER,
    LIMBS,
    N_POINTS,
    R_FOOT,
    R_HAND,
    R_HIP,
    R_SHOULDER,
    BodyDimensions,
)
from toolkit.depth.orus import OrusGrid
from toolkit.depth.primitives import (
    _CAP_A,
    _CAP_B,
    _N_CAPS,
    _SPH,
    _TORSO_POINTS,
    _XYZ,
    N_PRIMITIVES,
    PRIMITIVE_NAMES,
    TORSO,
    capsule_distances,
    primitive_radii,
    sphere_distances,
    torso_distance,
)

__all__ = [
    "CONTOUR_SAMPLES",
    "N_PRIMITIVES",
    "PRIMITIVE_NAMES",
    "TORSO",
    "Assignment",
    "EnergyConfig",
    "EnergyTerms",
    "FitData",
    "Residuals",
    "assign",
    "energy_terms",
    "fit_data",
    "support_fraction",
    "unexplained_penalty",
]

#: Primitive order: the 8 limb capsules, the 5 end spheres, the torso.
_REST_BASE = np.array([L_SHOULDER, R_SHOULDER, L_HIP, R_HIP])
_REST_END = np.array([L_HAND, R_HAND, L_FOOT, R_FOOT])
_GRAVITY_VIEW = np.array([0.0, 1.0, 0.0])


def _rest_jacobian() -> np.ndarray:
    J = np.zeros((12, N_POINTS, 3))
    for k, (b, e) in enumerate(zip(_REST_BASE, _REST_END)):
        J[3 * k:3 * k + 3, e] = np.eye(3)
        J[3 * k:3 * k + 3, b] = -np.eye(3)
    return J


_REST_J = _rest_jacobian()

#: Fractions along each limb sampled by the contour term (besides the control points).
CONTOUR_FRACTIONS = (0.5,)


def _contour_samples() -> np.ndarray:
    """Weights (S, 13) of the points checked against the silhouette: the control points and
    the points at :data:`CONTOUR_FRACTIONS` along every limb."""
    W = [np.eye(N_POINTS)]
    for f in CONTOUR_FRACTIONS:
        for _, a, b, _ in LIMBS:
            w = np.zeros(N_POINTS)
            w[a], w[b] = 1.0 - f, f
            W.append(w[None])
    return np.concatenate(W)





#: Weights (S, 13) of the contour samples.
CONTOUR_SAMPLES = _contour_samples()


@dataclass(frozen=True)
class EnergyConfig:
    """Standard deviations and gates of the energy terms.

    Attributes
    ----------
    surface_sigma_m : float
        Surface points' distance to the model surface.
    centre_sigma_m : float
        Curvature centres' distance to the axes.
    contour_sigma_m : float
        Outside the silhouette / in front of the surface.
    previous_sigma_m : float
        Distance to the predicted skeleton.
    rest_sigma_m : float
        Distance of hands and feet to their relaxed positions.
    gate_m : float
        Data farther from every primitive are unexplained ...
    torso_gate_m : float
        ... and data are given to the torso only within this distance of its
        surface (the torso's shape is known well; data farther out belong to a
        limb in front of it or beside it).
    centre_gate_m : float
        Gate of the curvature centres.
    huber_sigmas : float
        Residuals beyond this many sigmas are down-weighted (Huber).
    behind_fraction : float
        A control point must be at least this fraction of its primitive's radius behind the surface ...
    max_behind_m : float
        ... and at most this far behind it (the thickness of a body seen from any side).
    """

    surface_sigma_m: float = 0.02
    centre_sigma_m: float = 0.05
    contour_sigma_m: float = 0.03
    previous_sigma_m: float = 0.10
    rest_sigma_m: float = 0.6
    gate_m: float = 0.25
    torso_gate_m: float = 0.08
    centre_gate_m: float = 0.12
    huber_sigmas: float = 2.0
    behind_fraction: float = 0.5
    max_behind_m: float = 0.35


@dataclass(frozen=True)
class FitData:
    """What the energy compares the skeleton with (view frame).

    Attributes
    ----------
    surface : ndarray of shape (B, 3)
        Filled bins' mean positions.
    surface_weight : ndarray of shape (B,)
        1 for occupied bins, less for bins filled from neighbours.
    planar : ndarray of shape (B,), bool
        Bins labelled planar.
    centres : ndarray of shape (K, 3)
        Osculating sphere centres.
    centre_weight : ndarray of shape (K,)
    outside : ndarray of shape (ny, nx)
        Distance outside the silhouette, metres (0 inside; bilinear between bin centres).
    surface_z : ndarray of shape (ny, nx)
        Depth of the visible surface per bin (NaN outside).
    origin : ndarray of shape (2,)
    bin_size : float
    frame : ViewFrame
    index : ndarray of shape (B, 2), int
        Grid (row, column) of each surface datum.
    """

    surface: np.ndarray
    surface_weight: np.ndarray
    planar: np.ndarray
    centres: np.ndarray
    centre_weight: np.ndarray
    outside: np.ndarray
    surface_z: np.ndarray
    origin: np.ndarray
    bin_size: float
    frame: ViewFrame
    index: np.ndarray

    @property
    def n_surface(self) -> int:
        return len(self.surface)


def fit_data(grid: OrusGrid, curvature: CurvatureResult | None, frame: ViewFrame,
             filled_weight: float = 0.5, keep: np.ndarray | None = None) -> FitData:
    """Collect the fitting data of one frame.

    Parameters
    ----------
    grid : OrusGrid
    curvature : CurvatureResult or None
    frame : ViewFrame
    filled_weight : float
        Weight of bins filled from neighbours.
    keep : ndarray of shape (ny, nx), bool, optional
        Bins that belong to the user (default: all filled bins); used to leave
        out a second person touching the user.
    """
    sel = grid.filled if keep is None else grid.filled & keep
    r, c = np.nonzero(sel)
    surface = grid.mean[r, c]
    w = np.where(grid.occupied[r, c], 1.0, filled_weight)
    planar = np.zeros(len(r), bool) if curvature is None else curvature.label[r, c] == PLANAR
    if curvature is not None and len(curvature.spheres):
        cen = curvature.spheres.centres
        cw = np.minimum(curvature.spheres.weights / 2.0, 1.5)
        if keep is not None:
            b = np.floor((cen[:, :2] - grid.origin) / grid.bin_size).astype(int)
            ny, nx = grid.shape
            ok = (b[:, 0] >= 0) & (b[:, 0] < nx) & (b[:, 1] >= 0) & (b[:, 1] < ny)
            ok[ok] = keep[b[ok, 1], b[ok, 0]]
            cen, cw = cen[ok], cw[ok]
    else:
        cen, cw = np.zeros((0, 3)), np.zeros(0)
    inside = sel.astype(np.uint8)
    if inside.any():
        dt = cv2.distanceTransform((1 - inside).astype(np.uint8), cv2.DIST_L2, 3).astype(np.float64)
    else:
        dt = np.full(sel.shape, 1e3)
    dt *= grid.bin_size
    zs = np.where(sel, grid.zmin, np.nan)
    return FitData(surface, w, planar, cen, cw, dt, zs, grid.origin.copy(), grid.bin_size, frame,
                   np.stack([r, c], -1))


# ---------------------------------------------------------- assignment
@dataclass(frozen=True)
class Assignment:
    """Which primitive explains each datum.

    Attributes
    ----------
    surface_prim : ndarray of shape (B,), int
        Primitive index (see :data:`PRIMITIVE_NAMES`), -1 when unexplained.
    surface_dist : ndarray of shape (B,)
        Signed distance to that primitive's surface, metres.
    centre_prim : ndarray of shape (K,), int
        Primitive of each curvature centre (capsules and end spheres only), -1 when unexplained.
    centre_dist : ndarray of shape (K,)
    surface_near : ndarray of shape (B,)
        Distance of each surface datum to the nearest primitive, whatever the gates.
    """

    surface_prim: np.ndarray
    surface_dist: np.ndarray
    centre_prim: np.ndarray
    centre_dist: np.ndarray
    surface_near: np.ndarray | None = None

    def explained_fraction(self) -> float:
        n = len(self.surface_prim)
        return float((self.surface_prim >= 0).mean()) if n else 0.0


def assign(data: FitData, X: np.ndarray, dims: BodyDimensions, config: EnergyConfig) -> Assignment:
    """Give every datum to its nearest primitive (or none beyond the gates)."""
    cr, sr = primitive_radii(dims)
    P = data.surface
    if len(P):
        dc, _, _, _ = capsule_distances(P, X, cr)
        ds, _, _ = sphere_distances(P, X, sr)
        dt, _ = torso_distance(P, X, dims)
        Ds = np.concatenate([dc, ds, dt[:, None]], axis=1)
        gates = np.full(N_PRIMITIVES, config.gate_m)
        gates[TORSO] = config.torso_gate_m
        D = np.abs(Ds)
        near = D.min(axis=1)
        D[D > gates] = np.inf
        k = np.argmin(D, axis=1)
        rows = np.arange(len(P))
        d = Ds[rows, k]
        k[~np.isfinite(D[rows, k])] = -1
    else:
        k, d, near = np.zeros(0, int), np.zeros(0), np.zeros(0)
    C = data.centres
    if len(C):
        _, dc, _, _ = capsule_distances(C, X, cr)
        _, ds, _ = sphere_distances(C, X, np.zeros(len(sr)))
        D = np.concatenate([dc, ds], axis=1)
        kc = np.argmin(D, axis=1)
        dcen = D[np.arange(len(C)), kc]
        kc = np.where(dcen <= config.centre_gate_m, kc, -1)
    else:
        kc, dcen = np.zeros(0, int), np.zeros(0)
    return Assignment(k, d, kc, dcen, near)


# ------------------------------------------------------------ residuals
class Residuals:
    """The stacked residual vector and its Jacobian for a fixed assignment.

    Parameters
    ----------
    data : FitData
    assignment : Assignment
    dims : BodyDimensions
    X_pred : ndarray of shape (13, 3)
        Predicted skeleton (the "previous skeleton" term).
    w_prev : ndarray of shape (13,)
        Per-point weights of the previous-skeleton term (0 = off).
    config : EnergyConfig
    constraints : ConstraintConfig
    ground_y : float or None
        View-frame y of the ground.
    """

    BLOCKS = ("surface", "centres", "contour", "previous", "rest", "length", "topology", "collision", "ground")

    def __init__(self, data: FitData, assignment: Assignment, dims: BodyDimensions, X_pred: np.ndarray,
                 w_prev: np.ndarray, config: EnergyConfig, constraints: ConstraintConfig, ground_y=None,
                 X_ref: np.ndarray | None = None):
        self.data = data
        self.dims = dims
        self.config = config
        self.constraints = constraints
        self.X_pred = np.asarray(X_pred, float)
        self.w_prev = np.asarray(w_prev, float)
        self.ground_y = ground_y
        self.cap_r, self.sph_r = primitive_radii(dims)
        a = assignment
        self.s_idx = np.nonzero(a.surface_prim >= 0)[0]
        self.s_prim = a.surface_prim[self.s_idx]
        # Huber weights from the distances at assignment time
        k = config.huber_sigmas * config.surface_sigma_m
        ad = np.abs(a.surface_dist[self.s_idx])
        self.s_w = data.surface_weight[self.s_idx] * np.sqrt(np.minimum(1.0, k / np.maximum(ad, 1e-9))) \
            / config.surface_sigma_m
        self.c_idx = np.nonzero(a.centre_prim >= 0)[0]
        self.c_prim = a.centre_prim[self.c_idx]
        kc = config.huber_sigmas * config.centre_sigma_m
        adc = np.abs(a.centre_dist[self.c_idx])
        self.c_w = data.centre_weight[self.c_idx] * np.sqrt(np.minimum(1.0, kc / np.maximum(adc, 1e-9))) \
            / config.centre_sigma_m
        self.sizes = None
        self._cache_list = []
        self._rest_J = _REST_J
        self._KV = data.frame.camera.K @ data.frame.view_from_cam.T   # view frame to homogeneous pixels
        self._wp = self.w_prev / config.previous_sigma_m
        self._Jp = np.diag(np.repeat(self._wp, 3))
        self._sgroups = self._groups(data.surface[self.s_idx], self.s_prim, self.s_w)
        self._cgroups = self._groups(data.centres[self.c_idx], self.c_prim, self.c_w)

    # ---------------------------------------------------------------- data
    @staticmethod
    def _groups(P, prim, w):
        """Split assigned points by primitive type once (capsules, spheres, torso)."""
        caps = np.nonzero(prim < _N_CAPS)[0]
        sph = np.nonzero((prim >= _N_CAPS) & (prim < TORSO))[0]
        tor = np.nonzero(prim == TORSO)[0]
        kc = prim[caps]
        ks = prim[sph] - _N_CAPS
        return {"n": len(P), "w": w,
                "caps": (caps, P[caps], kc, 3 * _CAP_A[kc][:, None] + _XYZ, 3 * _CAP_B[kc][:, None] + _XYZ),
                "sph": (sph, P[sph], ks, 3 * _SPH[ks][:, None] + _XYZ),
                "tor": (tor, P[tor])}

    def _points_block(self, X, g, with_radius: bool):
        """Residuals (n,) and Jacobian rows (n, 39) of points given to capsules / spheres / the torso."""
        n = g["n"]
        r = np.zeros(n)
        J = np.zeros((n, 3 * N_POINTS))
        if n == 0:
            return r, J
        i, P, k, ca, cb = g["caps"]
        if len(i):
            A, B = X[_CAP_A[k]], X[_CAP_B[k]]
            AB = B - A
            L2 = np.maximum(np.einsum("ij,ij->i", AB, AB), 1e-12)
            AP = P - A
            t = np.clip(np.einsum("ij,ij->i", AP, AB) / L2, 0.0, 1.0)
            q = AP - t[:, None] * AB
            dist = np.sqrt(np.einsum("ij,ij->i", q, q))
            qh = q / np.maximum(dist, 1e-9)[:, None]
            rad = self.cap_r[k, 0] + t * (self.cap_r[k, 1] - self.cap_r[k, 0]) if with_radius else 0.0
            r[i] = dist - rad
            rows = i[:, None]
            J[rows, ca] = -(1 - t)[:, None] * qh
            J[rows, cb] = -t[:, None] * qh
        i, P, k, cs = g["sph"]
        if len(i):
            q = P - X[_SPH[k]]
            dist = np.sqrt(np.einsum("ij,ij->i", q, q))
            r[i] = dist - (self.sph_r[k] if with_radius else 0.0)
            J[i[:, None], cs] = -q / np.maximum(dist, 1e-9)[:, None]
        i, P = g["tor"]
        if len(i):
            d, G = self._torso_block(X, P)
            r[i] = d
            for c, idx in enumerate(_TORSO_POINTS):
                J[i, 3 * idx:3 * idx + 3] = G[:, c]
        w = g["w"]
        return r * w, J * w[:, None]

    def _torso_block(self, X, P):
        """Torso residuals (n,) and their Jacobian (n, 4, 3) on (l_shoulder, r_shoulder, l_hip, r_hip)."""
        d, x = torso_distance(P, X, self.dims)
        n = len(P)
        G = np.zeros((n, 4, 3))
        v, qh, cl, a, b, rho = x["v"], x["qh"], x["cl"], x["a"], x["b"], x["rho"]
        # distance to the axis line through ms and mh: d/dms = -(1 - w) qh, d/dmh = -w qh,
        # w the projection parameter of the point along ms -> mh
        ms = 0.5 * (X[L_SHOULDER] + X[R_SHOULDER])
        mh = 0.5 * (X[L_HIP] + X[R_HIP])
        axis = mh - ms
        wpar = ((P - ms) @ axis) / max(axis @ axis, 1e-12)
        # moving the axis also turns the direction qh of the point, hence its angle on the ellipse
        rho3 = rho ** 3
        drho_dcl = -rho3 * cl * (1.0 / a ** 2 - 1.0 / b ** 2)
        el = x["el"]
        gC = -qh + (drho_dcl / np.maximum(x["rp"], 1e-6))[:, None] * (el[None] - cl[:, None] * qh)
        gs = (0.5 * (1 - wpar))[:, None] * gC
        gh = (0.5 * wpar)[:, None] * gC
        # the ellipse radius rho depends on the half-width a (shoulder and hip spans) and on the lateral axis
        drho_da = rho3 * cl ** 2 / a ** 3
        es = X[R_SHOULDER] - X[L_SHOULDER]
        eh = X[R_HIP] - X[L_HIP]
        es_u = es / max(np.sqrt(es @ es), 1e-9)
        eh_u = eh / max(np.sqrt(eh @ eh), 1e-9)
        ga_s = (-0.5 * drho_da * (1 - v))[:, None] * es_u[None]
        ga_h = (-0.5 * drho_da * v)[:, None] * eh_u[None]
        eu, nl = x["eu"], x["nl"]
        # d(cl)/d(lateral) = P_u (I - el el^T) qh / |P_u lateral|  (el is perpendicular to eu)
        qp = qh - (qh @ el)[:, None] * el[None]
        qp = qp - (qp @ eu)[:, None] * eu[None]
        g_lat = (-drho_dcl / max(nl, 1e-9))[:, None] * qp
        G[:, 0] = gs - ga_s - g_lat
        G[:, 1] = gs + ga_s + g_lat
        G[:, 2] = gh - ga_h - g_lat
        G[:, 3] = gh + ga_h + g_lat
        # beyond the ends: d = sqrt(max(d_rad, 0)^2 + beyond^2), the axial excess moving with the nearer end
        beyond = x["beyond"]
        out = np.abs(beyond) > 1e-9
        if out.any():
            dd = np.maximum(d[out], 1e-9)
            kr = np.maximum(x["d_rad"][out], 0.0) / dd
            kb = 0.5 * beyond[out] / dd
            Go = G[out] * kr[:, None, None]
            above = v[out] <= 0.0
            add = kb[:, None] * eu[None]
            Go[above, 0] += add[above]
            Go[above, 1] += add[above]
            Go[~above, 2] += add[~above]
            Go[~above, 3] += add[~above]
            G[out] = Go
        return d, G

    def _contour_block(self, X):
        data = self.data
        cfg = self.config
        S = CONTOUR_SAMPLES @ X                                      # (S, 3)
        nS = len(S)
        w = 1.0 / cfg.contour_sigma_m
        r = np.zeros(2 * nS)
        J = np.zeros((2 * nS, N_POINTS, 3))
        ph = S @ self._KV.T                                          # pinhole projection of view points
        z = ph[:, 2]
        zs_ = np.where(z > 1e-6, z, 1.0)
        u, v = ph[:, 0] / zs_, ph[:, 1] / zs_
        wimg, himg = data.frame.camera.size
        seen = (z > 1e-6) & (u >= 1) & (u <= wimg - 2) & (v >= 1) & (v <= himg - 2)
        g = (S[:, :2] - data.origin) / data.bin_size - 0.5
        ny, nx = data.outside.shape
        gi = np.clip(np.round(g[:, 1]).astype(int), 0, ny - 1)
        gj = np.clip(np.round(g[:, 0]).astype(int), 0, nx - 1)
        ingrid = (g[:, 0] >= -0.5) & (g[:, 0] <= nx - 0.5) & (g[:, 1] >= -0.5) & (g[:, 1] <= ny - 0.5)
        # outside the silhouette: bilinear distance transform
        x0 = np.clip(np.floor(g[:, 0]).astype(int), 0, nx - 2)
        y0 = np.clip(np.floor(g[:, 1]).astype(int), 0, ny - 2)
        fx = np.clip(g[:, 0] - x0, 0, 1)
        fy = np.clip(g[:, 1] - y0, 0, 1)
        D = data.outside
        val = (D[y0, x0] * (1 - fx) * (1 - fy) + D[y0, x0 + 1] * fx * (1 - fy) + D[y0 + 1, x0] * (1 - fx) * fy
               + D[y0 + 1, x0 + 1] * fx * fy)
        act = seen & ingrid & (val > 0)
        r[:nS] = np.where(act, val, 0.0) * w
        gx = ((D[y0, x0 + 1] - D[y0, x0]) * (1 - fy) + (D[y0 + 1, x0 + 1] - D[y0 + 1, x0]) * fy) / data.bin_size
        gy = ((D[y0 + 1, x0] - D[y0, x0]) * (1 - fx) + (D[y0 + 1, x0 + 1] - D[y0, x0 + 1]) * fx) / data.bin_size
        grad = np.stack([gx, gy], -1)
        Jin = np.zeros((nS, 3))
        Jin[:, :2] = np.where(act[:, None], grad, 0.0) * w
        J[:nS] = CONTOUR_SAMPLES[:, :, None] * Jin[:, None, :]
        # behind the visible surface, but not deeper than a body can be
        zs = data.surface_z[gi, gj]
        rad = self._sample_radius()
        front = zs + cfg.behind_fraction * rad - S[:, 2]
        back = S[:, 2] - (zs + cfg.max_behind_m)
        ok = seen & ingrid & np.isfinite(zs)
        act2 = ok & (front > 0)
        act3 = ok & (back > 0)
        r[nS:] = (np.where(act2, front, 0.0) + np.where(act3, back, 0.0)) * w
        Jb = np.zeros((nS, 3))
        Jb[:, 2] = np.where(act2, -w, 0.0) + np.where(act3, w, 0.0)
        J[nS:] = CONTOUR_SAMPLES[:, :, None] * Jb[:, None, :]
        return r, J

    def _rest_block(self, X):
        w = 1.0 / self.config.rest_sigma_m
        down = 0.5 * (X[L_HIP] + X[R_HIP]) - 0.5 * (X[L_SHOULDER] + X[R_SHOULDER])
        down = down / max(np.sqrt(down @ down), 1e-9)
        dirs = np.stack([down, down, _GRAVITY_VIEW, _GRAVITY_VIEW])
        L = np.asarray(self._rest_lengths)
        r = (w * (X[_REST_END] - X[_REST_BASE] - L[:, None] * dirs)).ravel()
        return r, self._rest_J * w

    @cached_property
    def _rest_lengths(self):
        d = self.dims
        arm = 0.97 * (d.length(L_SHOULDER, L_ELBOW) + d.length(L_ELBOW, L_HAND))
        leg = 0.97 * (d.length(L_HIP, L_KNEE) + d.length(L_KNEE, L_FOOT))
        return (arm, arm, leg, leg)

    def _sample_radius(self):
        if self.sizes is None:
            rad = np.full(N_POINTS, self.dims.radius("upper_arm")[1])
            rad[HEAD] = self.sph_r[0]
            rad[[L_HAND, R_HAND]] = self.dims.radius("hand") * 0.5
            rad[[L_FOOT, R_FOOT]] = self.dims.radius("foot") * 0.5
            torso = self.dims.radius("torso_half_depth")[0]
            rad[[L_SHOULDER, R_SHOULDER, L_HIP, R_HIP]] = 0.6 * torso
            mids = np.concatenate([self.cap_r[:, 0] + f * (self.cap_r[:, 1] - self.cap_r[:, 0])
                                   for f in CONTOUR_FRACTIONS])
            self.sizes = np.concatenate([rad, mids])
        return self.sizes

    # ------------------------------------------------------------- assembly
    def evaluate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual vector (M,) and Jacobian (M, 39) at ``x`` (39,)."""
        for cx, val in self._cache_list:
            if np.array_equal(x, cx):
                return val
        X = x.reshape(N_POINTS, 3)
        blocks = []
        blocks.append(self._points_block(X, self._sgroups, True))
        blocks.append(self._points_block(X, self._cgroups, False))
        blocks.append(self._contour_block(X))
        rp = ((X - self.X_pred) * self._wp[:, None]).ravel()
        blocks.append((rp, self._Jp))
        blocks.append(self._rest_block(X))
        for rr, JJ in constraint_residuals(X, self.dims, self.constraints, self.ground_y):
            blocks.append((rr, JJ))
        self.sizes_of_blocks = [len(b[0]) for b in blocks]
        r = np.concatenate([b[0] for b in blocks])
        J = np.concatenate([b[1].reshape(len(b[0]), 3 * N_POINTS) for b in blocks], axis=0)
        self._cache_list = ([(x.copy(), (r, J))] + self._cache_list)[:3]
        return r, J

    def fun(self, x):
        return self.evaluate(x)[0]

    def jac(self, x):
        return self.evaluate(x)[1]

    def block_energies(self, x: np.ndarray) -> dict:
        """Sum of squared residuals per block at ``x``."""
        r, _ = self.evaluate(x)
        out = {}
        k = 0
        names = list(self.BLOCKS)
        for name, n in zip(names, self.sizes_of_blocks):
            out[name] = float(np.sum(r[k:k + n] ** 2))
            k += n
        return out


def support_fraction(data: FitData, X: np.ndarray, config: EnergyConfig = EnergyConfig()) -> float:
    """Fraction of the skeleton's contour samples seen by the camera that the data support.

    A sample (control point or limb midpoint) inside the image is supported when
    its grid bin belongs to the user and its depth is between the visible surface
    (minus 10 cm) and ``max_behind_m`` behind it.  A skeleton that explains all
    the data but sits beside or behind the user scores low.
    """
    S = CONTOUR_SAMPLES @ np.asarray(X, float)
    uv = data.frame.project(S)
    wimg, himg = data.frame.camera.size
    seen = np.all(np.isfinite(uv), axis=1) & (uv[:, 0] >= 0) & (uv[:, 0] <= wimg - 1) & (uv[:, 1] >= 0) & \
        (uv[:, 1] <= himg - 1)
    if not seen.any():
        return 0.0
    g = np.round((S[:, :2] - data.origin) / data.bin_size - 0.5).astype(int)
    ny, nx = data.outside.shape
    ing = (g[:, 0] >= 0) & (g[:, 0] < nx) & (g[:, 1] >= 0) & (g[:, 1] < ny)
    zs = np.full(len(S), np.nan)
    zs[ing] = data.surface_z[g[ing, 1], g[ing, 0]]
    with np.errstate(invalid="ignore"):
        ok = ing & np.isfinite(zs) & (S[:, 2] > zs - 0.1) & (S[:, 2] < zs + config.max_behind_m)
    return float(ok[seen].mean())


@dataclass(frozen=True)
class EnergyTerms:
    """Energy of a skeleton with the data assigned at that skeleton.

    Attributes
    ----------
    terms : dict
        Sum of squared residuals per block, plus ``unexplained`` (the penalty
        of data beyond the gates).
    total : float
    explained : float
        Fraction of surface bins explained.
    assignment : Assignment
    """

    terms: dict = field(default_factory=dict)
    total: float = 0.0
    explained: float = 0.0
    assignment: Assignment | None = None


def unexplained_penalty(data: FitData, a: Assignment, config: EnergyConfig) -> float:
    """Energy of the data no primitive explains: ``(gate / sigma)^2 / 4`` per surface bin (weighted)
    and half that per curvature centre."""
    bad = a.surface_prim < 0
    wun = float(data.surface_weight[bad].sum()) if bad.any() else 0.0
    nc = int((a.centre_prim < 0).sum())
    return (wun * 0.25 * (config.gate_m / config.surface_sigma_m) ** 2
            + nc * 0.125 * (config.centre_gate_m / config.centre_sigma_m) ** 2)


def energy_terms(data: FitData, X: np.ndarray, dims: BodyDimensions, X_pred: np.ndarray, w_prev: np.ndarray,
                 config: EnergyConfig, constraints: ConstraintConfig, ground_y=None) -> EnergyTerms:
    """The energy of ``X`` (13, 3), re-assigning the data first (used to compare skeletons)."""
    a = assign(data, X, dims, config)
    res = Residuals(data, a, dims, X_pred, w_prev, config, constraints, ground_y)
    terms = res.block_energies(np.asarray(X, float).ravel())
    terms["unexplained"] = unexplained_penalty(data, a, config)
    return EnergyTerms(terms, float(sum(terms.values())), a.explained_fraction(), a)
