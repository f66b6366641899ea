"""The initial pose when no previous skeleton exists (source 001, step 210).

1. **Key points**: the filled bins of the orthographic grid are clustered
   (k-means on their 3D positions, about :attr:`InitConfig.bins_per_keypoint`
   bins each); clusters whose bins touch at a similar depth are neighbours in a
   region adjacency graph.
2. **Classification**: a key point with at most one neighbour, or at a peak of
   the radial profile, is an *extremity* (head, hand, foot); one with two
   neighbours a *limb* point; the others *torso*.
3. **Head candidates**: extremities among the highest points, linked to the
   torso within a few hops, and roughly aligned with the principal direction
   from the centroid.
4. **Torso extrapolated from height**: the user is assumed standing; stature is
   measured from the head top to the ground (or to the lowest point; a person
   cut by the image border gets a default stature) and the torso patch placed
   below the head with the median proportions of that stature, facing the camera.
5. **Limbs by back-tracking**: the remaining extremities are assigned to the
   hands and feet (or to none) by a depth-first search that prunes every
   partial assignment breaking a joint or morphology constraint (reach of the
   arm or leg, feet below the hips, one extremity per limb); assignments score
   by the number of limbs found, side consistency and not crossing over;
   elbows and knees are placed by two-bone inverse kinematics, unassigned
   limbs hang.

Each head candidate gives a pose for each of its best limb assignments; the
caller keeps the one of lowest energy after a local fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.cluster.vq import kmeans2

from toolkit.body.control_points import (
    HEAD,
    L_ELBOW,
    L_FOOT,
    L_HAND,
    L_HIP,
    L_KNEE,
    L_SHOULDER,
    R_ELBOW,
    R_FOOT,
    R_HAND,
    R_HIP,
    R_KNEE,
    R_SHOULDER,
    BodyDimensions,
    rest_pose13,
)
from toolkit.depth.orus import OrusGrid
from toolkit.depth.radial import RadialProfile
from toolkit.motion.kinematics import two_bone_ik

__all__ = [
    "CLASS_NAMES",
    "EXTREMITY",
    "LIMB",
    "TORSO_CLASS",
    "HeadCandidate",
    "InitConfig",
    "InitialPose",
    "KeyPoints",
    "estimate_stature",
    "head_candidates",
    "initial_poses",
    "key_points",
]

EXTREMITY, LIMB, TORSO_CLASS = 0, 1, 2
CLASS_NAMES = ("extremity", "limb", "torso")


@dataclass(frozen=True)
class InitConfig:
    """Settings of the initial-pose search.

    Attributes
    ----------
    bins_per_keypoint : float
        Grid bins per key point (sets the number of k-means clusters).
    min_keypoints, max_keypoints : int
    neighbour_depth_m : float
        Touching clusters are neighbours if their bins' depths differ less than this.
    head_top_fraction : float
        Head candidates lie in this top fraction of the user's height.
    head_max_angle_deg : float
        Largest angle between centroid-to-head and the principal direction.
    max_head_candidates : int
    limb_assignments : int
        Best limb assignments kept per head candidate (each becomes a pose).
    reach_slack : float
        Limb reach tolerance (fraction).
    default_stature_m : float
        Stature when it cannot be measured.
    stature_range_m : tuple of float
    """

    bins_per_keypoint: float = 8.0
    min_keypoints: int = 8
    max_keypoints: int = 40
    neighbour_depth_m: float = 0.15
    head_top_fraction: float = 0.3
    head_max_angle_deg: float = 45.0
    max_head_candidates: int = 3
    limb_assignments: int = 3
    reach_slack: float = 0.15
    default_stature_m: float = 1.75
    stature_range_m: tuple[float, float] = (1.45, 2.05)


@dataclass(frozen=True)
class KeyPoints:
    """Clustered key points of the user.

    Attributes
    ----------
    positions : ndarray of shape (k, 3)
        View frame, metres.
    sizes : ndarray of shape (k,)
        Bins per key point.
    classes : ndarray of shape (k,), int
        :data:`EXTREMITY`, :data:`LIMB` or :data:`TORSO_CLASS`.
    adjacency : ndarray of shape (k, k), bool
    labels : ndarray of shape (ny, nx), int
        Key point of every filled bin (-1 elsewhere).
    """

    positions: np.ndarray
    sizes: np.ndarray
    classes: np.ndarray
    adjacency: np.ndarray
    labels: np.ndarray


def key_points(grid: OrusGrid, profile: RadialProfile | None, rng=None, config: InitConfig = InitConfig()) -> KeyPoints:
    """Cluster the grid into key points, link them and classify them.

    ``rng`` None starts the k-means seeding at the highest bin (the same grid always
    gives the same key points); a generator or seed starts it at a random bin.
    """
    r, c = np.nonzero(grid.filled)
    P = grid.mean[r, c]
    n = len(P)
    k = int(np.clip(round(n / config.bins_per_keypoint), config.min_keypoints, config.max_keypoints))
    k = max(min(k, n), 1)
    # spread-out seeds by farthest-point sampling from the highest bin: the same grid always
    # gives the same key points (``rng`` is kept for callers that want random restarts)
    seeds = [int(np.argmin(P[:, 1]))] if rng is None else [int(np.random.default_rng(rng).integers(n))]
    dmin = np.linalg.norm(P - P[seeds[0]], axis=1)
    for _ in range(1, k):
        j = int(np.argmax(dmin))
        seeds.append(j)
        dmin = np.minimum(dmin, np.linalg.norm(P - P[j], axis=1))
    cent, lab = kmeans2(P, P[seeds], iter=8, minit="matrix", missing="warn")
    used = np.unique(lab)
    remap = -np.ones(k, int)
    remap[used] = np.arange(len(used))
    lab = remap[lab]
    cent = cent[used]
    k = len(used)
    labels = -np.ones(grid.shape, int)
    labels[r, c] = lab
    sizes = np.bincount(lab, minlength=k)
    A = np.zeros((k, k), bool)
    z = grid.mean[..., 2]
    ny, nx = labels.shape
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        j0, j1 = (0, nx - dj) if dj >= 0 else (-dj, nx)
        a = labels[:ny - di, j0:j1]
        b = labels[di:, j0 + dj:j1 + dj]
        za = z[:ny - di, j0:j1]
        zb = z[di:, j0 + dj:j1 + dj]
        m = (a >= 0) & (b >= 0) & (a != b) & (np.abs(za - zb) < config.neighbour_depth_m)
        A[a[m], b[m]] = True
        A[b[m], a[m]] = True
    deg = A.sum(1)
    cls = np.where(deg <= 1, EXTREMITY, np.where(deg == 2, LIMB, TORSO_CLASS))
    if profile is not None:
        for p in list(profile.peaks):
            q = profile.points[p]
            j = int(np.argmin(np.linalg.norm(cent[:, :2] - q[:2], axis=1)))
            if np.linalg.norm(cent[j, :2] - q[:2]) < 0.2:
                cls[j] = EXTREMITY
    return KeyPoints(cent, sizes, cls, A, labels)


@dataclass(frozen=True)
class HeadCandidate:
    """A possible head: key point index, position (view frame) and score."""

    index: int
    position: np.ndarray
    score: float


def _hops(A: np.ndarray, start: int, max_hops: int) -> np.ndarray:
    """Hop distance from ``start`` to every key point (max_hops + 1 beyond)."""
    k = len(A)
    dist = np.full(k, max_hops + 1)
    dist[start] = 0
    frontier = [start]
    for h in range(1, max_hops + 1):
        nxt = []
        for f in frontier:
            for j in np.nonzero(A[f])[0]:
                if dist[j] > h:
                    dist[j] = h
                    nxt.append(j)
        frontier = nxt
    return dist


def _run_width(grid: OrusGrid, xy: np.ndarray) -> float:
    """Width (metres) of the run of filled bins in the grid row of ``xy`` that contains it (0 if empty)."""
    j = int(np.floor((xy[0] - grid.origin[0]) / grid.bin_size))
    i = int(np.floor((xy[1] - grid.origin[1]) / grid.bin_size))
    ny, nx = grid.shape
    if not (0 <= i < ny and 0 <= j < nx):
        return 0.0
    row = grid.filled[i]
    if not row[j]:
        near = np.nonzero(row[max(j - 1, 0):j + 2])[0]
        if len(near) == 0:
            return 0.0
        j = max(j - 1, 0) + int(near[0])
    lo = j
    while lo > 0 and row[lo - 1]:
        lo -= 1
    hi = j
    while hi < nx - 1 and row[hi + 1]:
        hi += 1
    return (hi - lo + 1) * grid.bin_size


def _body_centre_x(grid: OrusGrid) -> float:
    """Median x of the filled bins in the middle band of the silhouette's height (the torso)."""
    ys = grid.mean[..., 1][grid.filled]
    xs = grid.mean[..., 0][grid.filled]
    if len(ys) == 0:
        return 0.0
    y0, y1 = np.percentile(ys, [35, 70])
    band = (ys >= y0) & (ys <= y1)
    return float(np.median(xs[band])) if band.any() else float(np.median(xs))


def top_contour_peaks(grid: OrusGrid, min_width_m: float = 0.10, max_width_m: float = 0.30,
                      min_drop_m: float = 0.08, min_body_m: float = 0.0) -> list[np.ndarray]:
    """Head-like bumps of the silhouette's upper contour.

    For every grid column the highest filled bin gives the upper contour; a
    bump is a run of columns within one bin of the run's top, between
    ``min_width_m`` and ``max_width_m`` wide, with the contour at least
    ``min_drop_m`` lower on both sides within 0.25 m (neck and shoulders) and,
    if ``min_body_m`` is set, a body under it: the grid column below the bump's
    top filled over at least that length (or down to the grid's lower edge),
    which a raised fist beside the head does not have.

    Returns
    -------
    list of ndarray of shape (3,)
        View-frame positions of the bumps' tops (mean of the run's top bins), highest first;
        of bumps less than 20 cm apart sideways only the highest.
    """
    ny, nx = grid.shape
    filled = grid.filled
    has = filled.any(0)
    top = np.where(has, np.argmax(filled, axis=0), ny).astype(float)   # row index, smaller = higher
    s = grid.bin_size
    reach = int(round(0.25 / s))
    out = []
    j = 0
    while j < nx:
        if not has[j]:
            j += 1
            continue
        k = j
        while k + 1 < nx and has[k + 1] and abs(top[k + 1] - top[j]) <= 1:
            k += 1
        run_top = top[j:k + 1].min()
        width = (k - j + 1) * s
        left = top[max(j - reach, 0):j]
        right = top[k + 1:k + 1 + reach]
        drop_l = (left.max() - run_top) * s if len(left) else 0.0
        drop_r = (right.max() - run_top) * s if len(right) else 0.0
        if min_width_m <= width <= max_width_m and drop_l >= min_drop_m and drop_r >= min_drop_m:
            cols = np.arange(j, k + 1)
            rows = top[j:k + 1].astype(int)
            p = grid.mean[rows, cols].mean(0)
            if min_body_m <= 0 or _column_filled(grid, (j + k) // 2, int(run_top), min_body_m) >= 0.8:
                out.append((run_top, p))
        j = k + 1
    out.sort(key=lambda t: t[0])
    kept: list = []
    for _, p in out:        # one bump per head: drop lower ones beside a higher one
        if all(abs(p[0] - q[0]) > 0.2 for q in kept):
            kept.append(p)
    return kept


def _column_filled(grid: OrusGrid, col: int, row: int, length_m: float) -> float:
    """Fraction of filled bins in column ``col`` from ``row`` down over ``length_m`` (or to the grid's edge)."""
    n = max(int(round(length_m / grid.bin_size)), 1)
    seg = grid.filled[row:row + n, col]
    return float(seg.mean()) if len(seg) else 0.0


def head_candidates(kp: KeyPoints, centroid: np.ndarray, principal: np.ndarray, profile: RadialProfile | None,
                    config: InitConfig = InitConfig(), grid: OrusGrid | None = None) -> list[HeadCandidate]:
    """Head candidates, best first.

    Key points in the top :attr:`InitConfig.head_top_fraction` of the user are
    scored by height, by how central they are over the torso (raised hands are
    off to the side), by the width of the silhouette there (a head is 12 to 26 cm
    wide, a hand or forearm narrower), by being an extremity linked to the torso,
    by their angle to the principal direction and by lying at the radial
    profile's head peak.
    """
    P = kp.positions
    y_top, y_bot = P[:, 1].min(), P[:, 1].max()
    span = max(y_bot - y_top, 1e-6)
    up = np.asarray(principal, float)
    if up[1] > 0:
        up = -up
    cx = _body_centre_x(grid) if grid is not None else float(centroid[0])
    cands = []
    for j in range(len(P)):
        if P[j, 1] > y_top + config.head_top_fraction * span:
            continue
        v = P[j] - centroid
        ang = np.degrees(np.arccos(np.clip(v @ up / max(np.linalg.norm(v), 1e-9), -1, 1)))
        score = (1.0 - (P[j, 1] - y_top) / span) + 0.3 * np.cos(np.radians(min(ang, 90.0)))
        score -= abs(P[j, 0] - cx) / 0.15
        if kp.classes[j] == EXTREMITY:
            score += 0.3
        hops = _hops(kp.adjacency, j, 3)
        if np.any((kp.classes == TORSO_CLASS) & (hops <= 3)) or len(P) <= 3:
            score += 0.2
        if grid is not None:
            w = _run_width(grid, P[j])
            if 0.12 <= w <= 0.26:
                score += 0.5
            elif w < 0.12:
                score -= 0.5
        cands.append(HeadCandidate(j, P[j].copy(), float(score)))
    if profile is not None and profile.head is not None:
        q = profile.points[profile.head]
        for i, c in enumerate(cands):
            if np.linalg.norm(c.position[:2] - q[:2]) < 0.15:
                cands[i] = HeadCandidate(c.index, c.position, c.score + 0.3)
    cands.sort(key=lambda c: -c.score)
    return cands[:config.max_head_candidates]


def estimate_stature(grid: OrusGrid, head_xy: np.ndarray, ground_y: float | None, cut_bottom: bool,
                     config: InitConfig = InitConfig()) -> float:
    """Stature from the top of the head down to the ground (or to the lowest point).

    A user cut by the image's lower border gets :attr:`InitConfig.default_stature_m`
    (the silhouette's breadth, quantised by the grid's bins, says too little); the
    segment lengths are refined while tracking.
    """
    ys = grid.bin_centres()
    filled = grid.filled
    near = filled & (np.abs(ys[..., 0] - head_xy[0]) < 0.2)
    if not near.any() or cut_bottom:
        return config.default_stature_m
    top = grid.mean[..., 1][near].min() - grid.bin_size / 2
    lo, hi = config.stature_range_m
    bottom = ground_y if ground_y is not None else grid.mean[..., 1][filled].max() + grid.bin_size / 2
    h = bottom - top
    if lo <= h <= hi:
        return float(h)
    if h > 0.5 * lo and ground_y is None:
        return float(np.clip(h, lo, hi))
    return config.default_stature_m


@dataclass(frozen=True)
class InitialPose:
    """One initial skeleton.

    Attributes
    ----------
    X : ndarray of shape (13, 3)
        View frame.
    dims : BodyDimensions
    head : HeadCandidate
    limbs : dict
        Key point (or ``None``) assigned to ``l_hand``, ``r_hand``, ``l_foot``, ``r_foot``.
    score : float
        Back-tracking score of the limb assignment.
    """

    X: np.ndarray
    dims: BodyDimensions
    head: HeadCandidate
    limbs: dict = field(default_factory=dict)
    score: float = 0.0


def _surface_z(grid: OrusGrid, xy: np.ndarray, default: float) -> float:
    b = np.floor((np.asarray(xy)[:2] - grid.origin) / grid.bin_size).astype(int)
    ny, nx = grid.shape
    i0, i1 = max(b[1] - 1, 0), min(b[1] + 2, ny)
    j0, j1 = max(b[0] - 1, 0), min(b[0] + 2, nx)
    z = grid.zmin[i0:i1, j0:j1]
    z = z[np.isfinite(z)]
    return float(z.min()) if len(z) else default


def _template(dims: BodyDimensions, head: np.ndarray, up: np.ndarray, lateral: np.ndarray,
              torso_depth: float) -> np.ndarray:
    """The median standing pose scaled to ``dims``, its head at ``head``, in the view frame."""
    R = rest_pose13(dims.stature)          # world: z up, facing +y, left at -x
    R = R - R[HEAD]
    fwd = np.cross(lateral, up)            # towards the camera when lateral points to the person's left
    # world x (person's right) -> -lateral, world y (forward) -> fwd, world z (up) -> up
    M = np.stack([-lateral, fwd, up], axis=1)
    X = head + R @ M.T
    X[:, 2] = np.where(np.arange(13) == HEAD, X[:, 2], X[:, 2] - X[HEAD, 2] + torso_depth)
    return X


def initial_poses(grid: OrusGrid, kp: KeyPoints, heads: list, centroid: np.ndarray, principal: np.ndarray,
                  ground_y: float | None, cut_bottom: bool, config: InitConfig = InitConfig()) -> list:
    """One initial pose per head candidate (see the module docstring)."""
    poses = []
    up = np.array([0.0, -1.0, 0.0])
    pa = np.asarray(principal, float)
    if pa[1] > 0:
        pa = -pa
    for hc in heads:
        # up: the principal direction when the user is elongated, else vertical
        # the user is assumed standing (source 001): the torso's up is gravity's, the
        # local fit then finds any lean
        u = up
        lateral = np.cross([0.0, 0.0, 1.0], u)       # view +x-ish: the person's left when facing the camera
        lateral /= np.linalg.norm(lateral)
        H = estimate_stature(grid, hc.position, ground_y, cut_bottom, config)
        dims = BodyDimensions.from_stature(H)
        s = dims.scale
        head = hc.position.copy()
        head[2] = _surface_z(grid, head, head[2]) + dims.radius("head")
        chest_xy = head[:2] - u[:2] * 0.3 * s
        torso_depth = _surface_z(grid, chest_xy, head[2]) + dims.radius("torso_half_depth")[0]
        X = _template(dims, head, u, lateral, torso_depth)
        X[HEAD, 2] = head[2]
        for limbs, score in _assign_limbs(X, kp, hc.index, dims, config, config.limb_assignments):
            poses.append(InitialPose(_place_limbs(X, limbs, kp, dims, grid, u, lateral), dims, hc, limbs, score))
    return poses


_LIMB_SLOTS = (("l_hand", L_SHOULDER, L_ELBOW, L_HAND, 1.0), ("r_hand", R_SHOULDER, R_ELBOW, R_HAND, -1.0),
               ("l_foot", L_HIP, L_KNEE, L_FOOT, 1.0), ("r_foot", R_HIP, R_KNEE, R_FOOT, -1.0))


def _assign_limbs(X: np.ndarray, kp: KeyPoints, head_index: int, dims: BodyDimensions, config: InitConfig,
                  n_best: int = 3) -> list:
    """Depth-first search of extremity-to-limb assignments under reach and side constraints.

    Returns
    -------
    list of (dict, float)
        The ``n_best`` assignments (limb name -> key point or None) and their scores, best first.
    """
    P = kp.positions
    head_r = 2.5 * dims.radius("head")     # key points this close to the head belong to it
    ext = [j for j in range(len(P)) if kp.classes[j] == EXTREMITY and j != head_index
           and np.linalg.norm((P[j] - X[HEAD])[:2]) > head_r]
    slack = 1.0 + config.reach_slack
    reach = {"hand": (dims.length(L_SHOULDER, L_ELBOW) + dims.length(L_ELBOW, L_HAND)) * slack,
             "foot": (dims.length(L_HIP, L_KNEE) + dims.length(L_KNEE, L_FOOT)) * slack}
    mid_x = 0.5 * (X[L_SHOULDER, 0] + X[R_SHOULDER, 0])
    hip_y = 0.5 * (X[L_HIP, 1] + X[R_HIP, 1])
    options = []
    for name, base, _, _, side in _LIMB_SLOTS:
        kind = name.split("_")[1]
        opts = [None]
        for j in ext:
            d = np.linalg.norm((P[j] - X[base])[:2])
            if d > reach[kind]:
                continue
            if kind == "foot" and P[j, 1] < hip_y + 0.15:
                continue
            if kind == "hand" and P[j, 1] > hip_y + 0.45 * dims.stature / 1.75:
                continue
            opts.append(j)
        options.append(opts)
    other = {L_SHOULDER: R_SHOULDER, R_SHOULDER: L_SHOULDER, L_HIP: R_HIP, R_HIP: L_HIP}
    best: list = []          # the n_best (score, choice), best first

    def score_of(choice):
        sc = 0.0
        for (name, base, _, _, side), j in zip(_LIMB_SLOTS, choice):
            if j is None:
                continue
            sc += 1.0
            sc += 0.3 * np.tanh(side * (P[j, 0] - mid_x) / 0.1)      # on the expected side
            d_own = np.linalg.norm(P[j] - X[base])
            d_other = np.linalg.norm(P[j] - X[other[base]])
            sc -= 0.5 * max(0.0, d_own - d_other) / 0.1                 # crossing over is unlikely
            sc -= 0.2 * np.linalg.norm((P[j] - X[base])[:2])           # nearer is likelier
        return sc

    def dfs(i, used, choice):
        if i == len(_LIMB_SLOTS):
            sc = score_of(choice)
            if len(best) < n_best or sc > best[-1][0]:
                best.append((sc, list(choice)))
                best.sort(key=lambda b: -b[0])
                del best[n_best:]
            return
        # upper bound: every remaining slot could add at most 1.3
        if len(best) == n_best and score_of(choice) + 1.3 * (len(_LIMB_SLOTS) - i) <= best[-1][0]:
            return
        for j in options[i]:
            if j is not None and j in used:
                continue
            choice.append(j)
            dfs(i + 1, used | ({j} if j is not None else set()), choice)
            choice.pop()

    dfs(0, frozenset(), [])
    if not best:
        best = [(0.0, [None] * len(_LIMB_SLOTS))]
    return [({slot[0]: j for slot, j in zip(_LIMB_SLOTS, ch)}, float(sc)) for sc, ch in best]


def _place_limbs(X: np.ndarray, limbs: dict, kp: KeyPoints, dims: BodyDimensions, grid: OrusGrid,
                 up: np.ndarray, lateral: np.ndarray) -> np.ndarray:
    Y = X.copy()
    fwd = np.cross(lateral, up)
    for name, base, mid, end, side in _LIMB_SLOTS:
        j = limbs.get(name)
        if j is None:
            continue
        kind = name.split("_")[1]
        tip = kp.positions[j].copy()
        l1 = dims.length(base, mid)
        l2 = dims.length(mid, end)
        # the extremity key point sits on the hand / foot; its centre is a little deeper
        tip[2] = _surface_z(grid, tip, tip[2]) + dims.radius(kind) * 0.5
        pole = (-up + side * 0.5 * lateral - 0.3 * fwd) if kind == "hand" else (fwd + 0.2 * side * lateral)
        m_, e_, _ = two_bone_ik(Y[base][None], tip[None], l1, l2, pole)
        Y[mid], Y[end] = m_[0], e_[0]
    return Y
