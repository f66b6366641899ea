"""Residual blocks shared by tracking and the global fit.

* **data**: the distance of each cloud point to the model's surface
  (:func:`toolkit.softbody.distance.distance_and_jacobian`); points only
  constrain the surface where they are.
* **coverage**: the distance from points on the model's visible surface to the
  nearest cloud point (a KD-tree query each evaluation, as in ICP), so a part
  cannot drift into a region without points, nor the body shrink or slip out
  of the cloud.  Which model points count is fixed per frame: those on the
  outer surface and, when viewpoints are given, facing one of them (the far
  side of the body has no points to be close to).  The global fit gives each
  sample an allowance, its distance to the cloud in the tracked pose
  (:meth:`CoverageSamples.allowing`): a sample far from every point there (a
  hand or a face a stereo matcher found no texture on) may stay as far, but
  is not pulled into the nearest points, which shortened the limbs.

Robust losses are applied per block by the square-root trick: a residual
``r`` with loss ``rho`` becomes ``sign(r) sqrt(2 rho(r))`` and its Jacobian
row is scaled by ``rho'(r) / sqrt(2 rho(r))``, so each block keeps its own
loss and scale inside one ``least_squares(loss="linear")`` problem.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from threadpoolctl import ThreadpoolController

from toolkit.errors import InputError
from toolkit.softbody.distance import distance, distance_and_jacobian
from toolkit.softbody.mesh import primitive_surface_points, unit_directions
from toolkit.softbody.model import WIDTHS, ModelState, SoftBodyModel, SoftBodyParams, attached_points_jacobian

__all__ = ["robust", "LOSSES", "CoverageSamples", "coverage_samples", "coverage_residuals", "data_residuals",
           "gate_points", "one_blas_thread",
           "coverage_margin"]

LOSSES = ("linear", "soft_l1", "huber", "cauchy")
_CONTROLLER = None


def one_blas_thread():
    """Context limiting BLAS to one thread while fitting.

    The fits' matrices are small (thousands x 27 to 47); on a busy machine
    multi-threaded BLAS made one tracked frame 10x slower (measured: 13.8 s
    against 1.4 s with one thread, 2 shared cores).  The controller is built
    once (scanning the loaded libraries costs tens of milliseconds).
    """
    global _CONTROLLER
    if _CONTROLLER is None:
        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER.limit(limits=1, user_api="blas")


def robust(r: np.ndarray, J: np.ndarray | None, loss: str, scale: float):
    """Residuals (and Jacobian rows) with a robust loss folded in.

    Parameters
    ----------
    r : ndarray of shape (N,)
    J : ndarray of shape (N, K) or None
    loss : {"linear", "soft_l1", "huber", "cauchy"}
    scale : float
        Residual size where the loss turns robust (metres for distances).

    Returns
    -------
    r2 : ndarray of shape (N,)
        ``0.5 * r2**2 == rho(r)``.
    J2 : ndarray of shape (N, K) or None
    """
    if loss not in LOSSES:
        raise InputError("loss", f"one of {LOSSES}", repr(loss))
    if loss == "linear":
        return r, J
    z = (r / scale) ** 2
    if loss == "soft_l1":
        phi, dphi = 2 * scale ** 2 * (np.sqrt(1 + z) - 1), 2 * r / np.sqrt(1 + z)
    elif loss == "cauchy":
        phi, dphi = scale ** 2 * np.log1p(z), 2 * r / (1 + z)
    else:  # huber
        a = np.abs(r)
        phi = np.where(a <= scale, r * r, 2 * scale * a - scale ** 2)
        dphi = np.where(a <= scale, 2 * r, 2 * scale * np.sign(r))
    r2 = np.sign(r) * np.sqrt(np.maximum(phi, 0.0))
    # d r2 / d r = dphi / (2 r2), -> 1 as r -> 0
    small = np.abs(r2) < 1e-12
    g = np.where(small, 1.0, dphi / (2 * np.where(small, 1.0, r2)))
    return r2, (None if J is None else J * g[:, None])


def data_residuals(model: SoftBodyModel, params: SoftBodyParams, points: np.ndarray, st: ModelState,
                   columns: np.ndarray, loss: str, scale: float, with_jac: bool = True):
    """Robust point-to-surface residuals and their Jacobian over ``columns``, (N,), (N, len(columns)) or None."""
    if not with_jac:
        return robust(distance(model, params, points, state=st), None, loss, scale)
    d, J = distance_and_jacobian(model, params, points, state=st)
    return robust(d, J[:, columns], loss, scale)


class CoverageSamples:
    """The model points of the coverage block for one frame.

    Attributes
    ----------
    prims : ndarray of shape (S,) int
        Primitive of each sample.
    dirs : ndarray of shape (S, 3)
        Unit direction of each sample in its primitive's axes.
    """

    def __init__(self, prims: np.ndarray, dirs: np.ndarray, allowance: np.ndarray | None = None):
        self.prims = np.asarray(prims, int)
        self.dirs = np.asarray(dirs, float)
        self.allowance = np.zeros(len(self.prims)) if allowance is None else np.asarray(allowance, float)
        if self.allowance.shape != self.prims.shape:
            raise InputError("CoverageSamples.allowance", f"shape {self.prims.shape}", f"shape {self.allowance.shape}")

    def __len__(self) -> int:
        return len(self.prims)

    def allowing(self, st: ModelState, tree: cKDTree) -> "CoverageSamples":
        """The same samples, each allowed its present distance to the cloud (metres).

        ``st`` is the model state the samples were taken in (the tracked
        pose), ``tree`` the cloud's KD-tree.  :func:`coverage_residuals` then
        counts only what a sample moves further away than that: the block
        still holds the model inside the cloud where it had points, but no
        longer pulls surface that had none into the nearest points.  On a
        stereo cloud the skin of the hands has few points (trinocular wave
        3100: 5-7 per hand and frame against 20-80 per arm segment; SGBM
        finds little texture on skin), and the coverage of the model's hands
        pulled them into the forearms' points: with the hands' points taken
        out of a walk of the model's own surface, the global fit shortened
        the upper arms and forearms by 19-21 mm each, by 3.5-4.8 mm with the
        allowance (``tests/softbody/test_arm_lengths.py``).
        """
        if len(self) == 0:
            return self
        d, _ = tree.query(self.points(st))
        return CoverageSamples(self.prims, self.dirs, d)

    def points(self, st: ModelState) -> np.ndarray:
        """World positions (S, 3) for a model state."""
        local = st.radii[self.prims] * self.dirs
        return st.centres[self.prims] + np.einsum("sij,sj->si", st.prim_R[self.prims], local)

    def jacobian(self, model: SoftBodyModel, st: ModelState) -> np.ndarray:
        """Derivatives of the points with respect to all parameters, shape (S, 3, 47)."""
        pts = self.points(st)
        R = st.prim_R[self.prims]
        axial = model.prim_axial[self.prims]
        base = model.prim_radii[self.prims]
        # lengths: the centre, plus the axial radius of stretched primitives
        dL = st.dcentres_dlengths[self.prims].copy()  # (S, M, 3)
        rz = np.where(axial, base[:, 2], 0.0)[:, None] * self.dirs[:, 2:3] * R[:, :, 2]  # (S, 3)
        dL += model.prim_onehot_length[self.prims][:, :, None] * rz[:, None, :]
        J = attached_points_jacobian(model, st, pts, model.prim_frame[self.prims], dL)
        wbase = base.copy()
        wbase[:, 2] = np.where(axial, 0.0, wbase[:, 2])
        dw = np.einsum("sij,sj->si", R, wbase * self.dirs)  # (S, 3) per unit of the primitive's width
        onehot = model.prim_onehot_group[self.prims]  # (S, G)
        J[:, :, WIDTHS] = dw[:, :, None] * onehot[:, None, :]
        return J


def coverage_samples(model: SoftBodyModel, params: SoftBodyParams, *, n_dirs: int = 24,
                     viewpoints: np.ndarray | None = None, surface_tol: float = 0.01) -> CoverageSamples:
    """Choose the model points of the coverage block for a frame.

    Parameters
    ----------
    model, params
    n_dirs : int
        Directions per primitive.
    viewpoints : ndarray of shape (C, 3), optional
        Camera centres, metres; only samples facing one of them are kept.
    surface_tol : float
        Samples deeper than this inside the blended surface are dropped (buried
        in another primitive).

    Returns
    -------
    CoverageSamples
    """
    st = model.state(params)
    dirs = unit_directions(n_dirs)
    pts, prims = primitive_surface_points(st, dirs)
    d, J = distance_and_jacobian(model, params, pts, state=st, columns=slice(3, 6))
    keep = d > -surface_tol
    if viewpoints is not None:
        v = np.asarray(viewpoints, float).reshape(-1, 3)
        normal = -J  # gradient of the distance in x
        facing = np.einsum("nc,vnc->vn", normal, v[:, None, :] - pts[None]) > 0
        keep &= facing.any(axis=0)
    idx = np.flatnonzero(keep)
    return CoverageSamples(prims[idx], np.tile(dirs, (model.n_prims, 1))[idx])


def coverage_residuals(model: SoftBodyModel, st: ModelState, samples: CoverageSamples, tree: cKDTree,
                       cloud: np.ndarray, columns: np.ndarray, loss: str, scale: float, margin: float,
                       with_jac: bool = True):
    """Robust distances from the samples to their nearest cloud points, (S,), (S, len(columns)).

    Distances below ``margin`` (metres: the spacing of the cloud's points),
    or below a sample's own ``allowance`` where that is larger
    (:meth:`CoverageSamples.allowing`), count as zero, so the block vanishes
    on a model that lies in its cloud.
    """
    if len(samples) == 0:
        return np.zeros(0), np.zeros((0, len(columns)))
    y = samples.points(st)
    _, nn = tree.query(y)
    diff = y - cloud[nn]
    dist = np.sqrt((diff * diff).sum(1) + 1e-12)
    r = np.maximum(dist - np.maximum(margin, samples.allowance), 0.0)
    J = None
    if with_jac:
        u = diff / dist[:, None] * (r > 0)[:, None]
        J = np.einsum("sc,sck->sk", u, samples.jacobian(model, st)[:, :, columns])
    return robust(r, J, loss, scale)


def coverage_margin(tree: cKDTree, points: np.ndarray, floor: float) -> float:
    """Distance below which a model point counts as covered by a cloud, metres.

    Twice the 90th percentile of the cloud's nearest-neighbour spacing, at
    least ``floor``: a model surface lying in the cloud is then covered almost
    everywhere, so the coverage block vanishes there instead of biasing the fit.
    """
    if len(points) < 2:
        return float(floor)
    d, _ = tree.query(points, k=2)
    return float(max(floor, 2.0 * np.percentile(d[:, 1], 90)))


def gate_points(model: SoftBodyModel, params: SoftBodyParams, points: np.ndarray, gate: float) -> np.ndarray:
    """Indices of the points within ``gate`` metres outside the model (anything inside is kept)."""
    if len(points) == 0:
        return np.zeros(0, int)
    return np.flatnonzero(distance(model, params, points) < gate)
