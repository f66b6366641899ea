"""Which detections of different cameras show the same person: ray-distance affinity, one frame.

A 2D detector finds every person in each view, in no particular order, and
different views see different people (a bystander at the edge of one image, a
person hidden in another).  Two detections of one person in two calibrated
views have keypoint rays that (nearly) meet: the affinity of a pair of
detections is the **median distance between the rays of their shared
keypoints** (metres, :func:`pair_ray_distances`), counted only where the
closest points lie in front of both cameras.  It is the 3D form of the
epipolar distance and needs no keypoint format: any detector's keypoints are
compared keypoint by keypoint.

Detections are then grouped (:func:`associate_frame`): a group holds at most
one detection per view; from every pair of detections whose ray distance is
at most :data:`MAX_RAY_DISTANCE_M` a group is grown, view by view, with the
detection whose mean ray distance to the group's is lowest, at most
:data:`MAX_RAY_DISTANCE_M` and at most :data:`JOIN_RATIO` times the group's own
plus :data:`JOIN_MARGIN_M`, none of them above :data:`MAX_RAY_DISTANCE_FACTOR`
times :data:`MAX_RAY_DISTANCE_M`.  The group seen by the most views (then with the lowest mean ray
distance) is kept, its detections leave, and the others are grown again.  A
"ghost" (person A in one view paired with person B in another, whose rays
may meet by chance, closer than A's own) gathers no third view and loses to
the groups that do; with two views the lower ray distance wins.  A group seen by fewer than ``min_views`` cameras
(a bystander seen by one camera only) is not a person, and neither is one
outside the **capture volume**: its keypoints must lie in the field of view of
more than :data:`CAPTURE_VOLUME_SHARE` of the cameras (whether they detected
it or not: a person hidden from a view is still a person).  A bystander
standing behind two cameras of a four-camera lab, whose rays meet in the
other two, is outside it.  Each person also counts the cameras that should
see it but show nothing there (``unexplained``: :data:`SHOULD_SEE_SHARE` of its
keypoints project into the view's image, the view is not in
the group, and no detection of that view covers
:data:`EXPLAINED_OVERLAP` of the box the person projects to; an occluder in
front covers it): the rays of two bystanders each seen by one camera can meet
by chance in a small floating "ghost" that the other cameras do not see.
:mod:`toolkit.multiview.tracking` drops people unexplained in most of their frames.  Identities over time
are :mod:`toolkit.multiview.tracking`'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.multiview.keypoints import MIN_JOINT_CONFIDENCE
from toolkit.multiview.offsets import triangulate_views

__all__ = ["MAX_RAY_DISTANCE_M", "MAX_RAY_DISTANCE_FACTOR", "MIN_SHARED_KEYPOINTS", "CAPTURE_VOLUME_SHARE",
           "AssociationConfig", "FrameAssociation", "pair_ray_distances", "associate_frame", "views_in_sight",
           "group_keypoints"]

#: Two detections show one person when the median distance between their keypoints' rays is
#: at most this (metres).  Detector noise (2-5 px) and calibration error (up to 8 px) at
#: 4-40 m give 1-8 cm; two people standing side by side are 0.4 m or more apart.
MAX_RAY_DISTANCE_M = 0.2
#: ... and no pair of the merged group's detections is further apart than this many times it.
MAX_RAY_DISTANCE_FACTOR = 2.0
#: Two detections are compared only on at least this many keypoints confident in both.
MIN_SHARED_KEYPOINTS = 4
#: A person must be in the field of view of more than this share of the cameras (the capture
#: volume: 2 of 2 or 3 cameras, 3 of 4, 4 of 6, 5 of 8), and of at least ``min_views``.
CAPTURE_VOLUME_SHARE = 0.5
#: A person is in a camera's field of view when this share of its keypoints project into the image.
IN_VIEW_SHARE = 0.5
#: A camera should show a person when this share of its keypoints projects into its image.
SHOULD_SEE_SHARE = 0.9
#: A camera "shows" a person when one of its detections covers this share of the box the
#: person's keypoints project to (the person itself, or someone in front of it).
EXPLAINED_OVERLAP = 0.25
#: A detection joins a group when its mean ray distance to the members is at most this many times
#: the members' own ...
JOIN_RATIO = 2.0
#: ... plus this (metres): a view where the person is hidden must not lend it someone else
#: (a bystander's rays passing 12 cm from a group whose own agree to 2 cm).
JOIN_MARGIN_M = 0.03
#: Rays closer to parallel than this (|sin| of their angle) do not tell where they meet.
MIN_RAY_SINE = 1e-3


@dataclass(frozen=True)
class AssociationConfig:
    """Options of :func:`associate_frame`.

    Parameters
    ----------
    max_ray_distance_m : float
        Largest mean ray distance (metres) of a group (:data:`MAX_RAY_DISTANCE_M`).
    max_ray_distance_factor : float
        Largest ray distance of any pair of a group, in units of ``max_ray_distance_m``.
    min_shared_keypoints : int
        Keypoints confident in both detections needed to compare them.
    min_confidence : float
        Keypoints below this confidence are not compared (nor triangulated).
    min_views : int
        Cameras that must see a group for it to be a person (2: a detection seen by one
        camera only is not a person).
    capture_volume_share : float
        A person must be in the field of view of more than this share of the cameras
        (:data:`CAPTURE_VOLUME_SHARE`); 0 keeps people anywhere.
    """

    max_ray_distance_m: float = MAX_RAY_DISTANCE_M
    max_ray_distance_factor: float = MAX_RAY_DISTANCE_FACTOR
    min_shared_keypoints: int = MIN_SHARED_KEYPOINTS
    min_confidence: float = MIN_JOINT_CONFIDENCE
    min_views: int = 2
    capture_volume_share: float = CAPTURE_VOLUME_SHARE

    def __post_init__(self):
        if not self.max_ray_distance_m > 0:
            raise InputError("AssociationConfig.max_ray_distance_m", "a positive distance in metres",
                             repr(self.max_ray_distance_m))
        if not self.max_ray_distance_factor >= 1:
            raise InputError("AssociationConfig.max_ray_distance_factor", "a factor >= 1",
                             repr(self.max_ray_distance_factor))
        if self.min_shared_keypoints < 1 or self.min_views < 2:
            raise InputError("AssociationConfig", "min_shared_keypoints >= 1 and min_views >= 2",
                             f"{self.min_shared_keypoints}, {self.min_views}")
        if not 0 <= self.capture_volume_share < 1:
            raise InputError("AssociationConfig.capture_volume_share", "a share in [0, 1)",
                             repr(self.capture_volume_share))

    def views_needed(self, n_views: int) -> int:
        """Cameras whose field of view must hold a person (the capture volume)."""
        return max(self.min_views, int(np.floor(self.capture_volume_share * n_views)) + 1)


@dataclass(frozen=True)
class FrameAssociation:
    """The people of one frame.

    Attributes
    ----------
    groups : ndarray of shape (n_people, n_views) of int
        Per person, the index of its detection in each view, -1 where the view does not see
        it; people sorted by the number of views (most first), then by ray distance.
    cost : ndarray of shape (n_people,)
        Mean ray distance between the group's detections, metres.
    joints3d : ndarray of shape (n_people, K, 3)
        The keypoints triangulated from the group (closest points of the rays), metres;
        NaN with fewer than two rays.
    unassigned : tuple of (int, int)
        ``(view, detection)`` of the detections in no person (seen by too few views).
    outside : ndarray of shape (n_outside, n_views) of int
        Groups seen by enough views but outside the capture volume (not people).
    unexplained : ndarray of shape (n_people,) of int
        Per person, the cameras that have it in sight, are not in its group, and show no
        detection over where it projects.
    """

    groups: np.ndarray
    cost: np.ndarray
    joints3d: np.ndarray
    unassigned: tuple
    outside: np.ndarray
    unexplained: np.ndarray

    @property
    def n_people(self) -> int:
        return len(self.groups)


def _check_detections(detections, rig: Rig) -> list[np.ndarray]:
    if len(detections) != len(rig):
        raise InputError("detections", f"one array of detections per camera ({len(rig)})", f"{len(detections)}")
    out, k = [], None
    for v, d in enumerate(detections):
        a = np.asarray(d, float)
        if a.size == 0:
            a = a.reshape(0, k or 0, 3)
        if a.ndim != 3 or a.shape[-1] != 3:
            raise InputError(f"detections[{v}]", "an array of shape (P, K, 3) (x, y, confidence)",
                             f"shape {a.shape}")
        if len(a) and k is not None and a.shape[1] != k:
            raise InputError(f"detections[{v}]", f"{k} keypoints per person like the other views",
                             f"{a.shape[1]}")
        if len(a):
            k = a.shape[1]
        out.append(a)
    return [a if len(a) else np.zeros((0, k or 0, 3)) for a in out]


def _confident(det: np.ndarray, min_confidence: float) -> np.ndarray:
    c = np.nan_to_num(det[..., 2])
    return np.isfinite(det[..., :2]).all(-1) & (c >= min_confidence) & (c > 0)


def pair_ray_distances(cam_a, det_a: np.ndarray, cam_b, det_b: np.ndarray,
                       min_confidence: float = MIN_JOINT_CONFIDENCE,
                       min_shared: int = MIN_SHARED_KEYPOINTS) -> np.ndarray:
    """Median ray distance between every detection of one view and every detection of another.

    Parameters
    ----------
    cam_a, cam_b : Camera
    det_a : ndarray of shape (Pa, K, 3)
        ``(x, y, confidence)`` pixels of the detections of ``cam_a``.
    det_b : ndarray of shape (Pb, K, 3)
    min_confidence : float
        Keypoints below it are not compared.
    min_shared : int
        Pairs with fewer keypoints confident in both are ``inf``.

    Returns
    -------
    ndarray of shape (Pa, Pb)
        Metres: the median over shared keypoints of the distance between the two rays (``inf``
        for a keypoint whose rays meet behind a camera or are parallel); ``inf`` for pairs
        with too few shared keypoints.
    """
    Pa, Pb = len(det_a), len(det_b)
    out = np.full((Pa, Pb), np.inf)
    if Pa == 0 or Pb == 0:
        return out
    ok_a, ok_b = _confident(det_a, min_confidence), _confident(det_b, min_confidence)
    oa, da = cam_a.rays(np.where(ok_a[..., None], det_a[..., :2], np.nan))  # (Pa, K, 3)
    ob, db = cam_b.rays(np.where(ok_b[..., None], det_b[..., :2], np.nan))
    w0 = (oa[:, None] - ob[None])                                          # (Pa, Pb, K, 3)
    d1, d2 = da[:, None], db[None]
    b = np.sum(d1 * d2, -1)
    d = np.sum(d1 * w0, -1)
    e = np.sum(d2 * w0, -1)
    den = 1.0 - b * b
    with np.errstate(invalid="ignore", divide="ignore"):
        s = (b * e - d) / den
        t = (e - b * d) / den
        gap = np.linalg.norm(w0 + s[..., None] * d1 - t[..., None] * d2, axis=-1)
    shared = ok_a[:, None] & ok_b[None]
    bad = (den < MIN_RAY_SINE ** 2) | ~(s > 0) | ~(t > 0) | ~np.isfinite(gap)
    gap = np.where(shared, np.where(bad, np.inf, gap), np.nan)
    n = shared.sum(-1)
    enough = n >= min_shared
    if enough.any():
        out[enough] = np.nanmedian(gap[enough], axis=-1)  # inf joints count as large, not as missing
    return out


def _pair_costs(dets: list, rig: Rig, config: AssociationConfig) -> tuple[list, np.ndarray]:
    """Every detection a node; the ray distance between every two detections of different views.

    Parameters
    ----------
    dets : list of ndarray of shape (P_v, K, 3)
        Checked detections per view.
    rig : Rig
    config : AssociationConfig

    Returns
    -------
    nodes : list of (int, int)
        ``(view, detection)`` of each node.
    C : ndarray of shape (N, N)
        Ray distance of each pair of nodes, metres (inf within a view or without enough shared keypoints).
    """
    V = len(rig)
    nodes = [(v, i) for v in range(V) for i in range(len(dets[v]))]
    N = len(nodes)
    C = np.full((N, N), np.inf)
    start = np.cumsum([0] + [len(d) for d in dets])
    for a in range(V):
        for b in range(a + 1, V):
            D = pair_ray_distances(rig[a], dets[a], rig[b], dets[b], config.min_confidence,
                                   config.min_shared_keypoints)
            C[start[a]:start[a + 1], start[b]:start[b + 1]] = D
            C[start[b]:start[b + 1], start[a]:start[a + 1]] = D.T
    return nodes, C


def _grown_clusters(C: np.ndarray, view_of: np.ndarray, thr: float, hard: float) -> list:
    """Greedy clusters: hypotheses grown from every agreeing pair; the one seen by most views (then the lowest
    ray distance) is taken, its detections leave, and the rest are grown again.  Left-overs are single nodes.

    Parameters
    ----------
    C : ndarray of shape (N, N)
        Ray distances, metres.
    view_of : ndarray of int, shape (N,)
        The view of each node.
    thr : float
        Largest mean ray distance of a member, metres.
    hard : float
        Largest ray distance of any pair within a cluster, metres.

    Returns
    -------
    list of list of int
        Node indices of each cluster.
    """
    N = len(C)

    def grow(members):
        """Add, view by view (closest first), the detection agreeing best with the members."""
        members = list(members)
        while True:
            free = np.flatnonzero(~np.isin(view_of, view_of[members]) & available)
            if not len(free):
                return members
            c = C[np.ix_(members, free)]
            fin = np.isfinite(c)
            n = fin.sum(0)
            mean = np.where(n > 0, np.where(fin, c, 0).sum(0) / np.maximum(n, 1), np.inf)
            limit = min(thr, JOIN_RATIO * group_cost(members) + JOIN_MARGIN_M)
            ok = (n > 0) & (mean <= limit) & ~(np.where(fin, c, 0) > hard).any(0)
            if not ok.any():
                return members
            members.append(int(free[np.argmin(np.where(ok, mean, np.inf))]))

    def group_cost(members):
        c = C[np.ix_(members, members)]
        fin = np.isfinite(c) & ~np.eye(len(members), dtype=bool)
        return float(c[fin].mean()) if fin.any() else np.inf

    available = np.ones(N, bool)
    clusters = []
    while True:
        pairs = [(a, b) for a in np.flatnonzero(available) for b in np.flatnonzero(available)
                 if a < b and view_of[a] != view_of[b] and C[a, b] <= thr]
        best, best_key = None, None
        for a, b in pairs:
            g = grow([a, b])
            key = (-len(g), group_cost(g))
            if best_key is None or key < best_key:
                best, best_key = g, key
        if best is None:
            break
        clusters.append(best)
        available[best] = False
    clusters += [[n] for n in np.flatnonzero(available)]
    return clusters


def _in_sight(people: list, dets: list, rig: Rig, K: int, config: AssociationConfig) -> tuple[list, list]:
    """Triangulate each person; keep those in sight of enough views, counting the views that should see them
    but have no detection there.

    Parameters
    ----------
    people : list of (ndarray of int, shape (V,), float)
        Detection per view (-1 none) and cost of each person.
    dets : list of ndarray of shape (P_v, K, 3)
    rig : Rig
    K : int
        Keypoints per detection.
    config : AssociationConfig

    Returns
    -------
    kept : list of (ndarray of int, float, ndarray of shape (K, 3), int)
        Groups, costs, joints (metres) and unexplained views of the people kept.
    outside : list of ndarray of int, shape (V,)
        Groups of people in sight of too few views.
    """
    V = len(rig)
    kept, outside = [], []
    need = config.views_needed(V)
    boxes = [_boxes(d, config.min_confidence) for d in dets]
    for g, c in people:
        uv, w = group_keypoints(dets, g, K, config.min_confidence)
        _, _, X, _ = triangulate_views(rig, uv, w)
        sight = views_in_sight(rig, X)
        if sight.sum() < need:
            outside.append(g)
            continue
        unexplained = 0
        for v in np.flatnonzero(views_in_sight(rig, X, SHOULD_SEE_SHARE) & (g < 0)):
            box = _boxes(rig[v].project(X[np.isfinite(X).all(-1)])[None, :, :], None)[0]
            unexplained += int(not (_cover(boxes[v], box) >= EXPLAINED_OVERLAP).any())
        kept.append((g, c, X, unexplained))
    return kept, outside


def associate_frame(detections, rig: Rig, config: AssociationConfig = AssociationConfig()) -> FrameAssociation:
    """Group the detections of one frame into people (see the module docstring).

    Parameters
    ----------
    detections : list of ndarray of shape (P_v, K, 3)
        Per camera of ``rig``, every person detected: ``(x, y, confidence)`` pixels, NaN /
        confidence 0 for keypoints not detected; ``P_v`` may differ between views (and be 0).
    rig : Rig
    config : AssociationConfig

    Returns
    -------
    FrameAssociation

    Raises
    ------
    InputError
        Not one array per camera, or arrays not of shape (P, K, 3) with one K.
    """
    dets = _check_detections(detections, rig)
    V = len(rig)
    K = next((d.shape[1] for d in dets if d.shape[1]), 0)
    nodes, C = _pair_costs(dets, rig, config)
    thr, hard = config.max_ray_distance_m, config.max_ray_distance_m * config.max_ray_distance_factor
    view_of = np.array([v for v, _ in nodes], int)
    clusters = _grown_clusters(C, view_of, thr, hard)
    clusters = _refine(clusters, C, view_of, thr, hard)

    people, unassigned = [], []
    for cl in clusters:
        if len(cl) < config.min_views:
            unassigned += [nodes[n] for n in cl]
            continue
        g = np.full(V, -1)
        for n in cl:
            g[nodes[n][0]] = nodes[n][1]
        c = C[np.ix_(cl, cl)]
        fin = np.isfinite(c) & ~np.eye(len(cl), dtype=bool)
        people.append((g, float(c[fin].mean()) if fin.any() else np.inf))
    kept, outside = _in_sight(people, dets, rig, K, config)
    kept.sort(key=lambda p: (-(p[0] >= 0).sum(), p[1]))
    groups = np.array([p[0] for p in kept], int).reshape(len(kept), V)
    cost = np.array([p[1] for p in kept], float)
    joints = np.array([p[2] for p in kept], float).reshape(len(kept), K, 3)   # K = 0 when nobody is seen
    return FrameAssociation(groups, cost, joints, tuple(sorted(unassigned)),
                            np.array(outside, int).reshape(-1, V), np.array([p[3] for p in kept], int))


def _mean_cost(C: np.ndarray, d: int, members, hard: float) -> float:
    """Mean finite ray distance of detection ``d`` to ``members``; inf if none or one above ``hard``."""
    if not len(members):
        return np.inf
    c = C[d, members]
    fin = np.isfinite(c)
    if not fin.any() or (c[fin] > hard).any():
        return np.inf
    return float(c[fin].mean())


def _refine(clusters: list, C: np.ndarray, view_of: np.ndarray, thr: float, hard: float) -> list:
    """Move a detection to another group (lacking its view) whose members it agrees with better.

    Growing the group seen by most views first can give it another person's detection in a
    view where its own is missing (occluded), at the 5-7 cm that separate people at one
    height; that detection agrees better with its own person's group and moves there.
    """
    clusters = [list(c) for c in clusters]
    for _ in range(len(view_of)):
        moved = False
        for gi in range(len(clusters)):
            for d in list(clusters[gi]):
                rest = [m for m in clusters[gi] if m != d]
                cur = _mean_cost(C, d, rest, hard)
                best, target = cur, None
                if len(rest) >= 2:
                    c = C[np.ix_(rest, rest)]
                    fin = np.isfinite(c) & ~np.eye(len(rest), dtype=bool)
                    own = float(c[fin].mean()) if fin.any() else np.inf
                    if cur > min(thr, JOIN_RATIO * own + JOIN_MARGIN_M):  # it does not belong: leaves
                        best, target = np.inf, -1
                for hi, H in enumerate(clusters):
                    if hi == gi or not H or (view_of[H] == view_of[d]).any():
                        continue
                    c = _mean_cost(C, d, H, hard)
                    if c <= thr and c < best:
                        best, target = c, hi
                if target is not None:
                    clusters[gi].remove(d)
                    if target < 0:
                        clusters.append([d])
                    else:
                        clusters[target].append(d)
                    moved = True
        if not moved:
            break
    return [c for c in clusters if c]


def _boxes(det: np.ndarray, min_confidence: float | None) -> np.ndarray:
    """(P, 4) boxes (x0, y0, x1, y1) of detections (P, K, 2 or 3); NaN rows when no keypoint."""
    xy = det[..., :2] if min_confidence is None else np.where(
        _confident(det, min_confidence)[..., None], det[..., :2], np.nan)
    out = np.full((len(det), 4), np.nan)
    ok = np.isfinite(xy).all(-1).any(-1)
    if ok.any():
        out[ok, :2] = np.nanmin(xy[ok], axis=1)
        out[ok, 2:] = np.nanmax(xy[ok], axis=1)
    return out


def _cover(boxes: np.ndarray, box: np.ndarray) -> np.ndarray:
    """(P,) share of ``box`` (4,) covered by each of ``boxes`` (P, 4); 0 for NaN boxes."""
    if not len(boxes) or not np.isfinite(box).all():
        return np.zeros(len(boxes))
    w = np.clip(np.minimum(boxes[:, 2], box[2]) - np.maximum(boxes[:, 0], box[0]), 0, None)
    h = np.clip(np.minimum(boxes[:, 3], box[3]) - np.maximum(boxes[:, 1], box[1]), 0, None)
    area = max((box[2] - box[0]) * (box[3] - box[1]), 1.0)
    return np.nan_to_num(w * h / area)


def views_in_sight(rig: Rig, points3d: np.ndarray, share: float = IN_VIEW_SHARE) -> np.ndarray:
    """Which cameras have a body in their field of view.

    Parameters
    ----------
    rig : Rig
    points3d : ndarray of shape (K, 3)
        The body's keypoints, metres; NaN ones are ignored.
    share : float
        At least this share of the finite keypoints must be in front of the camera and
        project into its image.

    Returns
    -------
    ndarray of shape (n_views,) of bool
    """
    X = np.asarray(points3d, float)
    X = X[np.isfinite(X).all(-1)]
    if not len(X):
        return np.zeros(len(rig), bool)
    out = []
    for cam in rig:
        front = cam.depth_of(X) > 0
        inside = front & cam.in_image(cam.project(X))
        out.append(inside.mean() >= share)
    return np.array(out)


def group_keypoints(detections, group: np.ndarray, n_keypoints: int, min_confidence: float = MIN_JOINT_CONFIDENCE):
    """The pixels and weights of one group's detections, one row per view.

    Parameters
    ----------
    detections : list of ndarray of shape (P_v, K, 3)
    group : ndarray of shape (n_views,) of int
        Detection index per view, -1 for none.
    n_keypoints : int
    min_confidence : float

    Returns
    -------
    uv : ndarray of shape (n_views, K, 2)
        Pixels, NaN where the view has no detection or the keypoint is below ``min_confidence``.
    w : ndarray of shape (n_views, K)
        Confidences, 0 where missing.
    """
    V = len(group)
    uv = np.full((V, n_keypoints, 2), np.nan)
    w = np.zeros((V, n_keypoints))
    for v, i in enumerate(group):
        if i >= 0:
            d = np.asarray(detections[v][i], float)
            ok = _confident(d, min_confidence)
            uv[v] = np.where(ok[:, None], d[:, :2], np.nan)
            w[v] = np.where(ok, d[:, 2], 0.0)
    return uv, w
