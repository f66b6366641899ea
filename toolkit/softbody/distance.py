"""Distance from 3D points to the soft body's implicit surface, with analytic derivatives.

The distance is the log of the summed metaball densities (see
:mod:`toolkit.softbody.model`): ``D(x) = -blend * log(sum_i exp(-e_i(x) / blend))``,
negative inside, zero on the surface, in metres; near a single primitive it is
the radial distance to that ellipsoid.  Its derivatives with respect to every
parameter are written out (vectorised numpy, no finite differences):

* a rotation about world axis ``w`` through pivot ``o`` moving the primitives
  of a subtree: ``dD = -w . ((x - o) x S)`` with ``S`` the density-weighted sum of the
  primitives' world gradients over the subtree;
* the root translation: ``-S`` over all primitives;
* lengths: the primitives' centre derivatives (plus the axial radii of the
  stretched primitives); widths: the radii.
"""

from __future__ import annotations

import numpy as np

from toolkit.errors import InputError
from toolkit.softbody.model import LENGTHS, N_PARAMS, POSE, WIDTHS, ModelState, SoftBodyModel, SoftBodyParams

__all__ = ["distance", "distance_and_jacobian", "primitive_distances", "check_points", "CHUNK"]

#: Points per block when evaluating large point sets (bounds the (N, P, 3) temporaries).
CHUNK = 20000
_EPS = 1e-6


def check_points(points, name: str = "points") -> np.ndarray:
    """``points`` as a finite float array of shape (N, 3) (N may be 0)."""
    x = np.asarray(points, dtype=float)
    if x.ndim != 2 or x.shape[1] != 3:
        raise InputError(name, "an array of shape (N, 3), metres", f"shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise InputError(name, "finite coordinates", "NaN or inf values")
    return x


def primitive_distances(st: ModelState, points: np.ndarray, *, local: bool = False):
    """Radial distance of each point to each ellipsoid.

    Parameters
    ----------
    st : ModelState
    points : ndarray of shape (N, 3)
    local : bool
        Also return the points in each primitive's axes.

    Returns
    -------
    e : ndarray of shape (N, P)
        ``|p| (1 - 1/sqrt(q))``, metres, negative inside.
    p : ndarray of shape (N, P, 3)
        Only with ``local``: ``R_i^T (x - c_i)``.
    """
    n, P = len(points), len(st.centres)
    Rcat = st.prim_R.transpose(1, 0, 2).reshape(3, P * 3)  # p_i = R_i^T (x - c_i), as rows
    p = (points @ Rcat).reshape(n, P, 3) - np.einsum("pi,pij->pj", st.centres, st.prim_R)[None]
    inv_r = 1.0 / st.radii
    p2 = p * p
    u2 = p2 * (inv_r * inv_r)[None]
    s = np.sqrt(np.maximum(u2[..., 0] + u2[..., 1] + u2[..., 2], _EPS ** 2))
    r = np.sqrt(p2[..., 0] + p2[..., 1] + p2[..., 2] + _EPS ** 2)
    e = r * (1.0 - 1.0 / s)
    return (e, p) if local else e


def _soft_min(e: np.ndarray, blend: float) -> tuple[np.ndarray, np.ndarray]:
    m = e.min(axis=1, keepdims=True)
    z = np.exp(-(e - m) / blend)
    tot = z.sum(axis=1, keepdims=True)
    return (m - blend * np.log(tot))[:, 0], z / tot


def distance(model: SoftBodyModel, params: SoftBodyParams, points, *, state: ModelState | None = None) -> np.ndarray:
    """Distance of points to the model's surface.

    Parameters
    ----------
    model : SoftBodyModel
    params : SoftBodyParams
    points : array_like of shape (N, 3)
        World, metres.
    state : ModelState, optional
        ``model.state(params)`` when already computed.

    Returns
    -------
    ndarray of shape (N,)
        Metres: negative inside, 0 on the surface.
    """
    x = check_points(points)
    st = model.state(params) if state is None else state
    out = np.empty(len(x))
    for a in range(0, len(x), CHUNK):
        out[a:a + CHUNK] = _soft_min(primitive_distances(st, x[a:a + CHUNK]), model.blend)[0]
    return out


def distance_and_jacobian(model: SoftBodyModel, params: SoftBodyParams, points, *,
                          state: ModelState | None = None, columns: slice | None = None):
    """Distance of points to the surface and its Jacobian with respect to the parameters.

    Parameters
    ----------
    model : SoftBodyModel
    params : SoftBodyParams
    points : array_like of shape (N, 3)
    state : ModelState, optional
    columns : slice, optional
        Only these parameter columns (e.g. ``model.POSE``); default all 47.

    Returns
    -------
    d : ndarray of shape (N,)
        Metres.
    jac : ndarray of shape (N, 47) (or the selected columns)
        ``d d / d params``; lengths in metres per metre, widths per unit multiplier.
    """
    x = check_points(points)
    st = model.state(params) if state is None else state
    cols = slice(0, N_PARAMS) if columns is None else columns
    n_cols = len(range(N_PARAMS)[cols])
    d = np.empty(len(x))
    jac = np.empty((len(x), n_cols))
    for a in range(0, len(x), CHUNK):
        d[a:a + CHUNK], J = _chunk(model, st, x[a:a + CHUNK], cols)
        jac[a:a + CHUNK] = J
    return d, jac


#: Pairs (point, primitive) whose share of the density is below this are left
#: out of the derivatives (their weight in every derivative is below it too).
MIN_WEIGHT = 1e-9


def _chunk(model: SoftBodyModel, st: ModelState, x: np.ndarray, cols: slice):
    n, P = len(x), model.n_prims
    e, p = primitive_distances(st, x, local=True)
    d, w = _soft_min(e, model.blend)
    ni, pi = np.nonzero(w > MIN_WEIGHT)  # the few primitives that matter for each point
    pp, wp = p[ni, pi], w[ni, pi]
    inv_r = 1.0 / st.radii[pi]
    p2 = pp * pp
    s = np.sqrt(np.maximum((p2 * inv_r * inv_r).sum(1), _EPS ** 2))
    r = np.sqrt(p2.sum(1) + _EPS ** 2)
    k = r / s ** 3
    de_dp = pp * ((1.0 - 1.0 / s) / r)[:, None] + pp * inv_r ** 2 * k[:, None]
    de_dr = -p2 * inv_r ** 3 * k[:, None]
    g = np.zeros((n, P, 3))  # density-weighted world gradients
    g[ni, pi] = np.einsum("mij,mj->mi", st.prim_R[pi], de_dp) * wp[:, None]
    J = np.zeros((n, N_PARAMS))
    need = set(range(N_PARAMS)[cols])
    if need & set(range(POSE.stop)):
        # per subtree root f: sum of g over the primitives of frames at or below f
        S_sub = (np.swapaxes(g, 1, 2).reshape(n * 3, P) @ (model.prim_onehot_frame @ model.subtree.T.astype(float))
                 ).reshape(n, 3, -1)
        J[:, 3:6] = -S_sub[:, :, 0]
        S = S_sub[:, :, st.dof_frames]  # (N, 3, K)
        a = x[:, :, None] - st.dof_pivots.T[None]  # (N, 3, K)
        w_ = st.dof_axes.T  # (3, K)
        # -w . (a x S) = -(w x a) . S
        rot = -((w_[1] * a[:, 2] - w_[2] * a[:, 1]) * S[:, 0] + (w_[2] * a[:, 0] - w_[0] * a[:, 2]) * S[:, 1]
                + (w_[0] * a[:, 1] - w_[1] * a[:, 0]) * S[:, 2])
        J[:, 0:3] = rot[:, 0:3]
        J[:, 6:POSE.stop] = rot[:, 6:POSE.stop]
    if need & set(range(LENGTHS.start, WIDTHS.stop)):
        dc = st.dcentres_dlengths  # (P, M, 3)
        M = dc.shape[1]
        J[:, LENGTHS] = -g.reshape(n, -1) @ dc.transpose(0, 2, 1).reshape(P * 3, M)
        # stretched primitives: rz = a * L
        rz_per_len = np.where(model.prim_axial, model.prim_radii[:, 2], 0.0)[pi]
        dr = np.zeros((n, P))
        dr[ni, pi] = wp * de_dr[:, 2] * rz_per_len
        J[:, LENGTHS] += dr @ model.prim_onehot_length
        base = model.prim_radii[pi].copy()
        base[:, 2] = np.where(model.prim_axial[pi], 0.0, base[:, 2])
        dw = np.zeros((n, P))
        dw[ni, pi] = wp * (de_dr * base).sum(1)
        J[:, WIDTHS] = dw @ model.prim_onehot_group
    return d, J[:, cols]
