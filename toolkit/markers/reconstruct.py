"""3D markers from unlabelled 2D blobs: trinocular matching (source 004, §3.1.1).

A marker is reconstructed when its blobs agree in at least three views: for
every pair of cameras, the blobs of the second camera within ``match_px`` of
the epipolar line of a blob of the first are candidate pairs; each pair is
triangulated and projected into the other cameras, and the pair is confirmed
when a blob lies within ``match_px`` of the projection in at least one third
view.  The point is then re-triangulated (linear DLT in normalised image
coordinates) from every view that agrees.  Hypotheses are accepted greedily,
most views and smallest reprojection error first, each blob used at most once,
so one blob never feeds two markers.

Two-view reconstructions (the source's binocular stereo, flagged as less
certain) are only added on request (:func:`reconstruct_frame` with
``two_view=True``, used when a frame shows fewer markers than the marker set
has): a pair of unused blobs that are each other's only epipolar partner.

Ghost blobs (reflections, spurious detections) are independent in each view,
so they almost never find a confirming third view; they therefore do not
create trinocular markers, and the tracker never turns a reconstruction that
it cannot follow into a marker.

All functions are vectorised over blobs and hypotheses (numpy); a frame of
40 markers seen by 8 cameras takes a few milliseconds.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations, count

import heapq

import numpy as np
from scipy.spatial import cKDTree

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.markers.trajectories import TRINOCULAR, TWO_VIEW


@dataclass(frozen=True)
class ReconstructionConfig:
    """Tolerances of the trinocular matching.

    Attributes
    ----------
    match_px : float
        Largest distance, pixels, of a blob from an epipolar line or from a
        projected point for the views to agree (about 3-4 sigma of the blob
        noise at 1 px).
    min_depth_m : float
        Triangulated points closer to a camera than this are rejected.
    """

    match_px: float = 3.5
    min_depth_m: float = 0.2


@dataclass(frozen=True)
class FrameMarkers:
    """The unlabelled 3D markers of one frame.

    Attributes
    ----------
    points : ndarray of shape (K, 3)
        Metres, world frame.
    views : ndarray of shape (K, C) int
        Blob index used in each camera, -1 where the camera does not contribute.
    state : ndarray of shape (K,) int8
        :data:`~toolkit.markers.trajectories.TRINOCULAR` or ``TWO_VIEW``.
    rms_px : ndarray of shape (K,)
        Root-mean-square reprojection error over the contributing views, pixels.
    """

    points: np.ndarray
    views: np.ndarray
    state: np.ndarray
    rms_px: np.ndarray

    @staticmethod
    def empty(n_cams: int) -> "FrameMarkers":
        return FrameMarkers(np.zeros((0, 3)), np.zeros((0, n_cams), int), np.zeros(0, np.int8), np.zeros(0))

    def __len__(self) -> int:
        return self.points.shape[0]


@dataclass(frozen=True)
class RigGeometry:
    """What the matching needs from a rig, computed once.

    Attributes
    ----------
    rig : Rig
    P : ndarray of shape (C, 3, 4)
        ``[R | t]`` of each camera (normalised image coordinates).
    focal : ndarray of shape (C,)
        Mean focal length of each camera, pixels (normalised units to pixels).
    essential : dict of (int, int) -> ndarray (3, 3)
        ``E_ba`` with ``x_b^T E_ba x_a = 0`` for every pair a < b.
    KP : ndarray of shape (C, 3, 4)
        ``K [R | t]`` (pixels, without distortion).
    pinhole : bool
        No camera has lens distortion (projection in one batched product).
    """

    rig: Rig
    P: np.ndarray
    focal: np.ndarray
    essential: dict
    KP: np.ndarray
    pinhole: bool

    @staticmethod
    def of(rig: Rig) -> "RigGeometry":
        if len(rig) < 3:
            raise InputError("rig", "at least 3 cameras (trinocular matching)", f"{len(rig)} cameras")
        P = np.stack([c.cam_from_world[:3, :] for c in rig])
        focal = np.array([0.5 * (c.K[0, 0] + c.K[1, 1]) for c in rig])
        E = {}
        for a, b in combinations(range(len(rig)), 2):
            Ra, ta, Rb, tb = P[a, :, :3], P[a, :, 3], P[b, :, :3], P[b, :, 3]
            R = Rb @ Ra.T
            t = tb - R @ ta
            tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
            E[(a, b)] = tx @ R
        KP = np.stack([c.K @ p for c, p in zip(rig, P)])
        return RigGeometry(rig, P, focal, E, KP, not any(c.has_distortion for c in rig))


def normalise_blobs(rig: Rig, blobs: list[np.ndarray]) -> list[np.ndarray]:
    """Undistorted normalised image coordinates of each camera's blobs.

    Parameters
    ----------
    rig : Rig
    blobs : list of ndarray of shape (n_c, 2)
        Pixels, one array per camera.

    Returns
    -------
    list of ndarray of shape (n_c, 2)
    """
    if len(blobs) != len(rig):
        raise InputError("blobs", f"one array per camera ({len(rig)})", f"{len(blobs)} arrays")
    return [cam.undistort_points(np.asarray(b, float).reshape(-1, 2)) for cam, b in zip(rig, blobs)]


def triangulate_dlt(P: np.ndarray, xy: np.ndarray, used: np.ndarray) -> np.ndarray:
    """Linear (DLT) triangulation of many finite points at once (inhomogeneous form, X = (x, y, z, 1)).

    Parameters
    ----------
    P : ndarray of shape (C, 3, 4)
        ``[R | t]`` per camera.
    xy : ndarray of shape (K, C, 2)
        Normalised image coordinates (anything where ``used`` is False).
    used : ndarray of shape (K, C) bool
        The views of each point; at least two.

    Returns
    -------
    ndarray of shape (K, 3)
        NaN where a point has fewer than two views or is at infinity.
    """
    K, C = used.shape
    if K == 0:
        return np.zeros((0, 3))
    x = np.where(used[..., None], xy, 0.0)
    w = used.astype(float)[..., None]
    rows_x = (x[..., 0:1] * P[None, :, 2, :] - P[None, :, 0, :]) * w  # (K, C, 4)
    rows_y = (x[..., 1:2] * P[None, :, 2, :] - P[None, :, 1, :]) * w
    A = np.concatenate([rows_x, rows_y], axis=1)  # (K, 2C, 4)
    # finite points: A[:, :, :3] X = -A[:, :, 3] in the least-squares sense (normal equations, 3x3)
    A3 = A[..., :3]
    N = np.swapaxes(A3, 1, 2) @ A3
    rhs = -(np.swapaxes(A3, 1, 2) @ A[..., 3:4])
    out = np.full((K, 3), np.nan)
    good = (used.sum(axis=1) >= 2) & (np.abs(np.linalg.det(N)) > 1e-12)
    if good.any():
        out[good] = np.linalg.solve(N[good], rhs[good])[..., 0]
    return out


def project_all(geom: RigGeometry, points: np.ndarray) -> np.ndarray:
    """Pixels (C, K, 2) of points (K, 3) in every camera (NaN behind a camera)."""
    if points.shape[0] == 0:
        return np.zeros((len(geom.rig), 0, 2))
    if geom.pinhole:  # no lens distortion: one batched product for all cameras
        q = np.einsum("cij,kj->cki", geom.KP[:, :, :3], points) + geom.KP[:, None, :, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = q[..., :2] / q[..., 2:3]
    else:
        uv = np.stack([cam.project(points) for cam in geom.rig])
    depth = points @ geom.P[:, 2, :3].T + geom.P[:, 2, 3]  # (K, C)
    depth = depth.T
    uv[depth < 0.0] = np.nan
    return uv


def _padded(arrays: list[np.ndarray]) -> np.ndarray:
    """(C, n_max, 2) with NaN rows after each camera's own blobs."""
    n = max((a.shape[0] for a in arrays), default=0)
    out = np.full((len(arrays), max(n, 1), 2), np.nan)
    for c, a in enumerate(arrays):
        out[c, :a.shape[0]] = a
    return out


def _pair_hypotheses(geom: RigGeometry, xy: np.ndarray, tol_px: float, free: np.ndarray | None = None):
    """Candidate blob pairs (a, ia, b, ib) along epipolar lines, all camera pairs at once.

    ``xy`` is (C, n, 2) padded with NaN; ``free`` (C, n) bool limits the pairs to free blobs.
    """
    pairs = np.array(list(geom.essential), int).reshape(-1, 2)
    if pairs.shape[0] == 0:
        return np.zeros((0, 4), int)
    E = np.stack([geom.essential[tuple(p)] for p in pairs])  # (P, 3, 3)
    h = np.concatenate([xy, np.ones(xy.shape[:2] + (1,))], axis=2)  # (C, n, 3)
    ha, hb = h[pairs[:, 0]], h[pairs[:, 1]]  # (P, n, 3)
    lb = np.einsum("pij,paj->pai", E, ha)  # lines in b of the blobs of a, (P, n, 3)
    la = np.einsum("pji,pbj->pbi", E, hb)  # lines in a of the blobs of b
    alg = np.einsum("pbi,pai->pba", hb, lb)  # (P, nb, na)
    with np.errstate(invalid="ignore", divide="ignore"):
        db = np.abs(alg) / np.linalg.norm(lb[..., :2], axis=2)[:, None, :] * geom.focal[pairs[:, 1], None, None]
        da = np.abs(alg) / np.linalg.norm(la[..., :2], axis=2)[:, :, None] * geom.focal[pairs[:, 0], None, None]
        ok = np.maximum(da, db) < tol_px
    if free is not None:
        ok &= free[pairs[:, 1]][:, :, None] & free[pairs[:, 0]][:, None, :]
    p, ib, ia = np.nonzero(ok)
    return np.stack([pairs[p, 0], ia, pairs[p, 1], ib], axis=1)


def _views_from_pairs(pairs: np.ndarray, n_cams: int) -> np.ndarray:
    views = -np.ones((pairs.shape[0], n_cams), int)
    r = np.arange(pairs.shape[0])
    views[r, pairs[:, 0]] = pairs[:, 1]
    views[r, pairs[:, 2]] = pairs[:, 3]
    return views


def _gather(padded: np.ndarray, views: np.ndarray) -> np.ndarray:
    """(K, C, 2) coordinates of the blobs ``views`` (K, C) picks from ``padded`` (C, n, 2); 0 where unused."""
    C = views.shape[1]
    out = padded[np.arange(C)[None, :], np.maximum(views, 0)]
    return np.where((views >= 0)[..., None], out, 0.0)


def _residuals(geom: RigGeometry, blobs: np.ndarray, X: np.ndarray, views: np.ndarray) -> np.ndarray:
    """Reprojection error (K, C) pixels in the used views, NaN elsewhere (``blobs`` padded (C, n, 2))."""
    uv = project_all(geom, X).transpose(1, 0, 2)  # (K, C, 2)
    err = np.linalg.norm(uv - _gather(blobs, views), axis=2)
    return np.where(views >= 0, err, np.nan)


def _confirm(geom: RigGeometry, blobs: np.ndarray, X: np.ndarray, views: np.ndarray, tol_px: float) -> np.ndarray:
    """Add to ``views`` the nearest blob within ``tol_px`` of each point's projection in the other cameras."""
    if X.shape[0] == 0:
        return views
    uv = project_all(geom, X)  # (C, K, 2)
    views = views.copy()
    for c in range(views.shape[1]):
        b = blobs[c][np.isfinite(blobs[c]).all(axis=1)]
        m = (views[:, c] < 0) & np.isfinite(uv[c]).all(axis=1)
        if b.shape[0] == 0 or not m.any():
            continue
        d, j = cKDTree(b).query(uv[c, m], distance_upper_bound=tol_px)
        hit = np.isfinite(d)
        views[np.flatnonzero(m)[hit], c] = j[hit]
    return views


def _in_front(geom: RigGeometry, X: np.ndarray, views: np.ndarray, min_depth: float) -> np.ndarray:
    depth = X @ geom.P[:, 2, :3].T + geom.P[:, 2, 3]  # (K, C)
    return np.all((depth > min_depth) | (views < 0), axis=1) & np.isfinite(X).all(axis=1)


def _greedy(geom: RigGeometry, B: np.ndarray, XY: np.ndarray, views: np.ndarray, X: np.ndarray,
            rms: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Accept hypotheses, most views and smallest error first, with no blob used twice.

    A hypothesis some of whose blobs were taken keeps its other views: with
    three or more left it is re-triangulated and queued again (a marker whose
    blob in one view went to a neighbour is not lost, nor split into chimeras).

    Returns
    -------
    views : ndarray of shape (K, C) int
    points : ndarray of shape (K, 3)
    rms : ndarray of shape (K,)
    """
    C = views.shape[1]
    used = [set() for _ in range(C)]
    heap = [(-int((v >= 0).sum()), float(r), k) for k, (v, r) in enumerate(zip(views, rms))]
    heapq.heapify(heap)
    items = {k: (views[k], X[k], rms[k]) for k in range(len(views))}
    fresh = count(len(views))
    out_v, out_x, out_r = [], [], []
    accepted = False
    same_m = 0.01  # two hypotheses this close are one marker (markers are >= 5 cm apart)
    while heap:
        _, _, k = heapq.heappop(heap)
        v, x, r = items.pop(k)
        vv = v.tolist()
        clash = [c for c in range(C) if vv[c] >= 0 and vv[c] in used[c]]
        if clash:
            if accepted and np.min(np.sum((np.array(out_x) - x) ** 2, axis=1)) < same_m ** 2:
                continue  # the same marker seen through another subset of views
            v = v.copy()
            v[clash] = -1
            if (v >= 0).sum() < 3:
                continue
            x = triangulate_dlt(geom.P, _gather(XY, v[None]), (v >= 0)[None])[0]
            err = _residuals(geom, B, x[None], v[None])[0]
            if not np.all(np.isfinite(x)) or np.nanmax(err) >= tol:
                continue
            r = float(np.sqrt(np.nanmean(err ** 2)))
            k2 = next(fresh)
            items[k2] = (v, x, r)
            heapq.heappush(heap, (-int((v >= 0).sum()), r, k2))
            continue
        for c in range(C):
            if vv[c] >= 0:
                used[c].add(vv[c])
        out_v.append(v)
        out_x.append(x)
        out_r.append(r)
        accepted = True
    if not out_v:
        return np.zeros((0, C), int), np.zeros((0, 3)), np.zeros(0)
    return np.array(out_v), np.array(out_x), np.array(out_r)


def reconstruct_frame(geom: RigGeometry, blobs: list[np.ndarray], config: ReconstructionConfig = ReconstructionConfig(),
                      *, two_view: bool = False, xy: list[np.ndarray] | None = None) -> FrameMarkers:
    """Trinocular reconstruction of one frame's blobs.

    Parameters
    ----------
    geom : RigGeometry
        From :meth:`RigGeometry.of` (``C`` cameras).
    blobs : list of ndarray of shape (n_c, 2)
        The blob centres of each camera, pixels.
    config : ReconstructionConfig
    two_view : bool
        Also add unambiguous two-view reconstructions from the blobs left over
        (state ``TWO_VIEW``).
    xy : list of ndarray of shape (n_c, 2), optional
        The blobs' normalised coordinates if already computed (:func:`normalise_blobs`).

    Returns
    -------
    FrameMarkers
        Every blob used at most once.
    """
    C = len(geom.rig)
    blobs = [np.asarray(b, float).reshape(-1, 2) for b in blobs]
    if len(blobs) != C:
        raise InputError("blobs", f"one array per camera ({C})", f"{len(blobs)} arrays")
    xy = normalise_blobs(geom.rig, blobs) if xy is None else xy
    B, XY = _padded(blobs), _padded(xy)
    tol = config.match_px
    pairs = _pair_hypotheses(geom, XY, tol)
    if pairs.shape[0] == 0:
        return _add_two_view(geom, B, XY, FrameMarkers.empty(C), config) if two_view else FrameMarkers.empty(C)
    views = _views_from_pairs(pairs, C)
    X = triangulate_dlt(geom.P, _gather(XY, views), views >= 0)
    ok = _in_front(geom, X, views, config.min_depth_m)
    views, X = views[ok], X[ok]
    views = _confirm(geom, B, X, views, tol)
    tri = (views >= 0).sum(axis=1) >= 3
    views = np.unique(views[tri], axis=0)
    # re-triangulate from all agreeing views; drop views that no longer agree
    X = triangulate_dlt(geom.P, _gather(XY, views), views >= 0)
    err = _residuals(geom, B, X, views)
    views = np.where(err < tol, views, -1)
    keep = (views >= 0).sum(axis=1) >= 3
    views = np.unique(views[keep], axis=0)
    X = triangulate_dlt(geom.P, _gather(XY, views), views >= 0)
    err = _residuals(geom, B, X, views)
    with np.errstate(invalid="ignore"):
        rms = np.sqrt(np.nanmean(err ** 2, axis=1)) if len(views) else np.zeros(0)
        good = np.isfinite(X).all(axis=1) & (np.nanmax(np.where(views >= 0, err, 0), axis=1) < tol)
    views, X, rms = _greedy(geom, B, XY, views[good], X[good], rms[good], tol)
    out = FrameMarkers(X, views, np.full(len(X), TRINOCULAR, np.int8), rms)
    if two_view:
        out = _add_two_view(geom, B, XY, out, config)
    return out


def used_blob_masks(views: np.ndarray, n_blobs: list[int]) -> list[np.ndarray]:
    """Per camera, a bool mask of the blobs that ``views`` (K, C) uses."""
    used = [np.zeros(n, bool) for n in n_blobs]
    for c in range(views.shape[1] if views.ndim == 2 else 0):
        v = views[:, c]
        used[c][v[v >= 0]] = True
    return used


def _add_two_view(geom, B, XY, found: FrameMarkers, config) -> FrameMarkers:
    """Unambiguous two-view reconstructions from the blobs no trinocular marker uses."""
    C, n = B.shape[:2]
    free = np.isfinite(B).all(axis=2)
    for c in range(C):
        v = found.views[:, c]
        free[c, v[v >= 0]] = False
    pairs = _pair_hypotheses(geom, XY, config.match_px, free)
    if pairs.shape[0] == 0:
        return found
    # keep the pairs whose two blobs have no other partner among the free blobs
    keys = np.concatenate([pairs[:, 0] * n + pairs[:, 1], pairs[:, 2] * n + pairs[:, 3]])
    uk, ck = np.unique(keys, return_counts=True)
    once = np.isin(keys, uk[ck == 1]).reshape(2, -1).all(axis=0)
    pairs = pairs[once]
    if pairs.shape[0] == 0:
        return found
    views = _views_from_pairs(pairs, C)
    X = triangulate_dlt(geom.P, _gather(XY, views), views >= 0)
    ok = _in_front(geom, X, views, config.min_depth_m)
    if len(found) and ok.any():  # a plausible place: near the trinocular markers
        lo, hi = found.points.min(axis=0) - 0.5, found.points.max(axis=0) + 0.5
        ok &= np.all((X >= lo) & (X <= hi), axis=1)
    views, X = views[ok], X[ok]
    err = _residuals(geom, B, X, views)
    rms = np.sqrt(np.nanmean(err ** 2, axis=1)) if len(views) else np.zeros(0)
    return FrameMarkers(np.concatenate([found.points, X]), np.concatenate([found.views, views]),
                        np.concatenate([found.state, np.full(len(X), TWO_VIEW, np.int8)]),
                        np.concatenate([found.rms_px, rms]))
