"""The radial-distance profile from the user's centroid to the contour (source 001, figures 8A and 8B).

Rays leave the centroid every :attr:`RadialConfig.step_deg` degrees (the source
names 2, 5 or 10) in the plane of the orthographic grid; angles are measured
from "up" (0 degrees) towards the image's right.  Along each ray the grid is
sampled every half bin; the ray's length is the distance to the contour where
the ray leaves the user for the last time (the farthest filled bin, so that an
arm held out above the centroid still shows).  Peaks of the profile are the
extremities:

* the **head** is the peak nearest to 0 degrees (within ``head_window_deg``);
* the **feet** are two peaks around 180 degrees of similar length
  (``feet_similarity``) less than :data:`FEET_MAX_SEPARATION_DEG` = 30 degrees
  apart, or the single longest peak there;
* the remaining peaks, up to two, are **hands**.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import find_peaks

from toolkit.depth.orus import OrusGrid
from toolkit.errors import InputError

__all__ = ["FEET_MAX_SEPARATION_DEG", "RADIAL_STEPS_DEG", "RadialConfig", "RadialProfile", "radial_profile"]

#: Angular steps named by the source, degrees.
RADIAL_STEPS_DEG = (2.0, 5.0, 10.0)
#: Two foot peaks are less than this far apart, degrees (source 001).
FEET_MAX_SEPARATION_DEG = 30.0


@dataclass(frozen=True)
class RadialConfig:
    """Settings of the radial profile.

    Attributes
    ----------
    step_deg : float
        Angle between rays.
    max_radius_m : float
        Longest ray.
    min_prominence_m : float
        Peak prominence.
    head_window_deg : float
        The head peak lies within this of 0 degrees.
    feet_window_deg : float
        Foot peaks lie within this of 180 degrees.
    feet_similarity : float
        Largest relative length difference of two foot peaks.
    """

    step_deg: float = 5.0
    max_radius_m: float = 1.6
    min_prominence_m: float = 0.08
    head_window_deg: float = 50.0
    feet_window_deg: float = 50.0
    feet_similarity: float = 0.25

    def __post_init__(self):
        if not 0.5 <= self.step_deg <= 45:
            raise InputError("RadialConfig.step_deg", "an angle between 0.5 and 45 degrees", repr(self.step_deg))


@dataclass(frozen=True)
class RadialProfile:
    """Distances from the centroid to the contour.

    Attributes
    ----------
    angles_deg : ndarray of shape (n,)
        From up, towards the image's right.
    distances : ndarray of shape (n,)
        Metres (0 where the centroid is outside the silhouette in that direction).
    points : ndarray of shape (n, 3)
        Contour points, view frame (z of the grid there).
    peaks : ndarray of shape (p,), int
        Indices of the profile's peaks.
    head : int or None
        Index (into ``angles_deg``) of the head peak.
    feet : tuple of int
        Indices of the foot peaks (0 to 2).
    hands : tuple of int
        Indices of the hand peaks (0 to 2).
    """

    angles_deg: np.ndarray
    distances: np.ndarray
    points: np.ndarray
    peaks: np.ndarray
    head: int | None
    feet: tuple
    hands: tuple

    def direction(self, index: int) -> np.ndarray:
        """Unit view-frame direction (x, y, 0) of ray ``index``."""
        a = np.radians(self.angles_deg[index])
        return np.array([np.sin(a), -np.cos(a), 0.0])


def _angle_diff(a, b):
    return np.abs((np.asarray(a) - b + 180.0) % 360.0 - 180.0)


def radial_profile(grid: OrusGrid, centre: np.ndarray, config: RadialConfig = RadialConfig()) -> RadialProfile:
    """The radial-distance profile of the grid's silhouette around ``centre``.

    Parameters
    ----------
    grid : OrusGrid
    centre : array_like of shape (2,) or (3,)
        View-frame (x, y) of the user's centroid.
    config : RadialConfig

    Returns
    -------
    RadialProfile
    """
    c = np.asarray(centre, float).ravel()[:2]
    n = int(round(360.0 / config.step_deg))
    ang = np.arange(n) * (360.0 / n)
    a = np.radians(ang)
    dirs = np.stack([np.sin(a), -np.cos(a)], -1)
    step = grid.bin_size / 2.0
    radii = np.arange(0.0, config.max_radius_m + step, step)
    pts = c[None, None, :] + radii[None, :, None] * dirs[:, None, :]          # (n, m, 2)
    b = np.floor((pts - grid.origin) / grid.bin_size).astype(np.int64)
    ny, nx = grid.shape
    inside = (b[..., 0] >= 0) & (b[..., 0] < nx) & (b[..., 1] >= 0) & (b[..., 1] < ny)
    occ = np.zeros(inside.shape, bool)
    occ[inside] = grid.filled[b[inside][:, 1], b[inside][:, 0]]
    m = occ.shape[1]
    last = np.where(occ.any(1), m - 1 - np.argmax(occ[:, ::-1], axis=1), 0)
    dist = np.where(occ[np.arange(n), last], radii[last], 0.0)
    cpts = c + dist[:, None] * dirs
    bi = np.clip(np.floor((cpts - grid.origin) / grid.bin_size).astype(np.int64), 0, [nx - 1, ny - 1])
    z = grid.mean[bi[:, 1], bi[:, 0], 2]
    points = np.column_stack([cpts, z])
    # circular peak finding: tile three times, keep the middle copy
    tiled = np.concatenate([dist, dist, dist])
    pk, _ = find_peaks(tiled, prominence=config.min_prominence_m)
    pk = pk[(pk >= n) & (pk < 2 * n)] - n
    pk = np.unique(pk)
    head = None
    feet: tuple = ()
    hands: tuple = ()
    if len(pk):
        dh = _angle_diff(ang[pk], 0.0)
        near = pk[dh <= config.head_window_deg]
        if len(near):
            head = int(near[np.argmin(_angle_diff(ang[near], 0.0))])
        lower = [int(p) for p in pk if _angle_diff(ang[p], 180.0) <= config.feet_window_deg and p != head]
        best = None
        for i in range(len(lower)):
            for j in range(i + 1, len(lower)):
                p, q = lower[i], lower[j]
                sim = abs(dist[p] - dist[q]) / max(dist[p], dist[q], 1e-9)
                if _angle_diff(ang[p], ang[q]) < FEET_MAX_SEPARATION_DEG and sim <= config.feet_similarity:
                    score = dist[p] + dist[q]
                    if best is None or score > best[0]:
                        best = (score, p, q)
        if best is not None:
            feet = (best[1], best[2])
        elif lower:
            feet = (max(lower, key=lambda p: dist[p]),)
        rest = [int(p) for p in pk if p != head and p not in feet]
        rest.sort(key=lambda p: -dist[p])
        hands = tuple(rest[:2])
    return RadialProfile(ang, dist, points, pk, head, feet, hands)
