"""Marker identification: labels from the marker set's template and the skeleton (source 004, §3.1.1).

The source asks the user to attach each marker of the first frame to a joint;
here the labels come from the marker set itself.  The marker set places its
markers on a 14-joint skeleton (:meth:`MarkerSet.positions`); standing in the
generic rest pose (:meth:`BodyProportions.rest_pose`) this gives a template
of labelled 3D markers.  The template is fitted to the unlabelled markers of
one frame by an articulated iterative-closest-point loop:

1. several initial headings about the vertical (the performer may face any
   way), the template centred on the markers;
2. each round assigns template markers to reconstructed markers one-to-one
   (Hungarian assignment, :func:`scipy.optimize.linear_sum_assignment`, with a
   "no partner" cost so ghosts and missing markers stay unassigned), then fits
   the root pose and a scale (Umeyama similarity on the assigned pairs) and a
   coarse pose: each segment, parent before child, is rotated about its
   proximal joint (Kabsch on the markers of the segment and its descendants),
   carrying its descendants;
3. the heading with the smallest truncated residual wins;
4. each segment of 3 to 5 markers is then placed as a whole
   (:func:`register_segment`): every one-to-one pairing of its markers with
   the free points near it is fitted rigidly, the best fit wins and, among
   nearly equal ones, the one turning the segment least from its coarse pose
   (a cluster plate is nearly planar and nearly symmetric: turned over it
   fits within millimetres).  Pairing marker by marker with the nearest
   points leaves a plate that sits a marker spacing away from the
   template's (a shank cluster placed higher than the generic one) with two
   of its markers on the other two's points, and those unlabelled; the
   whole shape has one place.  This is done once, after the heading is
   chosen: inside the heading loop it lets a wrong heading fit as well as the
   right one, since the left and right arms' plates are congruent;
5. the final assignment gives the labels.

The labels are then checked with the distances between markers of one
segment (rigid on the body): a marker whose distances to its segment mates
disagree with the scaled template is left unlabelled in that frame (it is
recovered later by the tracker from its segment's motion), never given a
doubtful label.

A user labelling file (:func:`read_labelling`) replaces the template fit.
"""

from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass
from itertools import permutations

import numpy as np
from scipy.optimize import linear_sum_assignment

from toolkit.errors import InputError
from toolkit.skeleton import JOINTS_14

#: Segment -> (pivot joint, parent segment) of the coarse pose fit; ``mid_hip`` is the
#: midpoint of the hip joints.  Segments not listed move with the root only.
SEGMENT_TREE = {
    "pelvis": (None, None),
    "thorax": ("mid_hip", "pelvis"),
    "head": ("neck", "thorax"),
    "l_upperarm": ("l_shoulder", "thorax"), "l_forearm": ("l_elbow", "l_upperarm"),
    "l_hand": ("l_wrist", "l_forearm"),
    "r_upperarm": ("r_shoulder", "thorax"), "r_forearm": ("r_elbow", "r_upperarm"),
    "r_hand": ("r_wrist", "r_forearm"),
    "l_thigh": ("l_hip", "pelvis"), "l_shank": ("l_knee", "l_thigh"), "l_foot": ("l_ankle", "l_shank"),
    "r_thigh": ("r_hip", "pelvis"), "r_shank": ("r_knee", "r_thigh"), "r_foot": ("r_ankle", "r_shank"),
}

#: The segment each joint of the 14-joint skeleton moves with (as its distal end).
JOINT_SEGMENT = {
    "head": "head", "neck": "thorax", "l_shoulder": "thorax", "r_shoulder": "thorax",
    "l_elbow": "l_upperarm", "l_wrist": "l_forearm", "r_elbow": "r_upperarm", "r_wrist": "r_forearm",
    "l_hip": "pelvis", "r_hip": "pelvis", "l_knee": "l_thigh", "l_ankle": "l_shank",
    "r_knee": "r_thigh", "r_ankle": "r_shank",
}


@dataclass(frozen=True)
class IdentifyConfig:
    """Settings of the template fit.

    Attributes
    ----------
    headings : int
        Initial headings tried, evenly spaced over 360 degrees.
    rounds : int
        Assignment / fit rounds per heading.
    gate_m : tuple of float
        "No partner" distance of the Hungarian assignment, metres, from the
        first round to the last (shrinking as the fit improves).
    reach_m : float
        Search radius of a segment's markers in the coarse pose fit, metres.
    refine_rounds : int
        Rounds of per-segment rigid refinement after the coarse pose ...
    refine_reach_m : float
        ... with this search radius, metres.
    scale_range : tuple of float
        Allowed template scale (performer size over the generic 1.75 m person).
    distance_tolerance : float
        Relative tolerance of the within-segment distance check ...
    distance_floor_m : float
        ... plus this absolute slack (soft tissue, marker placement), metres.
    segment_reach_m : float
        Points offered to a segment's registration (:func:`register_segment`):
        within this distance of one of its markers, metres ...
    segment_candidates : int
        ... at most this many more than the segment has markers, the nearest.
    segment_gate_m : float
        A marker's cost in a pairing is its squared distance to its partner,
        capped at this (also the cost of a marker without one), metres.
    segment_slack_m : float
        Pairings within ``k * segment_slack_m ** 2`` of the best cost (k
        markers) count as equal; the one turning the segment least wins.
    register_rounds : int
        Passes of the registration over all segments.
    """

    headings: int = 8
    rounds: int = 12
    gate_m: tuple = (0.35, 0.06)
    scale_range: tuple = (0.8, 1.25)
    reach_m: float = 0.5
    refine_rounds: int = 3
    refine_reach_m: float = 0.1
    distance_tolerance: float = 0.2
    distance_floor_m: float = 0.02
    segment_reach_m: float = 0.15
    segment_candidates: int = 3
    segment_gate_m: float = 0.03
    segment_slack_m: float = 0.005
    register_rounds: int = 2


@dataclass(frozen=True)
class Identification:
    """The labels of one frame's markers.

    Attributes
    ----------
    point_of_marker : ndarray of shape (M,) int
        Index of the reconstructed point carrying each label, -1 if none.
    fitted : ndarray of shape (M, 3)
        The fitted template's markers, metres (a prediction for unlabelled ones).
    residual_m : ndarray of shape (M,)
        Distance from each fitted template marker to its point, NaN if none.
    scale : float
    heading_deg : float
        The initial heading that won.
    rejected : tuple of int
        Markers left unlabelled by the within-segment distance check.
    """

    point_of_marker: np.ndarray
    fitted: np.ndarray
    residual_m: np.ndarray
    scale: float
    heading_deg: float
    rejected: tuple = ()


def _rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def kabsch(a: np.ndarray, b: np.ndarray, *, center: bool = True) -> np.ndarray:
    """Rotation R (3, 3) minimising sum |R (a_i - ca) - (b_i - cb)|^2 for points (N, 3)."""
    if center:
        a = a - a.mean(axis=0)
        b = b - b.mean(axis=0)
    U, _, Vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    return Vt.T @ np.diag([1.0, 1.0, d if d != 0 else 1.0]) @ U.T


def _similarity(a: np.ndarray, b: np.ndarray, scale_range) -> tuple[float, np.ndarray, np.ndarray]:
    """Umeyama: s, R, t with b ~ s R a + t."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    a0, b0 = a - ca, b - cb
    R = kabsch(a0, b0, center=False)
    s = float(np.sum((a0 @ R.T) * b0) / max(np.sum(a0 ** 2), 1e-12))
    s = float(np.clip(s, *scale_range))
    return s, R, cb - s * R @ ca


def assign(template: np.ndarray, points: np.ndarray, gate: float) -> np.ndarray:
    """One-to-one assignment (M,) of template markers to points, -1 where farther than ``gate``."""
    M, K = template.shape[0], points.shape[0]
    out = -np.ones(M, int)
    if K == 0:
        return out
    d2 = np.sum((template[:, None, :] - points[None, :, :]) ** 2, axis=2)
    cost = np.concatenate([d2, np.full((M, M), gate ** 2)], axis=1)  # dummy "no partner" columns
    rows, cols = linear_sum_assignment(cost)
    real = cols < K
    out[rows[real]] = cols[real]
    return out


class _Body:
    """The template's markers and joints with the segment tree, moved in place by the fit."""

    def __init__(self, template, joints, segments):
        self.markers = np.array(template, float)
        self.coarse = self.markers.copy()  # where the coarse pose put them (set by the fit)
        self.joints = np.array(joints, float)
        names = [s if s in SEGMENT_TREE else "pelvis" for s in segments]
        self.order = [s for s in SEGMENT_TREE if SEGMENT_TREE[s][0] is not None]  # parents first
        self.order_all = [s for s in SEGMENT_TREE if s in set(names)]  # the root too
        desc = {s: {s} for s in SEGMENT_TREE}
        for s in reversed(list(SEGMENT_TREE)):
            parent = SEGMENT_TREE[s][1]
            if parent is not None:
                desc[parent] |= desc[s]
        names_arr = np.array(names)
        self.segment_of = names_arr
        jseg = np.array([JOINT_SEGMENT[j] for j in JOINTS_14])
        self.subtree_markers = {s: np.isin(names_arr, list(desc[s])) for s in SEGMENT_TREE}
        self.subtree_joints = {s: np.isin(jseg, list(desc[s])) for s in SEGMENT_TREE}

    def pivot(self, segment: str) -> np.ndarray:
        name = SEGMENT_TREE[segment][0]
        if name == "mid_hip":
            return 0.5 * (self.joints[JOINTS_14.index("l_hip")] + self.joints[JOINTS_14.index("r_hip")])
        return self.joints[JOINTS_14.index(name)]

    def move_all(self, s, R, t):
        self.markers = s * self.markers @ R.T + t
        self.joints = s * self.joints @ R.T + t

    def rotate_segment(self, segment: str, target: np.ndarray, match: np.ndarray, reach: float,
                       max_turn_deg: float = 90.0) -> None:
        """Rotate ``segment`` and its descendants about its pivot onto ``target`` (ICP step).

        The subtree's markers are paired one-to-one with the points that no
        marker outside the subtree holds, within ``reach`` metres (a limb far
        from the rest pose has no partner within the global gate yet).  A
        turn of more than ``max_turn_deg`` in one step is refused.
        """
        sel = self.subtree_markers[segment]
        if sel.sum() < 2:
            return
        outside = match[~sel]
        free = np.setdiff1d(np.arange(target.shape[0]), outside[outside >= 0])
        if free.size < 2:
            return
        sub = assign(self.markers[sel], target[free], reach)
        ok = sub >= 0
        if ok.sum() < 2:
            return
        p = self.pivot(segment)
        R = kabsch(self.markers[sel][ok] - p, target[free[sub[ok]]] - p, center=False)
        if np.trace(R) < 1.0 + 2.0 * np.cos(np.radians(max_turn_deg)):
            return  # a segment turned over (a foot's heel onto its toe) is a wrong pairing, not a pose
        self.markers[sel] = (self.markers[sel] - p) @ R.T + p
        js = self.subtree_joints[segment]
        self.joints[js] = (self.joints[js] - p) @ R.T + p


    def refine_segment(self, segment: str, target: np.ndarray, match: np.ndarray, reach: float) -> None:
        """Move one segment's markers alone (rigidly; translation only with fewer than 3 partners).

        Absorbs what the generic skeleton gets wrong about the performer
        (segment lengths, marker placement) once the coarse pose is in place.
        """
        sel = np.flatnonzero(self.segment_of == segment)
        if sel.size == 0:
            return
        outside = np.delete(match, sel)
        free = np.setdiff1d(np.arange(target.shape[0]), outside[outside >= 0])
        if free.size == 0:
            return
        sub = assign(self.markers[sel], target[free], reach)
        ok = sub >= 0
        if not ok.any():
            return
        a, b = self.markers[sel][ok], target[free[sub[ok]]]
        if 3 <= ok.sum() <= 5:  # the partners' order with the best rigid fit (no swap within the segment)
            b = b[list(_best_permutation(a, b))]
        if ok.sum() >= 3:
            R = kabsch(a, b)
            self.markers[sel] = (self.markers[sel] - a.mean(axis=0)) @ R.T + b.mean(axis=0)
        else:
            self.markers[sel] += (b - a).mean(axis=0)

    def register_segment(self, segment: str, target: np.ndarray, match: np.ndarray,
                         config: "IdentifyConfig") -> None:
        """Place a segment of 3 to 5 markers where its whole shape fits the free points best.

        See :func:`register_segment`; the points held by other segments'
        markers are not offered; turns are measured from the coarse pose
        (``self.coarse``, before the per-segment refinement, which may have
        turned a symmetric segment over).  Segments of other sizes are left as
        they are.
        """
        sel = np.flatnonzero(self.segment_of == segment)
        if not 3 <= sel.size <= 5:
            return
        outside = np.delete(match, sel)
        free = np.setdiff1d(np.arange(target.shape[0]), outside[outside >= 0])
        moved = register_segment(self.markers[sel], target[free], config, coarse=self.coarse[sel])
        if moved is not None:
            self.markers[sel] = moved


def _batched_kabsch(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rotations and translations of many rigid fits: ``b[p] ~ a[p] @ R[p].T + t[p]``.

    Parameters
    ----------
    a, b : ndarray of shape (P, k, 3)

    Returns
    -------
    R : ndarray of shape (P, 3, 3)
    t : ndarray of shape (P, 3)
    residual : ndarray of shape (P, k)
        Distance of each fitted point to its partner, metres.
    """
    ca, cb = a.mean(axis=1, keepdims=True), b.mean(axis=1, keepdims=True)
    H = np.einsum("pki,pkj->pij", a - ca, b - cb)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(U @ Vt))
    D = np.ones((H.shape[0], 3))
    D[:, 2] = np.where(d == 0, 1.0, d)
    R = np.einsum("pji,pj,pkj->pik", Vt, D, U)  # V D U^T
    t = cb[:, 0] - np.einsum("pij,pj->pi", R, ca[:, 0])
    fitted = np.einsum("pij,pkj->pki", R, a) + t[:, None]
    return R, t, np.linalg.norm(fitted - b, axis=2)


def _pairings(k: int, n: int, min_pairs: int) -> np.ndarray:
    """Every one-to-one pairing (P, k) of k markers with n points (-1: no partner), >= min_pairs pairs."""
    from itertools import combinations

    rows = []
    for m in range(min(k, n), min_pairs - 1, -1):
        for markers in combinations(range(k), m):
            for pts in permutations(range(n), m):
                row = [-1] * k
                for i, j in zip(markers, pts):
                    row[i] = j
                rows.append(row)
    return np.array(rows, int).reshape(-1, k)


_PAIRINGS: dict = {}


def register_segment(markers: np.ndarray, points: np.ndarray, config: "IdentifyConfig", *,
                     coarse: np.ndarray | None = None) -> np.ndarray | None:
    """The rigid placement of one segment's template markers that fits the nearby points best.

    Every one-to-one pairing of the segment's k markers (3 <= k <= 5) with
    the ``config.segment_candidates + k`` points nearest them (within
    ``config.segment_reach_m``), with at most one marker left without a
    partner, is fitted rigidly (batched Kabsch).  Its cost is the sum over
    the markers of the squared distance to the partner, capped at
    ``config.segment_gate_m``, and that cap for a marker without one.
    Among the pairings within ``k * config.segment_slack_m ** 2`` of the
    lowest cost the one turning the markers least wins: a plate's markers lie
    nearly in a plane and a few of them nearly symmetric, so the plate turned
    over (or about its normal) fits almost as well, and the coarse pose, which
    the skeleton and the neighbouring segments placed, is the nearer one.

    Parameters
    ----------
    markers : ndarray of shape (k, 3)
        The segment's template markers in their current place, metres.
    points : ndarray of shape (n, 3)
        The points not held by other segments' markers, metres.
    config : IdentifyConfig
    coarse : ndarray of shape (k, 3), optional
        The markers where the skeleton's coarse pose put them (the turns are
        measured from there); by default ``markers``.

    Returns
    -------
    ndarray of shape (k, 3) or None
        The markers moved rigidly; None when fewer than 3 points are near.
    """
    k = markers.shape[0]
    d = np.linalg.norm(points[:, None] - markers[None], axis=2).min(axis=1)
    near = np.flatnonzero(d <= config.segment_reach_m)
    near = near[np.argsort(d[near])][:k + config.segment_candidates]
    if near.size < 3:
        return None
    key = (k, near.size, max(3, k - 1))
    if key not in _PAIRINGS:
        _PAIRINGS[key] = _pairings(*key)
    pairs = _PAIRINGS[key]
    b = points[near]
    cost = np.zeros(len(pairs))
    turn = np.zeros(len(pairs))
    Rs, ts = np.zeros((len(pairs), 3, 3)), np.zeros((len(pairs), 3))
    g2 = config.segment_gate_m ** 2
    for m in np.unique((pairs >= 0).sum(axis=1)):  # one batch per number of pairs
        rows = np.flatnonzero((pairs >= 0).sum(axis=1) == m)
        mk = np.argsort(pairs[rows] < 0, axis=1, kind="stable")[:, :m]  # the paired markers, in order
        pk = np.take_along_axis(pairs[rows], mk, axis=1)
        R, t, res = _batched_kabsch(markers[mk], b[pk])
        cost[rows] = np.minimum(res ** 2, g2).sum(axis=1) + (k - m) * g2
        total = R if coarse is None else R @ kabsch(coarse, markers)  # from the coarse pose
        turn[rows] = np.degrees(np.arccos(np.clip((np.trace(total, axis1=1, axis2=2) - 1) / 2, -1, 1)))
        Rs[rows], ts[rows] = R, t
    close = np.flatnonzero(cost <= cost.min() + k * config.segment_slack_m ** 2)
    best = close[np.argmin(turn[close])]
    return markers @ Rs[best].T + ts[best]


def _best_permutation(a: np.ndarray, b: np.ndarray, slack_m: float = 0.005) -> tuple:
    """The order of the points ``b`` (k, 3) that ``a`` (k, 3) fits best rigidly (k <= 5).

    Among the orders whose rigid-fit residual is within ``slack_m`` (rms, metres)
    of the best, the one turning ``a`` least wins (a symmetric plate fits
    as well turned over; the coarse pose is closer to the right one).
    """
    perms = np.array(list(permutations(range(a.shape[0]))))
    bb = b[perms]  # (P, k, 3)
    a0 = a - a.mean(axis=0)
    b0 = bb - bb.mean(axis=1, keepdims=True)
    H = np.einsum("ki,pkj->pij", a0, b0)
    U, S, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(U @ Vt))
    D = np.ones((len(perms), 3))
    D[:, 2] = d
    R = np.einsum("pji,pj,pkj->pik", Vt, D, U)  # V D U^T
    angle = np.degrees(np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    # residual of the best rotation: |a0|^2 + |b0|^2 - 2 (s1 + s2 + d s3)
    res = np.sum(a0 ** 2) + np.sum(b0 ** 2, axis=(1, 2)) - 2 * (S[:, 0] + S[:, 1] + d * S[:, 2])
    near = res <= res.min() + a.shape[0] * slack_m ** 2
    return tuple(perms[np.flatnonzero(near)[np.argmin(angle[near])]])


def _truncated_cost(body: _Body, points: np.ndarray, match: np.ndarray, gate: float) -> float:
    d = np.full(match.size, gate)
    ok = match >= 0
    d[ok] = np.minimum(np.linalg.norm(body.markers[ok] - points[match[ok]], axis=1), gate)
    return float(np.sum(d ** 2))


def fit_template(points: np.ndarray, template: np.ndarray, joints: np.ndarray, segments,
                 config: IdentifyConfig = IdentifyConfig()) -> Identification:
    """Fit the template to one frame's unlabelled markers (see the module docstring).

    Parameters
    ----------
    points : ndarray of shape (K, 3)
        Reconstructed markers, metres (may include a few ghosts, may miss a few markers).
    template : ndarray of shape (M, 3)
        The marker set's markers on the generic skeleton in the rest pose.
    joints : ndarray of shape (14, 3)
        That skeleton's joints.
    segments : sequence of str
        The segment of each marker (M,).
    config : IdentifyConfig

    Returns
    -------
    Identification
    """
    points = np.asarray(points, float).reshape(-1, 3)
    M = template.shape[0]
    if points.shape[0] < 3:
        raise InputError("identification frame", "at least 3 reconstructed markers", f"{points.shape[0]}")
    gates = np.geomspace(config.gate_m[0], config.gate_m[1], config.rounds)
    best = None
    centre = points.mean(axis=0)
    for h in np.arange(config.headings) * 2 * np.pi / config.headings:
        body = _Body(template, joints, segments)
        R0 = _rot_z(h)
        c0 = body.markers.mean(axis=0)
        body.move_all(1.0, R0, centre - R0 @ c0)
        for r, gate in enumerate(gates):
            match = assign(body.markers, points, gate)
            ok = match >= 0
            if ok.sum() < 3:
                break
            s, R, t = _similarity(body.markers[ok], points[match[ok]], config.scale_range)
            body.move_all(s, R, t)
            if r >= 2:  # the coarse pose once the root is roughly in place
                match = assign(body.markers, points, gate)
                for seg in body.order:
                    body.rotate_segment(seg, points, match, max(gate, config.reach_m))
                    match = assign(body.markers, points, gate)
        body.coarse = body.markers.copy()
        for _ in range(config.refine_rounds):
            match = assign(body.markers, points, gates[-1])
            for seg in np.unique(body.segment_of):
                body.refine_segment(seg, points, match, config.refine_reach_m)
                match = assign(body.markers, points, gates[-1])
        match = assign(body.markers, points, gates[-1])
        cost = _truncated_cost(body, points, match, gates[-1])
        if best is None or cost < best[0]:
            best = (cost, h, body, match)
    _, h, body, match = best
    for _ in range(config.register_rounds):  # each segment's shape as a whole (not done per heading: see above)
        for seg in body.order_all:
            body.register_segment(seg, points, match, config)
            match = assign(body.markers, points, gates[-1])
    scale = float(np.linalg.norm(body.joints[0] - body.joints[JOINTS_14.index("l_ankle")])
                  / max(np.linalg.norm(joints[0] - joints[JOINTS_14.index("l_ankle")]), 1e-9))
    res = np.full(M, np.nan)
    ok = match >= 0
    res[ok] = np.linalg.norm(body.markers[ok] - points[match[ok]], axis=1)
    match, rejected = check_segment_distances(points, match, body.markers, segments, config)
    res[list(rejected)] = np.nan
    return Identification(match, body.markers, res, scale, float(np.degrees(h)), rejected)


def check_segment_distances(points: np.ndarray, match: np.ndarray, fitted: np.ndarray, segments,
                            config: IdentifyConfig = IdentifyConfig()) -> tuple[np.ndarray, tuple]:
    """Unlabel markers whose distances to their segment mates disagree with the fitted template.

    Parameters
    ----------
    points : ndarray of shape (K, 3)
    match : ndarray of shape (M,) int
        Point of each marker, -1 if none.
    fitted : ndarray of shape (M, 3)
        The fitted template (its within-segment distances are the reference).
    segments : sequence of str (M,)
    config : IdentifyConfig

    Returns
    -------
    match : ndarray of shape (M,) int
        With the rejected markers set to -1.
    rejected : tuple of int
        The markers unlabelled, worst first.
    """
    match = np.array(match, int)
    seg = np.asarray(segments)
    same = seg[:, None] == seg[None, :]
    np.fill_diagonal(same, False)
    ref = np.linalg.norm(fitted[:, None] - fitted[None], axis=2)
    tol = config.distance_tolerance * ref + config.distance_floor_m
    rejected = []
    while True:
        ok = match >= 0
        X = np.where(ok[:, None], points[np.maximum(match, 0)], np.nan)
        d = np.linalg.norm(X[:, None] - X[None], axis=2)
        bad = same & ok[:, None] & ok[None, :] & (np.abs(d - ref) > tol)
        n_bad = bad.sum(axis=1)
        if n_bad.max(initial=0) == 0:
            break
        worst = int(np.argmax(n_bad))
        match[worst] = -1
        rejected.append(worst)
    return match, tuple(rejected)


def read_labelling(path: str | os.PathLike, labels) -> tuple[int, dict]:
    """Read a user labelling file: the 3D position of some labels in one frame.

    Two formats, chosen by the file's suffix:

    * JSON: ``{"frame": 0, "markers": {"LASI": [x, y, z], ...}}``;
    * CSV with a header ``label,x,y,z`` (and optionally a ``frame`` column,
      the same value on every row; frame 0 when absent).

    Positions are metres in the capture's world frame (e.g. picked in a viewer).

    Parameters
    ----------
    path : str or PathLike
    labels : sequence of str
        The marker set's labels; every label of the file must be one of them.

    Returns
    -------
    frame : int
    positions : dict of str -> ndarray of shape (3,)

    Raises
    ------
    InputError
        Naming the file and the field at fault.
    """
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except OSError as e:
        raise InputError(path, "a readable labelling file", f"{type(e).__name__}: {e}") from None
    if path.lower().endswith(".json"):
        def unique(pairs):  # json.loads would keep the last of duplicated keys silently
            keys = [k for k, _ in pairs]
            dup = sorted({k for k in keys if keys.count(k) > 1})
            if dup:
                raise InputError(f"{path}: label {dup[0]!r}", "each label once", "a duplicated label (key)")
            return dict(pairs)

        try:
            data = json.loads(text, object_pairs_hook=unique)
        except json.JSONDecodeError as e:
            raise InputError(path, "valid JSON", str(e)) from None
        if not isinstance(data, dict) or not isinstance(data.get("markers"), dict):
            raise InputError(f"{path}: markers", "an object label -> [x, y, z]", f"{type(data).__name__}")
        frame, rows = data.get("frame", 0), list(data["markers"].items())
    elif path.lower().endswith(".csv"):
        reader = csv.DictReader(text.splitlines())
        need = {"label", "x", "y", "z"}
        if reader.fieldnames is None or not need <= set(reader.fieldnames):
            raise InputError(f"{path}: header", "columns label,x,y,z[,frame]", f"{reader.fieldnames}")
        table = list(reader)
        frames = {r.get("frame") or "0" for r in table}
        if len(frames) > 1:
            raise InputError(f"{path}: frame", "one frame for every row", f"frames {sorted(frames)}")
        frame = frames.pop() if frames else 0
        rows = [(r["label"], [r["x"], r["y"], r["z"]]) for r in table]
    else:
        raise InputError(path, "a .json or .csv labelling file", f"suffix {os.path.splitext(path)[1]!r}")
    try:
        frame = int(frame)
    except (TypeError, ValueError):
        raise InputError(f"{path}: frame", "an integer frame", f"{frame!r}") from None
    known = set(labels)
    out = {}
    for label, xyz in rows:
        if label not in known:
            raise InputError(f"{path}: label {label!r}", "a label of the marker set", "an unknown label")
        if label in out:
            raise InputError(f"{path}: label {label!r}", "each label once", "a duplicated label")
        try:
            p = np.asarray(xyz, dtype=float).reshape(3)
        except (TypeError, ValueError):
            raise InputError(f"{path}: {label}", "three numbers x, y, z (metres)", f"{xyz!r}") from None
        if not np.all(np.isfinite(p)):
            raise InputError(f"{path}: {label}", "finite coordinates", f"{p.tolist()}")
        out[label] = p
    if not out:
        raise InputError(path, "at least one labelled marker", "none")
    return frame, out


def identify_from_labelling(points: np.ndarray, labels, positions: dict, tolerance_m: float) -> np.ndarray:
    """Match a labelling file's positions to one frame's reconstructed markers.

    Parameters
    ----------
    points : ndarray of shape (K, 3)
    labels : sequence of str (M,)
    positions : dict of str -> ndarray (3,)
        From :func:`read_labelling`.
    tolerance_m : float
        Largest distance between a given position and its marker.

    Returns
    -------
    ndarray of shape (M,) int
        Point of each label, -1 for labels not in the file or without a point within tolerance.
    """
    labels = list(labels)
    idx = [labels.index(k) for k in positions]
    target = np.array([positions[k] for k in positions])
    sub = assign(target, np.asarray(points, float).reshape(-1, 3), tolerance_m)
    out = -np.ones(len(labels), int)
    out[idx] = sub
    return out
