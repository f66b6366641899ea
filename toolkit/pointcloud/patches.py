"""Robust local surface patches: a noisy cloud reduced to patch centres (issue 18; source 002).

The source "robustly fit[s] local surface patches to the raw 3-D points and
use[s] the center of those patches" as the data of the body-model fit: it
thins the cloud and removes most outliers.  Here:

1. isolated points go first: Open3D's statistical outlier removal (a point
   whose mean distance to its ``sor_neighbours`` nearest neighbours is more than
   ``sor_std`` standard deviations above the cloud's average), a maintained,
   KD-tree based filter;
2. the cloud is cut into a grid of ``patch_m`` cells; in each cell a plane is
   fitted by principal component analysis (the smallest eigenvector of the
   points' covariance), points farther from it than ``trim_sigma`` times the
   RMS residual are dropped and the plane refitted (a trimmed, robust fit);
3. a patch is kept when it still has ``min_points`` points and an RMS residual
   of at most ``max_residual_m`` and at most ``max_flatness`` times its in-plane spread (a thin, planar
   piece of surface) and
   ``min_neighbours`` kept patches among its 26 neighbouring cells (a surface
   continues; an isolated blob of false matches does not); its centre (the
   inliers' mean, on the plane), normal and support are the output.

Everything is vectorised over cells (sums of outer products per cell, one
batched ``numpy.linalg.eigh``), so a frame of 10^5 points takes milliseconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError

__all__ = ["PatchConfig", "SurfacePatches", "surface_patches"]


@dataclass(frozen=True)
class PatchConfig:
    """Options of :func:`surface_patches`.

    Parameters
    ----------
    patch_m : float
        Side of the grid cells a patch is fitted in, metres.
    min_points : int
        Fewest inliers a patch needs.
    max_residual_m : float
        Largest RMS distance of a patch's inliers to its plane, metres.
    trim_sigma : float
        Points farther from the first plane than this many RMS residuals are dropped before the refit.
    sor_neighbours : int
        Neighbours of Open3D's statistical outlier removal (0: no removal).
    sor_std : float
        Standard-deviation ratio of the statistical outlier removal.
    max_flatness : float
        Largest ratio of the RMS residual across the first (untrimmed) plane to the points' RMS
        spread along its narrower in-plane axis (a surface is flat at the cell's scale; a clump of scattered
        points is round: about 0.6-1).
    min_neighbours : int
        Fewest other patches among a patch's 26 neighbouring cells (an isolated planar
        blob, e.g. a small cluster of false matches, is not a piece of the body's surface).
    min_coverage : float
        Fewest of the cloud's points (a fraction, after the outlier removal) the patches
        must hold; below it the cell side and ``max_residual_m`` double and the cloud is
        reduced again, at most ``max_doublings`` times (0: fixed scale).  The scale
        follows the cloud where the sensor's noise or the points' spacing outgrow the
        cell: a Kinect-like camera's noise grows with the square of the distance, and a
        runner 4-5 m away (synthetic, 320 x 240) left 3-6 % of the points in 18-40
        patches, too few to track (every frame ``empty``); at 3 m 38-40 % of the points
        are in patches and nothing changes.
    max_doublings : int
        See ``min_coverage``.
    """

    patch_m: float = 0.025
    min_points: int = 4
    max_residual_m: float = 0.012
    trim_sigma: float = 2.0
    sor_neighbours: int = 12
    sor_std: float = 2.0
    min_neighbours: int = 1
    max_flatness: float = 0.5
    min_coverage: float = 0.1
    max_doublings: int = 2

    def __post_init__(self):
        if not 0.005 <= self.patch_m <= 1.0:
            raise InputError("PatchConfig.patch_m", "a cell side from 0.005 to 1 m", repr(self.patch_m))
        if not (isinstance(self.min_points, int) and self.min_points >= 3):
            raise InputError("PatchConfig.min_points", "an integer >= 3 (a plane needs 3 points)",
                             repr(self.min_points))
        if not self.max_residual_m > 0 or not self.trim_sigma > 0:
            raise InputError("PatchConfig.max_residual_m/trim_sigma", "values > 0",
                             f"{self.max_residual_m!r}, {self.trim_sigma!r}")
        if not (0.0 <= self.min_coverage < 1.0 and isinstance(self.max_doublings, int) and self.max_doublings >= 0):
            raise InputError("PatchConfig.min_coverage/max_doublings", "a fraction in [0, 1) and an integer >= 0",
                             f"{self.min_coverage!r}, {self.max_doublings!r}")
        if self.sor_neighbours < 0 or not self.sor_std > 0:
            raise InputError("PatchConfig.sor_neighbours/sor_std", "neighbours >= 0 and a ratio > 0",
                             f"{self.sor_neighbours!r}, {self.sor_std!r}")


@dataclass(frozen=True)
class SurfacePatches:
    """Patches of one cloud.

    Attributes
    ----------
    centres : ndarray of shape (P, 3)
        Patch centres, metres (the input's frame).
    normals : ndarray of shape (P, 3)
        Unit plane normals (sign arbitrary).
    support : ndarray of shape (P,) of int
        Inliers per patch.
    residuals : ndarray of shape (P,)
        RMS distance of the inliers to the plane, metres.
    n_input : int
        Points given.
    n_isolated : int
        Points the statistical outlier removal dropped.
    n_rejected : int
        Points in cells that gave no patch, or trimmed from a patch.
    """

    centres: np.ndarray
    normals: np.ndarray
    support: np.ndarray
    residuals: np.ndarray
    n_input: int
    n_isolated: int
    n_rejected: int

    def __len__(self) -> int:
        return len(self.centres)


def _statistical_outliers(points: np.ndarray, k: int, std: float) -> np.ndarray:
    """Indices of the points Open3D's statistical outlier removal keeps."""
    if k <= 0 or len(points) <= k:
        return np.arange(len(points))
    import open3d as o3d

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    _, idx = pc.remove_statistical_outlier(nb_neighbors=int(k), std_ratio=float(std))
    return np.asarray(idx, dtype=np.int64)


def _planes(points: np.ndarray, cell: np.ndarray, n_cells: int, weight: np.ndarray):
    """Per-cell weighted mean, plane normal, RMS residual, narrower in-plane RMS spread and count."""
    cnt = np.bincount(cell, weight, n_cells)
    s = np.zeros((n_cells, 3))
    np.add.at(s, cell, points * weight[:, None])
    mean = s / np.maximum(cnt, 1)[:, None]
    d = (points - mean[cell]) * weight[:, None]
    cov = np.zeros((n_cells, 3, 3))
    np.add.at(cov, cell, d[:, :, None] * d[:, None, :])
    cov /= np.maximum(cnt, 1)[:, None, None]
    evals, evecs = np.linalg.eigh(cov)
    sd = np.sqrt(np.maximum(evals, 0.0))
    return mean, evecs[:, :, 0], sd[:, 0], sd[:, 1], cnt


def _neighbour_count(cell_keys: np.ndarray, good: np.ndarray) -> np.ndarray:
    """Per cell, how many of its 26 neighbouring cells are ``good`` (cells as integer grid keys (C, 3))."""
    lo = cell_keys.min(axis=0) - 1
    span = cell_keys.max(axis=0) - lo + 2

    def code(k):
        k = k - lo
        return (k[:, 0] * span[1] + k[:, 1]) * span[2] + k[:, 2]

    good_codes = np.sort(code(cell_keys[good]))
    count = np.zeros(len(cell_keys), int)
    for off in np.array(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij")).reshape(3, -1).T:
        if not off.any():
            continue
        c = code(cell_keys + off)
        i = np.searchsorted(good_codes, c).clip(0, max(len(good_codes) - 1, 0))
        count += good_codes[i] == c if len(good_codes) else 0
    return count


def surface_patches(points: np.ndarray, config: PatchConfig | None = None) -> SurfacePatches:
    """Reduce a cloud to robust local planar patches (see the module docstring).

    Parameters
    ----------
    points : ndarray of shape (N, 3)
        A cloud, metres (any frame); non-finite rows are ignored; N may be 0.
    config : PatchConfig, optional

    Returns
    -------
    SurfacePatches
        Possibly empty (a tiny or scattered cloud gives no patch).

    Raises
    ------
    InputError
        ``points`` not of shape (N, 3).
    """
    cfg = config or PatchConfig()
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError("surface_patches: points", "an array of shape (N, 3)", f"shape {pts.shape}")
    n_in = len(pts)
    pts = pts[np.isfinite(pts).all(axis=1)]
    kept = pts[_statistical_outliers(pts, cfg.sor_neighbours, cfg.sor_std)]
    n_iso = len(pts) - len(kept)
    empty = SurfacePatches(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, int), np.zeros(0), n_in, n_iso, len(kept))
    if len(kept) < cfg.min_points:
        return empty
    out = _patches_at(kept, cfg, cfg.patch_m, cfg.max_residual_m, n_in, n_iso)
    for k in range(1, cfg.max_doublings + 1):  # the scale follows a noisy or sparse cloud
        if out.support.sum() >= cfg.min_coverage * len(kept):
            break
        out = _patches_at(kept, cfg, cfg.patch_m * 2 ** k, cfg.max_residual_m * 2 ** k, n_in, n_iso)
    return out


def _patches_at(kept: np.ndarray, cfg: PatchConfig, cell_m: float, max_residual_m: float, n_in: int,
                n_iso: int) -> SurfacePatches:
    """The patches of the outlier-free points ``kept`` (N, 3) on a grid of ``cell_m`` metres."""
    keys = np.floor(kept / cell_m).astype(np.int64)
    _, cell = np.unique(keys, axis=0, return_inverse=True)
    cell = cell.reshape(-1)
    n_cells = int(cell.max()) + 1
    w = np.ones(len(kept))
    mean, normal, rms, spread, cnt = _planes(kept, cell, n_cells, w)
    flat = rms <= cfg.max_flatness * spread  # judged before trimming (trimming flattens anything)
    dist = np.abs(((kept - mean[cell]) * normal[cell]).sum(axis=1))
    w = (dist <= cfg.trim_sigma * np.maximum(rms[cell], 1e-4)).astype(float)  # the trimmed refit
    mean, normal, rms, _, cnt = _planes(kept, cell, n_cells, w)
    good = flat & (cnt >= cfg.min_points) & (rms <= max_residual_m)
    if cfg.min_neighbours > 0 and good.any():
        cell_keys = np.zeros((n_cells, 3), np.int64)
        cell_keys[cell] = keys
        good &= _neighbour_count(cell_keys, good) >= cfg.min_neighbours
    n_rej = len(kept) - int(cnt[good].sum())
    return SurfacePatches(mean[good], normal[good], cnt[good].astype(int), rms[good], n_in, n_iso, n_rej)
