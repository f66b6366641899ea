"""The soft body's surface as a triangle mesh and as points.

The mesh comes from scikit-image's marching cubes
(:func:`skimage.measure.marching_cubes`, a maintained implementation with
sub-voxel interpolation) run on the distance of
:mod:`toolkit.softbody.distance` sampled on a grid around the primitives.
Surface points come from the primitives' own ellipsoids, projected onto the
blended surface by a few Newton steps along the distance gradient.
"""

from __future__ import annotations

import numpy as np
from skimage.measure import marching_cubes

from toolkit.errors import InputError
from toolkit.softbody.distance import distance, distance_and_jacobian
from toolkit.softbody.model import ModelState, SoftBodyModel, SoftBodyParams

__all__ = ["surface_mesh", "sample_surface", "unit_directions", "primitive_surface_points", "MAX_GRID_POINTS"]

#: Largest grid (voxels) a mesh may ask for: a 2 m person at 4 mm.
MAX_GRID_POINTS = 60_000_000


def surface_mesh(model: SoftBodyModel, params: SoftBodyParams, *, voxel: float = 0.01
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Triangle mesh of the model's surface (the zero level of the distance).

    Parameters
    ----------
    model : SoftBodyModel
    params : SoftBodyParams
    voxel : float
        Grid step, metres.

    Returns
    -------
    vertices : ndarray of shape (V, 3)
        World, metres.
    triangles : ndarray of shape (F, 3) int
        Counter-clockwise seen from outside.

    Raises
    ------
    InputError
        If ``voxel`` is not positive or the grid would be too large.
    """
    if not (np.isfinite(voxel) and voxel > 0):
        raise InputError("voxel", "a positive grid step in metres", repr(voxel))
    st = model.state(params)
    ext = st.radii.max(axis=1)[:, None]
    lo = (st.centres - ext).min(axis=0) - 3 * voxel
    hi = (st.centres + ext).max(axis=0) + 3 * voxel
    shape = np.ceil((hi - lo) / voxel).astype(int) + 1
    if np.prod(shape) > MAX_GRID_POINTS:
        raise InputError("voxel", f"a step giving at most {MAX_GRID_POINTS} grid points", f"{voxel} ({shape})")
    axes = [lo[i] + voxel * np.arange(shape[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    vol = distance(model, params, grid, state=st).reshape(shape)
    verts, faces, _, _ = marching_cubes(vol, level=0.0, spacing=(voxel,) * 3)
    # marching_cubes orders each triangle counter-clockwise seen from the higher values (outside)
    return verts + lo, faces.astype(np.int64)


def unit_directions(n: int) -> np.ndarray:
    """``n`` nearly uniform unit vectors (a Fibonacci sphere), shape (n, 3)."""
    if n < 1:
        raise InputError("n", "a positive number of directions", repr(n))
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5 ** 0.5) * k
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)


def primitive_surface_points(st: ModelState, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points on every primitive's ellipsoid along fixed directions of its axes.

    Parameters
    ----------
    st : ModelState
    directions : ndarray of shape (K, 3)
        Unit vectors in the primitive's axes.

    Returns
    -------
    points : ndarray of shape (P * K, 3)
        ``c_i + R_i (r_i * u_k)``, primitive-major.
    prims : ndarray of shape (P * K,) int
    """
    local = st.radii[:, None, :] * directions[None]  # (P, K, 3)
    pts = st.centres[:, None, :] + np.einsum("pij,pkj->pki", st.prim_R, local)
    prims = np.repeat(np.arange(len(st.centres)), len(directions))
    return pts.reshape(-1, 3), prims


def sample_surface(model: SoftBodyModel, params: SoftBodyParams, n: int,
                   rng: np.random.Generator | int | None = None, *, tol: float = 1e-4) -> np.ndarray:
    """Points on the model's surface (noiseless observations of the model itself).

    Each primitive's ellipsoid is sampled in random directions; samples buried
    in other primitives are dropped; the rest are moved onto the blended surface by
    Newton steps ``x -= D(x) grad D / |grad D|^2``.

    Parameters
    ----------
    model : SoftBodyModel
    params : SoftBodyParams
    n : int
        Number of points returned (drawn from the projected samples).
    rng : numpy.random.Generator or int or None
    tol : float
        Largest ``|D|`` of a returned point, metres.

    Returns
    -------
    ndarray of shape (n, 3)
        World, metres, ``|distance| <= tol``.
    """
    rng = np.random.default_rng(rng)
    st = model.state(params)
    per = max(8, int(np.ceil(4 * n / model.n_prims)))
    u = rng.normal(size=(model.n_prims, per, 3))
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    local = st.radii[:, None, :] * u
    x = (st.centres[:, None, :] + np.einsum("pij,pkj->pki", st.prim_R, local)).reshape(-1, 3)
    x = x[distance(model, params, x, state=st) > -0.01]
    for _ in range(6):
        d, J = distance_and_jacobian(model, params, x, state=st, columns=slice(3, 6))
        grad = -J  # d D / d x = - d D / d translation
        x = x - (d / np.maximum((grad * grad).sum(1), 1e-6))[:, None] * grad
    x = x[np.abs(distance(model, params, x, state=st)) <= tol]
    if len(x) < n:
        raise InputError("n", f"at most {len(x)} surface points for this model", repr(n))
    return x[rng.choice(len(x), n, replace=False)]
