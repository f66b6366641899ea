"""Which detections of different cameras show the same person, with and without the cameras' poses.

Calibration from the people (:func:`toolkit.calibration.extrinsics.extrinsics_from_people`) needs
keypoint correspondences: the same joint of the same person seen by two cameras at one moment.  A
detector gives, per camera and frame, every person it found in no particular order, and a choice of
one person per camera (the most confident) picks different people in different cameras whenever
several are in view: on ``pose2sim_multiperson`` (two participants, bystanders) the four cameras'
most confident detections show the same person in 5 of 100 frames.  This module finds the
correspondences at the level of whole detections:

* :func:`match_camera_pair`: before any pose is known, RANSAC over *detection pairs* of two cameras:
  the keypoints of two detection pairs from two frames give an essential matrix (OpenCV's
  five-point RANSAC), which is scored by the detection pairs of every frame whose shared keypoints
  it explains (at least :data:`MATCH_SHARE` of them within the threshold), each detection in one
  pair at most; a new best hypothesis is re-estimated on the keypoints it explains (locally
  optimised RANSAC).
* :func:`group_pair_matches`: per frame, the detection pairs of all camera pairs joined into groups,
  strongest first, never two detections of one camera in a group.
* :func:`associate_detections`: with every pose known, per frame: every two detections of two
  cameras are triangulated from the two; pairs whose median reprojection error is within
  ``match_px`` are joined, lowest error first, while every detection of the grown group agrees
  with the group's triangulation (within :data:`JOIN_FACTOR` times ``match_px``; two people in one
  epipolar plane of two cameras can agree by chance, a third camera does not).  A detection no
  other camera agrees with (a bystander seen by one camera, a person the detector mixed with
  another) is in no group.

Arrays: ``xy`` of shape ``(n_cams, T, P, K, 2)`` normalised image coordinates (undistorted, ``x/z,
y/z``), NaN where missing; ``seen`` ``(n_cams, T, P, K)`` boolean; ``P`` detections per camera and
frame (padded with unseen ones).  Errors in pixels are normalised errors times the focal length.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.errors import InputError

__all__ = ["MIN_SHARED_KEYPOINTS", "MATCH_SHARE", "JOIN_FACTOR", "PairMatch", "detections_array",
           "triangulate_normalised", "match_camera_pair", "group_pair_matches", "associate_detections",
           "group_observations"]

#: Keypoints two detections must share (both confident) to be compared.
MIN_SHARED_KEYPOINTS = 8
#: Share of a detection pair's shared keypoints that must lie within the threshold for the two
#: detections to be the same person (a person mixed with another by the detector fails it).
MATCH_SHARE = 0.6
#: A detection stays in a group (of three cameras or more) while its median reprojection error against
#: the group's triangulation is within this many times the pair threshold.
JOIN_FACTOR = 2.0
#: RANSAC stops when a sample of two true detection pairs has been drawn with this probability.
RANSAC_CONFIDENCE = 0.999
#: Hypotheses drawn at least / at most per camera pair or camera.
MIN_HYPOTHESES = 20
MAX_HYPOTHESES = 300
#: Refits of a new best hypothesis on the keypoints it explains (locally optimised RANSAC).
LOCAL_REFITS = 5
#: Iterations of OpenCV's RANSAC inside one hypothesis' fit (its points are mostly of one person).
FIT_ITERATIONS = 200
#: Correspondences drawn for a refit (OpenCV's RANSAC inside is slow on thousands).
LOCAL_POINTS = 400


@dataclass(frozen=True)
class PairMatch:
    """Two cameras' relative pose and the detection pairs it explains.

    Attributes
    ----------
    a, b : int
        The cameras.
    R : ndarray of shape (3, 3)
    t : ndarray of shape (3,)
        ``cam_b_from_cam_a`` (unit baseline).
    frames, det_a, det_b : ndarray of shape (M,) of int
        The matched detection pairs: frame, detection in ``a``, detection in ``b``.
    pair_inliers : ndarray of shape (M,) of int
        Keypoints of each matched pair within the threshold.
    inliers : int
        Keypoints of those pairs within the threshold (the score).
    candidates : int
        Detection pairs that could be compared (sharing :data:`MIN_SHARED_KEYPOINTS`).
    """

    a: int
    b: int
    R: np.ndarray
    t: np.ndarray
    frames: np.ndarray
    det_a: np.ndarray
    det_b: np.ndarray
    pair_inliers: np.ndarray
    inliers: int
    candidates: int


def detections_array(cameras, frames, n_keypoints: int) -> np.ndarray:
    """Every detection of every camera, frame by frame, as one padded array.

    Parameters
    ----------
    cameras : sequence of CameraDetections
        Per camera its ``frames`` (frame numbers) and ``people`` (per frame an array (P, K, 3))
        (``toolkit.io.keypoint_formats.KeypointInput.cameras``).
    frames : sequence of int
        The frame numbers wanted, T of them (a camera without one gives no detection there).
    n_keypoints : int
        K.

    Returns
    -------
    ndarray of shape (n_cams, T, P, K, 3)
        ``(x, y, confidence)`` pixels; ``P`` the most detections of any camera and frame (at least
        1); NaN and confidence 0 where a slot holds no detection.

    Raises
    ------
    InputError
        A detection that is not (K, 3).
    """
    frames = [int(n) for n in frames]
    per_cam = []
    for cam in cameras:
        pos = {int(n): t for t, n in enumerate(cam.frames)}
        rows = []
        for n in frames:
            people = np.asarray(cam.people[pos[n]], float) if n in pos else np.zeros((0, n_keypoints, 3))
            people = people.reshape(-1, *people.shape[-2:]) if people.size else np.zeros((0, n_keypoints, 3))
            if people.shape[1:] != (n_keypoints, 3):
                raise InputError(f"detections of frame {n}", f"arrays of shape (P, {n_keypoints}, 3)",
                                 f"shape {people.shape}")
            rows.append(people)
        per_cam.append(rows)
    P = max([1] + [len(r) for rows in per_cam for r in rows])
    out = np.full((len(per_cam), len(frames), P, n_keypoints, 3), np.nan)
    out[..., 2] = 0.0
    for c, rows in enumerate(per_cam):
        for t, people in enumerate(rows):
            out[c, t, :len(people)] = people
    return out


def triangulate_normalised(cam_from_world: np.ndarray, xy: np.ndarray, min_views: int = 2) -> np.ndarray:
    """Linear (DLT) triangulation of normalised image points, batched.

    Parameters
    ----------
    cam_from_world : ndarray of shape (n_cams, 4, 4) or (n_cams, 3, 4)
    xy : ndarray of shape (n_cams, ..., 2)
        Normalised coordinates; NaN where a camera does not see the point.
    min_views : int

    Returns
    -------
    ndarray of shape (..., 3)
        NaN where fewer than ``min_views`` cameras see the point.
    """
    P = np.asarray(cam_from_world, float)[:, :3, :]
    xy = np.asarray(xy, float)
    C, shape = xy.shape[0], xy.shape[1:-1]
    x = np.moveaxis(xy.reshape(C, -1, 2), 0, 1)  # (N, C, 2)
    ok = np.isfinite(x).all(-1)
    xz = np.where(ok[..., None], x, 0.0)
    A = np.concatenate([xz[..., 0:1] * P[None, :, 2] - P[None, :, 0],
                        xz[..., 1:2] * P[None, :, 2] - P[None, :, 1]], axis=1)  # (N, 2C, 4)
    A *= np.concatenate([ok, ok], axis=1)[..., None]
    out = np.full((len(x), 3), np.nan)
    good = ok.sum(1) >= max(min_views, 2)
    if good.any():
        _, _, vt = np.linalg.svd(A[good])
        X = vt[:, -1]
        w = X[:, 3]
        fine = np.abs(w) > 1e-12
        res = np.full((len(X), 3), np.nan)
        res[fine] = X[fine, :3] / w[fine, None]
        out[good] = res
    return out.reshape(*shape, 3)


def _row_median(values: np.ndarray) -> np.ndarray:
    """Median over the last axis ignoring NaN; ``inf`` for rows without a value."""
    ok = ~np.isnan(values)
    out = np.full(values.shape[:-1], np.inf)
    rows = ok.any(-1)
    if rows.any():
        out[rows] = np.nanmedian(values[rows], axis=-1)
    return out


def _project(T: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Normalised projections (..., 2) of points (..., 3); NaN behind the camera."""
    Y = X @ T[:3, :3].T + T[:3, 3]
    z = Y[..., 2:3]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(z > 1e-9, Y[..., :2] / z, np.nan)


def _n_hypotheses(good_share: float) -> int:
    """Draws needed for :data:`RANSAC_CONFIDENCE` of one all-good sample of two (adaptive RANSAC)."""
    w = min(max(good_share, 1e-3), 1.0) ** 2
    if w >= 1.0:
        return MIN_HYPOTHESES
    n = np.log(1 - RANSAC_CONFIDENCE) / np.log(1 - w)
    return int(np.clip(np.ceil(n), MIN_HYPOTHESES, MAX_HYPOTHESES))


def _one_to_one(inliers: np.ndarray, share: np.ndarray, keys_a: np.ndarray, keys_b: np.ndarray) -> np.ndarray:
    """Accepted candidates (share >= MATCH_SHARE), each key of either side used once, best share first."""
    ok = np.flatnonzero((share >= MATCH_SHARE) & (inliers >= MIN_SHARED_KEYPOINTS * MATCH_SHARE))
    ok = ok[np.lexsort((-inliers[ok], -share[ok]))]
    used_a, used_b, keep = set(), set(), []
    for i in ok:
        ka, kb = keys_a[i], keys_b[i]
        if ka in used_a or kb in used_b:
            continue
        used_a.add(ka)
        used_b.add(kb)
        keep.append(i)
    return np.array(keep, int)


def _draw_two(rng: np.random.Generator, frames: np.ndarray) -> np.ndarray:
    """Two candidate indices, from two different frames when there are two."""
    i = int(rng.integers(len(frames)))
    other = np.flatnonzero(frames != frames[i])
    j = int(rng.choice(other)) if len(other) else int(rng.integers(len(frames)))
    return np.array([i, j])


def _sampson_sq(E: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Squared Sampson distances (normalised units) of correspondences (..., 2) under E."""
    h1 = np.concatenate([x1, np.ones(x1.shape[:-1] + (1,))], -1)
    h2 = np.concatenate([x2, np.ones(x2.shape[:-1] + (1,))], -1)
    Ex1 = h1 @ E.T
    Etx2 = h2 @ E
    num = np.einsum("...i,...i->...", h2, Ex1) ** 2
    den = Ex1[..., 0] ** 2 + Ex1[..., 1] ** 2 + Etx2[..., 0] ** 2 + Etx2[..., 1] ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        return num / den


def match_camera_pair(xy: np.ndarray, seen: np.ndarray, a: int, b: int, focal_px: tuple[float, float],
                      ransac_px: float, match_px: float, rng: np.random.Generator) -> PairMatch | None:
    """The relative pose of two cameras and their matching detections, from unassociated detections.

    Parameters
    ----------
    xy : ndarray of shape (n_cams, T, P, K, 2)
        Normalised coordinates of every detection (see the module docstring).
    seen : ndarray of shape (n_cams, T, P, K) of bool
    a, b : int
        The two cameras.
    focal_px : tuple of float
        Their focal lengths, pixels (the threshold in normalised units).
    ransac_px : float
        Threshold of OpenCV's RANSAC inside each hypothesis' fit, pixels (at least half ``match_px``:
        the keypoints of one person in two cameras disagree by a few pixels).
    match_px : float
        Sampson distance for a keypoint of a detection pair to agree with a hypothesis, pixels.
    rng : numpy.random.Generator
        Draws the samples.

    Returns
    -------
    PairMatch or None
        None when no detection pair can be compared or no hypothesis explains any.
    """
    shared = seen[a][:, :, None, :] & seen[b][:, None, :, :]  # (T, P, P, K)
    n_shared = shared.sum(-1)
    ct, cp, cq = np.nonzero(n_shared >= MIN_SHARED_KEYPOINTS)
    if len(ct) == 0:
        return None
    m = shared[ct, cp, cq]  # (n, K)
    x1, x2 = xy[a, ct, cp], xy[b, ct, cq]  # (n, K, 2)
    scale = np.sqrt(focal_px[0] * focal_px[1])
    thr, fit_thr = match_px / scale, max(ransac_px, match_px / 2) / scale
    counts = m.sum(1)
    P = seen.shape[2]
    keys_a, keys_b = ct * P + cp, ct * P + cq

    def score(E):
        d2 = _sampson_sq(E, np.where(m[..., None], x1, 0.0), np.where(m[..., None], x2, 0.0))
        inl = m & (d2 < thr ** 2)
        n_in = inl.sum(1)
        keep = _one_to_one(n_in, n_in / counts, keys_a, keys_b)
        return int(n_in[keep].sum()), keep, inl

    def fit(idx, mask=None):
        mm = m[idx] if mask is None else mask[idx]
        p1, p2 = x1[idx][mm], x2[idx][mm]
        if len(p1) < 6:
            return []
        if len(p1) > LOCAL_POINTS:  # a refit on many pairs: a random subset is as good and much faster
            sub = rng.choice(len(p1), LOCAL_POINTS, replace=False)
            p1, p2 = p1[sub], p2[sub]
        E, _ = cv2.findEssentialMat(p1, p2, np.eye(3), cv2.RANSAC, RANSAC_CONFIDENCE, fit_thr, FIT_ITERATIONS)
        if E is None:
            return []
        return [E[i:i + 3] for i in range(0, len(E) - 2, 3)]

    best = (0, np.zeros(0, int), None, None)
    drawn, needed = 0, MIN_HYPOTHESES
    n_keys = max(1, min(len(np.unique(keys_a)), len(np.unique(keys_b))))
    while drawn < needed:
        drawn += 1
        for E in fit(_draw_two(rng, ct)):
            cand = (*score(E), E)
            if cand[0] <= best[0]:
                continue
            for _ in range(LOCAL_REFITS):  # local optimisation: refit on what the hypothesis explains
                better = [(*score(E2), E2) for E2 in fit(cand[1], cand[2])]
                better = max(better, key=lambda h: h[0], default=None)
                if better is None or better[0] <= cand[0]:
                    break
                cand = better
            best = cand
            needed = max(needed, _n_hypotheses(len(best[1]) / n_keys))
    if best[2] is None:
        return None
    s, keep, inl, E = best
    p1, p2 = x1[keep][inl[keep]], x2[keep][inl[keep]]
    mask = np.full((len(p1), 1), 255, np.uint8)
    _, R, t, _ = cv2.recoverPose(E, p1, p2, np.eye(3), mask=mask)
    return PairMatch(a, b, R, t.ravel(), ct[keep], cp[keep], cq[keep], inl[keep].sum(1), s, len(ct))


def _join(edges: list, n_cams: int, accept=None) -> tuple[np.ndarray, np.ndarray]:
    """Join detections linked by edges ``(frame, cam a, det a, cam b, det b)`` into groups, in the edges'
    order, never two detections of one camera in a group, and only when ``accept(frame, group)`` (if
    given) holds for the grown group; groups of two cameras or more."""
    groups, frames = [], []
    k = 0
    while k < len(edges):
        t = edges[k][0]
        owner: dict = {}  # (camera, detection) -> index in comp
        comp: list = []
        while k < len(edges) and edges[k][0] == t:
            _, a, p, b, q = edges[k]
            k += 1
            ga, gb = owner.get((a, p)), owner.get((b, q))
            if ga is None and gb is None:
                g = -np.ones(n_cams, int)
                g[a], g[b] = p, q
                comp.append(g)
                owner[(a, p)] = owner[(b, q)] = len(comp) - 1
            elif gb is None and comp[ga][b] < 0:
                g = comp[ga].copy()
                g[b] = q
                if accept is None or accept(t, g):
                    comp[ga] = g
                    owner[(b, q)] = ga
            elif ga is None and comp[gb][a] < 0:
                g = comp[gb].copy()
                g[a] = p
                if accept is None or accept(t, g):
                    comp[gb] = g
                    owner[(a, p)] = gb
            elif ga is not None and gb is not None and ga != gb and not np.any((comp[ga] >= 0) & (comp[gb] >= 0)):
                g = np.maximum(comp[ga], comp[gb])
                if accept is None or accept(t, g):
                    comp[ga] = g
                    comp[gb] = -np.ones(n_cams, int)
                    for key, v in owner.items():
                        if v == gb:
                            owner[key] = ga
        for g in comp:
            if (g >= 0).sum() >= 2:
                groups.append(g)
                frames.append(t)
    if not groups:
        return np.zeros((0, n_cams), int), np.zeros(0, int)
    return np.array(groups), np.array(frames)


def group_pair_matches(matches: list[PairMatch], n_cams: int) -> tuple[np.ndarray, np.ndarray]:
    """Detection pairs of several camera pairs joined into groups, frame by frame.

    Per frame the pairs are taken strongest first (most agreeing keypoints) and join their two
    detections' groups unless that would put two detections of one camera in a group (two people
    in one epipolar plane of a camera pair can agree by chance; the other cameras then disagree).

    Parameters
    ----------
    matches : list of PairMatch
    n_cams : int

    Returns
    -------
    groups : ndarray of shape (G, n_cams) of int
        Per group its detection in each camera, -1 where none; two cameras or more each.
    frames : ndarray of shape (G,) of int
    """
    edges = [(int(t), m.a, int(p), m.b, int(q), -int(n)) for m in matches
             for t, p, q, n in zip(m.frames, m.det_a, m.det_b, m.pair_inliers)]
    edges.sort(key=lambda e: (e[0], e[5]))
    return _join([e[:5] for e in edges], n_cams)


def associate_detections(cam_from_world: np.ndarray, xy: np.ndarray, seen: np.ndarray, focal_px: np.ndarray,
                         match_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Group the detections of calibrated cameras into people, frame by frame.

    Every two detections of two cameras in one frame are triangulated from the two; their error is
    the median over shared keypoints of the larger reprojection error.  Pairs within ``match_px``
    are joined, lowest error first, never two detections of one camera in a group.  Each group is
    then triangulated from all its detections, and a detection whose median reprojection error
    exceeds ``2 * match_px`` leaves it (a chance pair: two people in one epipolar plane).

    Parameters
    ----------
    cam_from_world : ndarray of shape (n_cams, 4, 4)
    xy : ndarray of shape (n_cams, T, P, K, 2)
        Normalised coordinates (see the module docstring).
    seen : ndarray of shape (n_cams, T, P, K) of bool
    focal_px : ndarray of shape (n_cams,)
    match_px : float
        Largest pair error, pixels.

    Returns
    -------
    groups : ndarray of shape (G, n_cams) of int
        Per group its detection in each camera, -1 where none; at least two cameras each.
    frames : ndarray of shape (G,) of int
        The frame (index into T) of each group.
    error_px : ndarray of shape (G,)
        Per group the largest median reprojection error of its detections, pixels.
    """
    Tm = np.asarray(cam_from_world, float)
    C = seen.shape[0]
    f = np.asarray(focal_px, float)
    edges = []
    for i in range(C):
        for j in range(i + 1, C):
            sh = seen[i][:, :, None, :] & seen[j][:, None, :, :]
            ct, cp, cq = np.nonzero(sh.sum(-1) >= MIN_SHARED_KEYPOINTS)
            if len(ct) == 0:
                continue
            m = sh[ct, cp, cq]
            pts = np.stack([np.where(m[..., None], xy[i, ct, cp], np.nan),
                            np.where(m[..., None], xy[j, ct, cq], np.nan)])
            X = triangulate_normalised(Tm[[i, j]], pts)  # (n, K, 3)
            e = [np.linalg.norm(_project(Tm[c], X) - xy[c, ct, p], axis=-1) * f[c] for c, p in ((i, cp), (j, cq))]
            e = np.where(m, np.fmax(e[0], e[1]), np.nan)
            e = np.where(np.isnan(e) & m, np.inf, e)  # behind a camera
            err = _row_median(e)
            for k in np.flatnonzero(err <= match_px):
                edges.append((float(err[k]), int(ct[k]), i, int(cp[k]), j, int(cq[k])))
    edges.sort(key=lambda e: (e[1], e[0]))

    def accept(t, g):  # a group grows only when all its detections agree with their joint triangulation
        err = _group_errors(Tm, xy, seen, f, g[None], np.array([t]))
        return bool(np.nanmax(err) <= JOIN_FACTOR * match_px)

    groups, frames = _join([e[1:] for e in edges], C, accept)
    if not len(groups):
        return groups, frames, np.zeros(0)
    # every group triangulated from all its detections; detections far from it leave
    for _ in range(2):
        err = _group_errors(Tm, xy, seen, f, groups, frames)
        out = err > JOIN_FACTOR * match_px
        if not out.any():
            break
        groups = np.where(out, -1, groups)
        keep = (groups >= 0).sum(1) >= 2
        groups, frames = groups[keep], frames[keep]
    err = _group_errors(Tm, xy, seen, f, groups, frames)
    return groups, frames, np.where(groups >= 0, err, 0.0).max(1)


def group_observations(groups: np.ndarray, frames: np.ndarray, xy: np.ndarray,
                       seen: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The keypoints of groups of detections, one row per group.

    Parameters
    ----------
    groups : ndarray of shape (G, n_cams) of int
        Per group its detection in each camera, -1 where none.
    frames : ndarray of shape (G,) of int
    xy : ndarray of shape (n_cams, T, P, K, 2)
    seen : ndarray of shape (n_cams, T, P, K) of bool

    Returns
    -------
    xy : ndarray of shape (n_cams, G, K, 2)
        NaN where the group has no detection in the camera.
    seen : ndarray of shape (n_cams, G, K) of bool
    """
    C = xy.shape[0]
    gx = np.full((C, len(groups)) + xy.shape[3:], np.nan)
    gs = np.zeros((C, len(groups), xy.shape[3]), bool)
    for c in range(C):
        g = np.flatnonzero(groups[:, c] >= 0)
        gx[c, g] = xy[c, frames[g], groups[g, c]]
        gs[c, g] = seen[c, frames[g], groups[g, c]]
    return gx, gs


def _group_errors(Tm, xy, seen, f, groups, frames) -> np.ndarray:
    """(G, C) median reprojection error (pixels) of each group's detections; NaN where none."""
    gx, gs = group_observations(groups, frames, xy, seen)
    obs = np.where(gs[..., None], gx, np.nan)
    X = triangulate_normalised(Tm, obs)
    err = np.full((len(groups), len(Tm)), np.nan)
    for c in range(len(Tm)):
        e = np.linalg.norm(_project(Tm[c], X) - obs[c], axis=-1) * f[c]
        e = np.where(np.isfinite(obs[c]).all(-1) & np.isfinite(X).all(-1) & np.isnan(e), np.inf, e)
        err[:, c] = np.where(groups[:, c] >= 0, _row_median(e), np.nan)
    return np.where(np.isnan(err) & (groups >= 0), np.inf, err)
