"""ORUS, the orthographic user grid (source 001, step 220).

The user's points are projected orthographically (along the view frame's z)
into a grid of fixed bin size, :data:`ORUS_BIN_SIZE_M` = 5 cm by default, with a
fixed number of bins, centred on the user's centroid.  Each bin keeps the
number of points, their mean X, Y, Z, their minimum depth and a normal.  Near
the camera many pixels fall into one bin, far away few; either way every later
stage works on the same fixed-size grid, so its cost does not depend on the
depth resolution (the source's main claim), and the bin size trades quality
for speed.

Empty bins inside the silhouette (sensor holes, shadows) are filled from their
neighbours: a bin with at least :attr:`OrusConfig.fill_min_neighbours` occupied
8-neighbours gets their mean position and normal; this is repeated
:attr:`OrusConfig.fill_iterations` times.

Normals come from the grid's own depth with the 3 x 3 kernel
(``normal_source="grid"``, robust to sensor noise because every bin averages
many pixels) or from the mean of the per-pixel normal map
(``normal_source="pixels"``).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.pointcloud.normals import grid_normals
from toolkit.errors import InputError

__all__ = ["ORUS_BIN_SIZE_M", "OrusConfig", "OrusGrid", "build_orus"]

#: Bin size of the orthographic user grid (source 001: "e.g. 5 cm").
ORUS_BIN_SIZE_M = 0.05


@dataclass(frozen=True)
class OrusConfig:
    """Settings of the orthographic user grid.

    Attributes
    ----------
    bin_size_m : float
        Side of a bin, metres.
    extent_m : tuple of float
        Width and height covered by the grid, metres (fixed, so the grid has a
        fixed number of bins: 52 x 52 at 5 cm).
    fill_iterations : int
        Rounds of hole filling.
    fill_min_neighbours : int
        Occupied 8-neighbours an empty bin needs to be filled.
    normal_source : {"grid", "pixels"}
    min_points : int
        Bins with fewer points count as empty.
    """

    bin_size_m: float = ORUS_BIN_SIZE_M
    extent_m: tuple[float, float] = (2.6, 2.6)
    fill_iterations: int = 2
    fill_min_neighbours: int = 4
    normal_source: str = "grid"
    min_points: int = 1

    def __post_init__(self):
        if not (0.005 <= self.bin_size_m <= 0.5):
            raise InputError("OrusConfig.bin_size_m", "a bin size between 0.005 and 0.5 m", f"{self.bin_size_m!r}")
        if self.normal_source not in ("grid", "pixels"):
            raise InputError("OrusConfig.normal_source", "'grid' or 'pixels'", repr(self.normal_source))

    @property
    def shape(self) -> tuple[int, int]:
        """Grid shape (rows, columns)."""
        return (int(np.ceil(self.extent_m[1] / self.bin_size_m)), int(np.ceil(self.extent_m[0] / self.bin_size_m)))


@dataclass(frozen=True)
class OrusGrid:
    """The orthographic user grid of one frame (view frame, metres).

    Bin ``(i, j)`` covers ``x in [x0 + j s, x0 + (j + 1) s)`` and
    ``y in [y0 + i s, y0 + (i + 1) s)`` with ``(x0, y0) = origin`` and ``s = bin_size``.

    Attributes
    ----------
    bin_size : float
    origin : ndarray of shape (2,)
        View-frame (x, y) of the corner of bin (0, 0).
    count : ndarray of shape (ny, nx), int
        Points per bin (0 for empty and filled bins).
    mean : ndarray of shape (ny, nx, 3)
        Mean X, Y, Z per bin (NaN where neither occupied nor filled).
    zmin : ndarray of shape (ny, nx)
        Minimum depth per bin (NaN likewise).
    normal : ndarray of shape (ny, nx, 3)
        Unit outward normal per bin (NaN where unknown).
    occupied : ndarray of shape (ny, nx), bool
        Bins holding points.
    filled : ndarray of shape (ny, nx), bool
        Occupied bins plus the bins filled from neighbours.
    n_points : int
        Points projected into the grid.
    n_outside : int
        User points that fell outside the grid.
    """

    bin_size: float
    origin: np.ndarray
    count: np.ndarray
    mean: np.ndarray
    zmin: np.ndarray
    normal: np.ndarray
    occupied: np.ndarray
    filled: np.ndarray
    n_points: int
    n_outside: int

    @property
    def shape(self) -> tuple[int, int]:
        return self.count.shape

    def bin_centres(self) -> np.ndarray:
        """View-frame (x, y) of every bin centre, (ny, nx, 2)."""
        ny, nx = self.shape
        xs = self.origin[0] + (np.arange(nx) + 0.5) * self.bin_size
        ys = self.origin[1] + (np.arange(ny) + 0.5) * self.bin_size
        X, Y = np.meshgrid(xs, ys)
        return np.stack([X, Y], -1)

    def to_bin(self, xy: np.ndarray) -> np.ndarray:
        """Continuous bin coordinates ``(col, row)`` (bin centres at integers) of points (..., 2+)."""
        p = np.asarray(xy, float)[..., :2]
        return (p - self.origin) / self.bin_size - 0.5

    def points(self, which: str = "filled") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bin positions, normals and (row, col) indices of ``"filled"`` or ``"occupied"`` bins.

        Returns
        -------
        positions : ndarray of shape (K, 3)
        normals : ndarray of shape (K, 3)
        index : ndarray of shape (K, 2), int
        """
        sel = self.filled if which == "filled" else self.occupied
        r, c = np.nonzero(sel)
        return self.mean[r, c], self.normal[r, c], np.stack([r, c], -1)


def _fill(mean, normal, sel, iterations, min_nb):
    """Fill empty bins with >= min_nb filled 8-neighbours by their mean (positions and normals)."""
    k = np.ones((3, 3), np.float32)
    k[1, 1] = 0
    mean = mean.copy()
    normal = normal.copy()
    filled = sel.copy()
    for _ in range(iterations):
        f = filled.astype(np.float32)
        nb = cv2.filter2D(f, -1, k, borderType=cv2.BORDER_CONSTANT)
        new = (~filled) & (nb >= min_nb)
        if not new.any():
            break
        m0 = np.where(filled[..., None], mean, 0.0).astype(np.float32)
        n0 = np.where(filled[..., None] & np.isfinite(normal), normal, 0.0).astype(np.float32)
        s = cv2.filter2D(m0, -1, k, borderType=cv2.BORDER_CONSTANT)          # 3 channels at once
        sn = cv2.filter2D(n0, -1, k, borderType=cv2.BORDER_CONSTANT)
        mean[new] = s[new] / nb[new][:, None]
        nn = sn[new]
        nrm = np.linalg.norm(nn, axis=-1, keepdims=True)
        normal[new] = np.where(nrm > 1e-6, nn / np.maximum(nrm, 1e-12), np.nan)
        filled |= new
    return mean, normal, filled


def build_orus(points: np.ndarray, centre: np.ndarray, config: OrusConfig = OrusConfig(),
               normals: np.ndarray | None = None) -> OrusGrid:
    """Project the user's points into the orthographic user grid.

    Parameters
    ----------
    points : ndarray of shape (N, 3)
        User points, view frame, metres.
    centre : array_like of shape (2,) or (3,)
        View-frame (x, y) the grid is centred on (the user's centroid); it is
        snapped to whole bins so that the binning does not shift with it.
    config : OrusConfig
    normals : ndarray of shape (N, 3), optional
        Per-point normals (view frame), required for ``normal_source="pixels"``.

    Returns
    -------
    OrusGrid
    """
    P = np.asarray(points, float)
    if P.ndim != 2 or P.shape[1] != 3:
        raise InputError("points", "an array of shape (N, 3)", f"shape {P.shape}")
    c = np.asarray(centre, float).ravel()[:2]
    if not np.all(np.isfinite(c)):
        raise InputError("centre", "finite (x, y)", f"{c.tolist()}")
    s = float(config.bin_size_m)
    ny, nx = config.shape
    origin = np.round(c / s) * s - np.array([nx, ny]) * s / 2.0
    j = np.floor((P[:, 0] - origin[0]) / s).astype(np.int64)
    i = np.floor((P[:, 1] - origin[1]) / s).astype(np.int64)
    inside = (i >= 0) & (i < ny) & (j >= 0) & (j < nx) & np.all(np.isfinite(P), axis=1)
    lin = i[inside] * nx + j[inside]
    Pin = P[inside]
    n_bins = ny * nx
    count = np.bincount(lin, minlength=n_bins)
    sums = np.stack([np.bincount(lin, weights=Pin[:, k], minlength=n_bins) for k in range(3)], -1)
    occupied = count >= max(config.min_points, 1)
    mean = np.full((n_bins, 3), np.nan)
    mean[occupied] = sums[occupied] / count[occupied, None]
    zmin = np.full(n_bins, np.inf)
    if len(lin):
        np.minimum.at(zmin, lin, Pin[:, 2])
    zmin[~occupied] = np.nan
    mean = mean.reshape(ny, nx, 3)
    zmin = zmin.reshape(ny, nx)
    occupied = occupied.reshape(ny, nx)
    if config.normal_source == "pixels":
        if normals is None:
            raise InputError("normals", "per-point normals for normal_source='pixels'", "None")
        N = np.asarray(normals, float)[inside]
        okn = np.all(np.isfinite(N), axis=1)
        nsum = np.stack([np.bincount(lin[okn], weights=N[okn, k], minlength=n_bins) for k in range(3)], -1)
        nn = np.linalg.norm(nsum, axis=1, keepdims=True)
        normal = np.where(nn > 1e-9, nsum / np.maximum(nn, 1e-12), np.nan).reshape(ny, nx, 3)
        normal[~occupied] = np.nan
    else:
        normal = None
    mean_f, normal_f, filled = _fill(mean, normal if normal is not None else np.full_like(mean, np.nan),
                                     occupied, config.fill_iterations, config.fill_min_neighbours)
    if config.normal_source == "grid":
        normal_f = grid_normals(np.where(filled, mean_f[..., 2], np.nan), s)
    zmin_f = np.where(occupied, zmin, np.where(filled, mean_f[..., 2], np.nan))
    count = count.reshape(ny, nx)
    return OrusGrid(s, origin, count, mean_f, zmin_f, normal_f, occupied, filled, int(inside.sum()),
                    int((~inside).sum()))
