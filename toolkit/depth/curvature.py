"""Curvature centres and osculating spheres from the grid's normals (source 001, step 220, figure 6).

For every filled bin of the orthographic user grid and each of four directions
(horizontal, vertical, two diagonals) the normal lines of the bin's two
neighbours are intersected: the distance ``t`` along the inward normals where
they meet best (least squares),

    t = (p_b - p_a) . (n_b - n_a) / |n_b - n_a|^2 ,

is the radius of curvature in that direction, and ``(n_b - n_a) . (p_b - p_a) /
|p_b - p_a|^2`` the curvature (positive convex, negative concave).  The most
curved direction labels the bin:

* **planar** when no direction curves more than ``1 / planar_radius_m`` (the torso),
* **convex** when it does, outwards (limbs, head); its curvature centre is
  ``p - r n`` with the radius of that direction,
* **concave** when it curves inwards (discarded, as in the source).

The convex bins' curvature centres are accumulated in a grid of the same
layout; the density maxima (cells at least as dense as both neighbours along
one of the four directions, with at least ``min_votes`` votes) are the centres
of the osculating spheres, each with the mean radius of its votes.  Joined,
they trace the central axes of the limbs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.depth.orus import OrusGrid
from toolkit.errors import InputError

__all__ = [
    "CONCAVE",
    "CONVEX",
    "LABEL_NAMES",
    "PLANAR",
    "CurvatureConfig",
    "CurvatureResult",
    "OsculatingSpheres",
    "curvature_centres",
]

#: Bin / sphere labels (0 = no data).
PLANAR, CONVEX, CONCAVE = 1, 2, 3
LABEL_NAMES = {0: "none", PLANAR: "planar", CONVEX: "convex", CONCAVE: "concave"}
_DIRS = ((0, 1), (1, 0), (1, 1), (1, -1))


@dataclass(frozen=True)
class CurvatureConfig:
    """Settings of the curvature centres.

    Attributes
    ----------
    planar_radius_m : float
        Surfaces curving less than ``1 / planar_radius_m`` in every direction are planar.
    min_radius_m, max_radius_m : float
        Radii of convex bins are clipped to this range.
    min_votes : float
        Votes a density maximum needs to become a sphere.
    """

    planar_radius_m: float = 0.30
    min_radius_m: float = 0.02
    max_radius_m: float = 0.20
    min_votes: float = 1.5

    def __post_init__(self):
        if not 0 < self.min_radius_m < self.max_radius_m <= self.planar_radius_m:
            raise InputError("CurvatureConfig", "0 < min_radius_m < max_radius_m <= planar_radius_m",
                             f"{self.min_radius_m}, {self.max_radius_m}, {self.planar_radius_m}")


@dataclass(frozen=True)
class OsculatingSpheres:
    """Osculating spheres of the convex parts (view frame).

    Attributes
    ----------
    centres : ndarray of shape (K, 3)
        Metres.
    radii : ndarray of shape (K,)
        Metres.
    weights : ndarray of shape (K,)
        Accumulated votes.
    """

    centres: np.ndarray
    radii: np.ndarray
    weights: np.ndarray

    def __len__(self) -> int:
        return len(self.radii)


@dataclass(frozen=True)
class CurvatureResult:
    """Per-bin curvature and the osculating spheres.

    Attributes
    ----------
    label : ndarray of shape (ny, nx), int8
        0 none, :data:`PLANAR`, :data:`CONVEX`, :data:`CONCAVE`.
    curvature : ndarray of shape (ny, nx)
        Largest curvature over the four directions, 1/m (NaN where unknown).
    radius : ndarray of shape (ny, nx)
        Radius of convex bins, metres (NaN elsewhere).
    centre : ndarray of shape (ny, nx, 3)
        Curvature centre of convex bins (NaN elsewhere).
    accumulator : ndarray of shape (ny, nx)
        Votes of the curvature centres per cell.
    spheres : OsculatingSpheres
    """

    label: np.ndarray
    curvature: np.ndarray
    radius: np.ndarray
    centre: np.ndarray
    accumulator: np.ndarray
    spheres: OsculatingSpheres


def _shift(a: np.ndarray, di: int, dj: int, fill) -> np.ndarray:
    """``out[i, j] = a[i + di, j + dj]`` (``fill`` outside)."""
    out = np.full_like(a, fill)
    ny, nx = a.shape[:2]
    si = slice(max(di, 0), ny + min(di, 0))
    di_ = slice(max(-di, 0), ny + min(-di, 0))
    sj = slice(max(dj, 0), nx + min(dj, 0))
    dj_ = slice(max(-dj, 0), nx + min(-dj, 0))
    out[di_, dj_] = a[si, sj]
    return out


def curvature_centres(grid: OrusGrid, config: CurvatureConfig = CurvatureConfig()) -> CurvatureResult:
    """Curvature centres, bin labels and osculating spheres of an orthographic user grid.

    Parameters
    ----------
    grid : OrusGrid
    config : CurvatureConfig

    Returns
    -------
    CurvatureResult
    """
    P = grid.mean
    N = grid.normal
    ok = grid.filled & np.all(np.isfinite(N), axis=-1) & np.all(np.isfinite(P), axis=-1)
    ny, nx = ok.shape
    best_k = np.full((ny, nx), -np.inf)
    best_t = np.full((ny, nx), np.nan)
    min_k = np.full((ny, nx), np.inf)
    # work on the usable bins only, with a one-bin border of "missing" around the grid
    rr, cc = np.nonzero(ok)
    okp = np.pad(ok, 1)
    Pp = np.pad(np.where(ok[..., None], P, 0.0), ((1, 1), (1, 1), (0, 0)))
    Np = np.pad(np.where(ok[..., None], N, 0.0), ((1, 1), (1, 1), (0, 0)))
    r1, c1 = rr + 1, cc + 1
    Pc, Nc = Pp[r1, c1], Np[r1, c1]
    bk = np.full(len(rr), -np.inf)
    bt = np.full(len(rr), np.nan)
    mk = np.full(len(rr), np.inf)
    for di, dj in _DIRS:
        ra, ca, rb, cb = r1 - di, c1 - dj, r1 + di, c1 + dj
        oa, ob = okp[ra, ca], okp[rb, cb]
        # central difference where both neighbours exist, one-sided otherwise (missing = the bin itself)
        p0 = np.where(oa[:, None], Pp[ra, ca], Pc)
        p1 = np.where(ob[:, None], Pp[rb, cb], Pc)
        n0 = np.where(oa[:, None], Np[ra, ca], Nc)
        n1 = np.where(ob[:, None], Np[rb, cb], Nc)
        use = oa | ob
        dp = p1 - p0
        dn = n1 - n0
        pp = np.einsum("ij,ij->i", dp, dp)
        nn = np.einsum("ij,ij->i", dn, dn)
        pn = np.einsum("ij,ij->i", dp, dn)
        with np.errstate(divide="ignore", invalid="ignore"):
            k = np.where(use & (pp > 1e-12), pn / pp, np.nan)
            t = np.where(use & (nn > 1e-12), pn / nn, np.nan)
        valid = np.isfinite(k)
        better = valid & (k > bk)
        bk = np.where(better, k, bk)
        bt = np.where(better, t, bt)
        mk = np.where(valid & (k < mk), k, mk)
    best_k[rr, cc] = bk
    best_t[rr, cc] = bt
    min_k[rr, cc] = mk
    # labels, radii and centres on the usable bins only
    has = np.isfinite(bk)
    k_planar = 1.0 / config.planar_radius_m
    cvx = has & (bk >= k_planar) & (bk >= -mk)
    ccv = has & ~cvx & (mk <= -k_planar)
    pln = has & ~cvx & ~ccv
    label = np.zeros((ny, nx), np.int8)
    label[rr[pln], cc[pln]] = PLANAR
    label[rr[cvx], cc[cvx]] = CONVEX
    label[rr[ccv], cc[ccv]] = CONCAVE
    rb = np.where(np.isfinite(bt), bt, 1.0 / np.maximum(bk, 1e-9))[cvx]
    rb = np.minimum(np.maximum(rb, config.min_radius_m), config.max_radius_m)
    cs = Pc[cvx] - rb[:, None] * Nc[cvx]
    rs = rb
    radius = np.full((ny, nx), np.nan)
    radius[rr[cvx], cc[cvx]] = rb
    centre = np.full((ny, nx, 3), np.nan)
    centre[rr[cvx], cc[cvx]] = cs
    curvature = np.full((ny, nx), np.nan)
    curvature[rr[has], cc[has]] = bk[has]
    # accumulate the curvature centres and find the density maxima
    acc = np.zeros((ny, nx))
    spheres = OsculatingSpheres(np.zeros((0, 3)), np.zeros(0), np.zeros(0))
    if len(cs):
        b = np.floor((cs[:, :2] - grid.origin) / grid.bin_size).astype(np.int64)
        inside = (b[:, 0] >= 0) & (b[:, 0] < nx) & (b[:, 1] >= 0) & (b[:, 1] < ny)
        lin = b[inside, 1] * nx + b[inside, 0]
        w = np.bincount(lin, minlength=ny * nx)
        sc = np.stack([np.bincount(lin, weights=cs[inside, i], minlength=ny * nx) for i in range(3)], -1)
        sr = np.bincount(lin, weights=rs[inside], minlength=ny * nx)
        acc = w.reshape(ny, nx).astype(float)
        ridge = np.zeros((ny, nx), bool)
        for di, dj in _DIRS:
            ridge |= (acc >= _shift(acc, di, dj, 0.0)) & (acc >= _shift(acc, -di, -dj, 0.0))
        peak = (ridge & (acc >= config.min_votes)).ravel()
        idx = np.nonzero(peak)[0]
        if len(idx):
            spheres = OsculatingSpheres(sc[idx] / w[idx, None], sr[idx] / w[idx], w[idx].astype(float))
    return CurvatureResult(label, curvature, radius, centre, acc, spheres)
