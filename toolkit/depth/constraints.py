"""Constraints of the 13-point skeleton (source 001, step 230).

* **Topological**: the torso patch of four points (shoulders and hips) stays a
  flat, untwisted quadrilateral (equal diagonals, shoulder line parallel to the
  hip line within ``twist_sigma_rad``); the neck triangle (head and both
  shoulders) is isosceles with the head above the middle of the shoulders;
  the legs do not cross (each knee and foot stays on its side of the other
  along the hip line, within ``crossing_margin_m``).
* **Geometric**: each :data:`~toolkit.body.control_points.LENGTH_PAIRS` distance near
  its expected length (soft, ``length_sigma_m``) and inside its anthropometric
  bounds (hard, :func:`enforce_lengths`); the expected lengths are refined over
  time by a running average of reliable frames (:class:`LengthEstimator`).
* **Velocity**: a control point moving faster than ``max_speed_m_s`` (or slower
  than ``min_speed_m_s``) did not move: it keeps its previous position
  (:func:`enforce_velocity`).
* **Collision**: limb segments never pass through each other: the distance
  between the axes of the pairs in :data:`COLLISION_PAIRS` stays above
  ``(1 - collision_margin)`` times the sum of their radii (soft residual, and
  :func:`enforce_collisions` puts a colliding segment back where it was).
* **Ground**: with a known ground plane no control point goes below it.

Soft constraints are residual blocks (``constraint_residuals``) stacked into the
fitting energy; hard ones are applied after each fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.body.control_points import (
    HEAD,
    L_ELBOW,
    L_FOOT,
    L_HAND,
    L_HIP,
    L_KNEE,
    L_SHOULDER,
    LENGTH_BOUNDS,
    LENGTH_PAIRS,
    LIMBS,
    N_POINTS,
    R_ELBOW,
    R_FOOT,
    R_HAND,
    R_HIP,
    R_KNEE,
    R_SHOULDER,
    BodyDimensions,
)

__all__ = [
    "COLLISION_PAIRS",
    "JOINT_LIMITS_DEG",
    "ConstraintConfig",
    "LengthEstimator",
    "constraint_residuals",
    "constraint_violations",
    "enforce_collisions",
    "enforce_joint_limits",
    "enforce_lengths",
    "enforce_velocity",
    "segment_distance",
    "segment_distances",
]

#: Pairs of limb segments (indices into LIMBS) that must not intersect.
COLLISION_PAIRS = ((2, 3), (0, 1), (4, 5), (6, 7), (2, 4), (3, 5))
#: Smallest interior angle (degrees) at the elbows and knees (full flexion limits).
JOINT_LIMITS_DEG = {"elbow": 25.0, "knee": 30.0}
_ELBOW_CHAINS = ((L_SHOULDER, L_ELBOW, L_HAND), (R_SHOULDER, R_ELBOW, R_HAND))
_KNEE_CHAINS = ((L_HIP, L_KNEE, L_FOOT), (R_HIP, R_KNEE, R_FOOT))
_JL_A, _JL_B, _JL_C = (np.array(v) for v in zip(*(_ELBOW_CHAINS + _KNEE_CHAINS)))


@dataclass(frozen=True)
class ConstraintConfig:
    """Weights and limits of the constraints.

    Attributes
    ----------
    length_sigma_m : float
        Soft tolerance of the segment lengths.
    topology_sigma_m : float
        Tolerance of the torso-patch and neck-triangle distances.
    twist_sigma_rad : float
        Tolerance of the angle between the shoulder and hip lines.
    collision_sigma_m : float
        Tolerance of a segment penetration.
    ground_sigma_m : float
    min_speed_m_s, max_speed_m_s : float
        Allowed speed range of a control point.
    collision_margin : float
        Fraction of the radii sum two limb axes may come closer than (soft flesh, and the
        capsules' mean radii overstate the thin ends); closer is a collision.
    crossing_margin_m : float
        How far a knee or foot may cross over to the other side (along the hip line) before
        the topological no-crossing residual acts.
    """

    length_sigma_m: float = 0.015
    topology_sigma_m: float = 0.02
    twist_sigma_rad: float = 0.25
    collision_sigma_m: float = 0.01
    ground_sigma_m: float = 0.01
    min_speed_m_s: float = 0.0
    max_speed_m_s: float = 8.0
    collision_margin: float = 0.5
    crossing_margin_m: float = 0.05


def _unit(v):
    n = float(np.sqrt(v @ v))
    return (v / n if n > 1e-12 else v * 0.0), max(n, 1e-12)


def segment_distances(P0, P1, Q0, Q1):
    """Closest distances between segments ``[P0, P1]`` and ``[Q0, Q1]`` (arrays (n, 3)), vectorised.

    Returns
    -------
    d : ndarray of shape (n,)
    s, t : ndarray of shape (n,)
        Parameters of the closest points ``P0 + s (P1 - P0)`` and ``Q0 + t (Q1 - Q0)``.
    """
    d1 = P1 - P0
    d2 = Q1 - Q0
    r = P0 - Q0
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    a_ = np.maximum(a, 1e-12)
    e_ = np.maximum(e, 1e-12)
    den = a * e - b * b
    s = np.where(den > 1e-12, np.clip((b * f - c * e) / np.maximum(den, 1e-12), 0, 1), 0.0)
    t = (b * s + f) / e_
    s = np.where(t < 0, np.clip(-c / a_, 0, 1), np.where(t > 1, np.clip((b - c) / a_, 0, 1), s))
    t = np.clip(t, 0, 1)
    C1 = P0 + d1 * s[:, None]
    C2 = Q0 + d2 * t[:, None]
    return np.linalg.norm(C1 - C2, axis=1), s, t


def segment_distance(p0, p1, q0, q1):
    """Closest distance between segments [p0, p1] and [q0, q1], with the parameters s, t of the closest points."""
    d, s, t = segment_distances(*(np.asarray(v, float)[None] for v in (p0, p1, q0, q1)))
    return float(d[0]), float(s[0]), float(t[0])


def _limb_radii(dims: BodyDimensions) -> np.ndarray:
    return dims.limb_radii.mean(1)


_LA = np.array([a for a, _ in LENGTH_PAIRS])
_LB = np.array([b for _, b in LENGTH_PAIRS])
_CP = np.array([[LIMBS[i][1], LIMBS[i][2], LIMBS[j][1], LIMBS[j][2]] for i, j in COLLISION_PAIRS])
_CI = np.array([i for i, _ in COLLISION_PAIRS])
_CJ = np.array([j for _, j in COLLISION_PAIRS])
_EYE3 = np.eye(3)


def constraint_residuals(X: np.ndarray, dims: BodyDimensions, config: ConstraintConfig, ground_y=None) -> list:
    """Soft constraint residual blocks at ``X`` (13, 3).

    Returns
    -------
    list of (r, J)
        ``length``, ``topology``, ``collision``, ``ground`` blocks; ``r`` (n,),
        ``J`` (n, 13, 3).  Block sizes do not depend on ``X``.
    """
    out = []
    # geometric: lengths
    w = 1.0 / config.length_sigma_m
    D = X[_LA] - X[_LB]
    n = np.maximum(np.linalg.norm(D, axis=1), 1e-12)
    E = D / n[:, None]
    nL = len(_LA)
    Jl = np.zeros((nL, N_POINTS, 3))
    k = np.arange(nL)
    Jl[k, _LA] = w * E
    Jl[k, _LB] = -w * E
    out.append((w * (n - dims.lengths), Jl))
    # topological: torso patch (equal diagonals, shoulder line parallel to hip line) and neck triangle
    wt = 1.0 / config.topology_sigma_m
    rt = np.zeros(8)
    Jt = np.zeros((8, N_POINTS, 3))
    e1, n1 = _unit(X[L_SHOULDER] - X[R_HIP])
    e2, n2 = _unit(X[R_SHOULDER] - X[L_HIP])
    rt[0] = wt * (n1 - n2)
    Jt[0, L_SHOULDER], Jt[0, R_HIP], Jt[0, R_SHOULDER], Jt[0, L_HIP] = wt * e1, -wt * e1, -wt * e2, wt * e2
    e1, n1 = _unit(X[HEAD] - X[L_SHOULDER])
    e2, n2 = _unit(X[HEAD] - X[R_SHOULDER])
    rt[1] = wt * (n1 - n2)
    Jt[1, HEAD] = wt * (e1 - e2)
    Jt[1, L_SHOULDER], Jt[1, R_SHOULDER] = -wt * e1, wt * e2
    es, ns = _unit(X[R_SHOULDER] - X[L_SHOULDER])
    h = X[HEAD] - 0.5 * (X[L_SHOULDER] + X[R_SHOULDER])
    Ps = (_EYE3 - es[:, None] * es[None, :]) / ns
    rt[2] = wt * (h @ es)
    Jt[2, HEAD] = wt * es
    Jt[2, L_SHOULDER] = wt * (-0.5 * es - Ps @ h)
    Jt[2, R_SHOULDER] = wt * (-0.5 * es + Ps @ h)
    eh, nh = _unit(X[R_HIP] - X[L_HIP])
    wp = 1.0 / config.twist_sigma_rad
    Ph = (_EYE3 - eh[:, None] * eh[None, :]) / nh
    rt[3:6] = wp * (es - eh)
    Jt[3:6, R_SHOULDER] = wp * Ps
    Jt[3:6, L_SHOULDER] = -wp * Ps
    Jt[3:6, R_HIP] = -wp * Ph
    Jt[3:6, L_HIP] = wp * Ph
    # legs do not cross: the right knee and foot stay on the right of the left ones (along the hip line)
    for row, (lj, rj) in zip((6, 7), ((L_KNEE, R_KNEE), (L_FOOT, R_FOOT))):
        sep = (X[rj] - X[lj]) @ eh
        if sep < -config.crossing_margin_m:
            rt[row] = wt * (-config.crossing_margin_m - sep)
            Jt[row, rj] = -wt * eh
            Jt[row, lj] = wt * eh
    out.append((rt, Jt))
    # collisions
    wc = 1.0 / config.collision_sigma_m
    rad = _limb_radii(dims)
    P = X[_CP]                                            # (n_pairs, 4, 3)
    d, s, t = segment_distances(P[:, 0], P[:, 1], P[:, 2], P[:, 3])
    need = (rad[_CI] + rad[_CJ]) * (1.0 - config.collision_margin)
    act = d < need
    nc = len(_CP)
    Jc = np.zeros((nc, N_POINTS, 3))
    rc = np.where(act, wc * (need - d), 0.0)
    if act.any():
        C1 = P[:, 0] + s[:, None] * (P[:, 1] - P[:, 0])
        C2 = P[:, 2] + t[:, None] * (P[:, 3] - P[:, 2])
        nv = C1 - C2
        nv = nv / np.maximum(np.linalg.norm(nv, axis=1), 1e-12)[:, None]
        for q in np.nonzero(act)[0]:
            a0, a1, b0, b1 = _CP[q]
            Jc[q, a0] += -wc * (1 - s[q]) * nv[q]
            Jc[q, a1] += -wc * s[q] * nv[q]
            Jc[q, b0] += wc * (1 - t[q]) * nv[q]
            Jc[q, b1] += wc * t[q] * nv[q]
    out.append((rc, Jc))
    # ground (view frame y is down; the ground is y = ground_y)
    wg = 1.0 / config.ground_sigma_m
    rg = np.zeros(N_POINTS)
    Jg = np.zeros((N_POINTS, N_POINTS, 3))
    if ground_y is not None:
        lim = ground_y - 0.02 * dims.scale
        below = np.nonzero(X[:, 1] > lim)[0]
        rg[below] = wg * (X[below, 1] - lim)
        Jg[below, below, 1] = wg
    out.append((rg, Jg))
    return out


# ------------------------------------------------------------ hard checks
def enforce_lengths(X: np.ndarray, bounds: np.ndarray = LENGTH_BOUNDS) -> np.ndarray:
    """Move distal points so that every bone length lies within its (min, max) bounds.

    Bones are processed from the torso outwards; the torso pairs (shoulder
    width, hip width, shoulder-hip) move both ends symmetrically.

    Parameters
    ----------
    X : ndarray of shape (13, 3)
    bounds : ndarray of shape (14, 2)

    Returns
    -------
    ndarray of shape (13, 3)
    """
    Y = np.array(X, float)
    L = np.sqrt(np.einsum("ij,ij->i", Y[_LA] - Y[_LB], Y[_LA] - Y[_LB]))
    if np.all((L >= bounds[:, 0]) & (L <= bounds[:, 1])):
        return Y
    order = [12, 13, 6, 7, 0, 1, 2, 3, 4, 5, 8, 9, 10, 11]  # torso first, then limbs outwards
    sym = {12, 13, 6, 7}
    for k in order:
        a, b = LENGTH_PAIRS[k]
        lo, hi = bounds[k]
        d = Y[b] - Y[a]
        n = np.linalg.norm(d)
        if n < 1e-9:
            continue
        target = np.clip(n, lo, hi)
        if target == n:
            continue
        delta = (target - n) * d / n
        if k in sym:
            Y[a] -= 0.5 * delta
            Y[b] += 0.5 * delta
        elif a == HEAD:
            Y[HEAD] -= delta
        else:
            # move the distal point and everything beyond it
            Y[_descendants(b)] += delta
    return Y


def _descendants(j: int) -> list[int]:
    from toolkit.skeleton import SKELETON_13

    out = [j]
    stack = [j]
    while stack:
        k = stack.pop()
        for c in SKELETON_13.children(k):
            if c not in out:
                out.append(c)
                stack.append(c)
    return out


def enforce_velocity(X: np.ndarray, X_prev: np.ndarray | None, dt: float, config: ConstraintConfig):
    """Keep points whose speed is outside the allowed range at their previous position.

    Returns
    -------
    X : ndarray of shape (13, 3)
    frozen : ndarray of shape (13,), bool
        Points that were reset.
    """
    Y = np.array(X, float)
    if X_prev is None or dt <= 0:
        return Y, np.zeros(N_POINTS, bool)
    P = np.asarray(X_prev, float)
    speed = np.linalg.norm(Y - P, axis=1) / dt
    bad = np.isfinite(speed) & ((speed > config.max_speed_m_s) | (speed < config.min_speed_m_s))
    Y[bad] = P[bad]
    return Y, bad


def enforce_collisions(X: np.ndarray, X_prev: np.ndarray | None, dims: BodyDimensions, config: ConstraintConfig):
    """Put back a segment that passes through another one.

    For every colliding pair of :data:`COLLISION_PAIRS` (axes closer than
    ``(1 - collision_margin)`` times the sum of their radii), the distal point
    of the segment that moved most since ``X_prev`` returns to its previous
    position (the source's "freeze at the last acceptable position"); without
    a previous skeleton the two segments are pushed apart.

    Returns
    -------
    X : ndarray of shape (13, 3)
    n_fixed : int
    """
    Y = np.array(X, float)
    rad = _limb_radii(dims)
    fixed = 0
    P = Y[_CP]
    d, _, _ = segment_distances(P[:, 0], P[:, 1], P[:, 2], P[:, 3])
    if np.all(d >= (rad[_CI] + rad[_CJ]) * (1 - config.collision_margin)):
        return Y, 0
    for _ in range(3):
        changed = False
        for i, j in COLLISION_PAIRS:
            _, a0, a1, _ = LIMBS[i]
            _, b0, b1, _ = LIMBS[j]
            d, s, t = segment_distance(Y[a0], Y[a1], Y[b0], Y[b1])
            need = (rad[i] + rad[j]) * (1 - config.collision_margin)
            if d >= need:
                continue
            changed = True
            fixed += 1
            if X_prev is not None:
                P = np.asarray(X_prev, float)
                dp, _, _ = segment_distance(P[a0], P[a1], P[b0], P[b1])
                mi = np.linalg.norm(Y[a1] - P[a1])
                mj = np.linalg.norm(Y[b1] - P[b1])
                k = a1 if mi >= mj else b1
                if dp >= need:
                    Y[k] = P[k]
                    continue
            c1 = Y[a0] + s * (Y[a1] - Y[a0])
            c2 = Y[b0] + t * (Y[b1] - Y[b0])
            n = c1 - c2
            nn = np.linalg.norm(n)
            n = n / nn if nn > 1e-9 else np.array([1.0, 0.0, 0.0])
            push = 0.5 * (need - d + 1e-3)
            Y[a1] += push * n
            Y[b1] -= push * n
        if not changed:
            break
    return Y, fixed


def _interior_angle(a, b, c):
    u = a - b
    v = c - b
    cosang = u @ v / max(np.linalg.norm(u) * np.linalg.norm(v), 1e-12)
    return np.degrees(np.arccos(np.clip(cosang, -1, 1)))


def enforce_joint_limits(X: np.ndarray, limits: dict = JOINT_LIMITS_DEG) -> tuple[np.ndarray, int]:
    """Open elbows and knees folded beyond their limits (rotating the distal point in the limb plane).

    Returns
    -------
    X : ndarray of shape (13, 3)
    n_fixed : int
    """
    Y = np.array(X, float)
    fixed = 0
    u = Y[_JL_A] - Y[_JL_B]
    v = Y[_JL_C] - Y[_JL_B]
    cosang = np.einsum("ij,ij->i", u, v) / np.maximum(np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1), 1e-12)
    lims = np.array([limits["elbow"]] * 2 + [limits["knee"]] * 2)
    if np.all(np.degrees(np.arccos(np.clip(cosang, -1, 1))) >= lims):
        return Y, 0
    for chains, lim in ((_ELBOW_CHAINS, limits["elbow"]), (_KNEE_CHAINS, limits["knee"])):
        for a, b, c in chains:
            ang = _interior_angle(Y[a], Y[b], Y[c])
            if ang >= lim:
                continue
            u = Y[a] - Y[b]
            v = Y[c] - Y[b]
            lu, lv = np.linalg.norm(u), np.linalg.norm(v)
            if lu < 1e-9 or lv < 1e-9:
                continue
            u /= lu
            w = v / lv - (v / lv @ u) * u
            if np.linalg.norm(w) < 1e-9:
                w = np.cross(u, [0.0, 0.0, 1.0])
                if np.linalg.norm(w) < 1e-9:
                    w = np.cross(u, [1.0, 0.0, 0.0])
            w /= np.linalg.norm(w)
            th = np.radians(lim)
            Y[c] = Y[b] + lv * (np.cos(th) * u + np.sin(th) * w)
            fixed += 1
    return Y, fixed


def constraint_violations(X: np.ndarray, dims: BodyDimensions, config: ConstraintConfig,
                          bounds: np.ndarray = LENGTH_BOUNDS, X_prev=None, dt: float = 0.0) -> dict:
    """Counts of violated hard constraints of a skeleton (for tests and reports)."""
    Y = np.asarray(X, float)
    L = np.array([np.linalg.norm(Y[a] - Y[b]) for a, b in LENGTH_PAIRS])
    rad = _limb_radii(dims)
    col = 0
    for i, j in COLLISION_PAIRS:
        _, a0, a1, _ = LIMBS[i]
        _, b0, b1, _ = LIMBS[j]
        d, _, _ = segment_distance(Y[a0], Y[a1], Y[b0], Y[b1])
        col += d < (rad[i] + rad[j]) * (1 - config.collision_margin) - 1e-9
    ang = 0
    for chains, lim in ((_ELBOW_CHAINS, JOINT_LIMITS_DEG["elbow"]), (_KNEE_CHAINS, JOINT_LIMITS_DEG["knee"])):
        for a, b, c in chains:
            ang += _interior_angle(Y[a], Y[b], Y[c]) < lim - 1e-6
    vel = 0
    if X_prev is not None and dt > 0:
        sp = np.linalg.norm(Y - np.asarray(X_prev), axis=1) / dt
        vel = int(np.sum(sp > config.max_speed_m_s + 1e-9))
    return {"length": int(np.sum((L < bounds[:, 0] - 1e-9) | (L > bounds[:, 1] + 1e-9))),
            "collision": int(col), "joint_limit": int(ang), "velocity": vel}


class LengthEstimator:
    """Segment lengths refined over time by averaging reliable measurements (source 001).

    Parameters
    ----------
    dims : BodyDimensions
        Initial lengths (from stature).
    prior_weight : float
        Weight of the initial lengths, in frames.
    max_weight : float
        The running average forgets beyond this many frames.
    """

    def __init__(self, dims: BodyDimensions, prior_weight: float = 5.0, max_weight: float = 200.0):
        self.prior = dims.lengths.copy()
        self.mean = dims.lengths.copy()
        self.weight = np.full(len(self.mean), float(prior_weight))
        self.max_weight = float(max_weight)

    def update(self, X: np.ndarray, reliable: np.ndarray) -> np.ndarray:
        """Add the lengths of ``X`` for the pairs flagged ``reliable`` (14,); returns the current estimate."""
        Y = np.asarray(X, float)
        L = np.array([np.linalg.norm(Y[a] - Y[b]) for a, b in LENGTH_PAIRS])
        ok = np.asarray(reliable, bool) & np.isfinite(L)
        ok &= (L >= LENGTH_BOUNDS[:, 0]) & (L <= LENGTH_BOUNDS[:, 1])
        w = self.weight[ok]
        self.mean[ok] = (self.mean[ok] * w + L[ok]) / (w + 1)
        self.weight[ok] = np.minimum(w + 1, self.max_weight)
        # keep left and right equal (symmetric bones)
        for i in range(0, 12, 2):
            m = 0.5 * (self.mean[i] + self.mean[i + 1])
            self.mean[i] = self.mean[i + 1] = m
        return self.mean.copy()
