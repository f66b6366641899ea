"""Guided configuration changes of the global minimisation (source 001, step 230).

Each move looks for a known pattern in the current state and proposes skeletons
as its predefined response; :class:`toolkit.depth.fit.GlobalSearch` minimises
them locally and keeps the lowest energy.

=================  ===========================================================
move               pattern -> response
=================  ===========================================================
``limb_to_peak``   an extremity of the radial profile no hand or foot is near
                   -> the nearest arm or leg reaches for it (two-bone IK)
``limb_to_data``   a patch of grid bins no primitive explains -> the arm or
                   leg that reaches it best is laid along it
``take_over``      a hand (foot) no data support while the other one sits on data
                   nearer the first one's shoulder (hip) -> the first limb takes
                   those data over, the other one hangs
``swap_hands``     always -> the two forearms exchanged (arms crossed or not)
``swap_legs``      always -> the two shanks exchanged
``mirror``         always -> left and right exchanged (the user turned round)
``arm_down``       a hand no data support -> that arm hangs beside the torso
``head_to_peak``   the head peak of the profile away from the head -> head moved there
``reinit``         always -> the initial-pose search from scratch
=================  ===========================================================
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.pointcloud.cloud import principal_direction
from toolkit.depth.fit import Move
from toolkit.depth.init import head_candidates, initial_poses, key_points
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
    mirror13,
)
from toolkit.motion.kinematics import two_bone_ik

__all__ = ["PEAK_EXPLAINED_M", "MoveContext", "default_moves"]

#: A profile peak with a hand, foot or head this close (in the grid plane) is explained, metres.
PEAK_EXPLAINED_M = 0.15
_CHAINS = {"l_arm": (L_SHOULDER, L_ELBOW, L_HAND), "r_arm": (R_SHOULDER, R_ELBOW, R_HAND),
           "l_leg": (L_HIP, L_KNEE, L_FOOT), "r_leg": (R_HIP, R_KNEE, R_FOOT)}


@dataclass
class MoveContext:
    """What a move may look at: the frame's radial profile, grid and data, the body, the tracker."""

    profile: object
    grid: object
    data: object
    dims: object
    frame: object
    predicted: np.ndarray
    tracker: object = None
    assignment: object = None
    data_index: np.ndarray | None = None


def _ik(X, chain, target, dims, pole):
    a, b, c = chain
    mid, end, _ = two_bone_ik(X[a][None], target[None], dims.length(a, b), dims.length(b, c), pole)
    Y = X.copy()
    Y[b], Y[c] = mid[0], end[0]
    return Y


def _reach(X, chain, tip, kind, dims, hand_pole):
    """Move a limb chain's end to ``tip`` by IK, bending the way it bends now.

    A straight limb has no bending direction; then ``hand_pole`` (arms) or
    backwards-down (legs) is used.
    """
    pole = X[chain[1]] - 0.5 * (X[chain[0]] + X[chain[2]])
    if np.linalg.norm(pole) < 1e-3:
        pole = np.array(hand_pole, float) if kind == "hand" else np.array([0.0, 0.0, -1.0])
    return _ik(X, chain, tip, dims, pole)


def _unexplained_peaks(X, ctx):
    prof = ctx.profile
    out = []
    ends = X[[HEAD, L_HAND, R_HAND, L_FOOT, R_FOOT]]
    for p in prof.peaks:
        q = prof.points[p]
        if np.min(np.linalg.norm(ends[:, :2] - q[:2], axis=1)) > PEAK_EXPLAINED_M:
            out.append(int(p))
    return out


def _limb_to_peak(X, ctx):
    cands = []
    prof = ctx.profile
    dims = ctx.dims
    for p in _unexplained_peaks(X, ctx)[:2]:
        q = prof.points[p].copy()
        inward = -prof.direction(p)
        best = None
        for name, chain in _CHAINS.items():
            kind = "hand" if "arm" in name else "foot"
            reach = dims.length(chain[0], chain[1]) + dims.length(chain[1], chain[2])
            tip = q + inward * dims.radius(kind)
            tip[2] = q[2] + dims.radius(kind) * 0.5
            d = np.linalg.norm(tip - X[chain[0]])
            if d > reach * 1.15:
                continue
            cost = np.linalg.norm(tip - X[chain[2]])
            if best is None or cost < best[0]:
                best = (cost, chain, tip, kind)
        if best is None:
            continue
        _, chain, tip, kind = best
        cands.append(_reach(X, chain, tip, kind, dims, hand_pole=(0.0, 1.0, 0.3)))
    return cands


def _unexplained_patches(ctx, min_bins: int = 3):
    """Connected patches of unexplained grid bins, largest first (lists of positions (k, 3))."""
    import cv2

    a = ctx.assignment
    if a is None or len(a.surface_prim) == 0:
        return []
    idx = ctx.data_index
    bad = a.surface_prim < 0
    if bad.sum() < min_bins:
        return []
    img = np.zeros(ctx.grid.shape, np.uint8)
    img[idx[bad, 0], idx[bad, 1]] = 1
    n, lab = cv2.connectedComponents(img, connectivity=8)
    out = []
    for k in range(1, n):
        sel = lab[idx[bad, 0], idx[bad, 1]] == k
        if sel.sum() >= min_bins:
            out.append(ctx.data.surface[bad][sel])
    out.sort(key=len, reverse=True)
    return out


def _limb_to_data(X, ctx):
    cands = []
    dims = ctx.dims
    for patch in _unexplained_patches(ctx)[:2]:
        best = None
        for name, chain in _CHAINS.items():
            kind = "hand" if "arm" in name else "foot"
            base = X[chain[0]]
            reach = dims.length(chain[0], chain[1]) + dims.length(chain[1], chain[2])
            d = np.linalg.norm(patch - base, axis=1)
            inreach = d <= reach * 1.1
            if not inreach.any():
                continue
            far = patch[inreach][np.argmax(d[inreach])]
            tip = far + (base - far) * min(dims.radius(kind) / max(np.linalg.norm(base - far), 1e-9), 0.5)
            tip[2] += dims.radius(kind) * 0.5
            cost = np.linalg.norm(tip - X[chain[2]]) - 0.5 * inreach.sum() * ctx.grid.bin_size
            if best is None or cost < best[0]:
                best = (cost, chain, tip, kind)
        if best is None:
            continue
        _, chain, tip, kind = best
        cands.append(_reach(X, chain, tip, kind, dims, hand_pole=(0.0, 0.3, 1.0)))
    return cands


def _supported(X, j, ctx, radius=0.12) -> bool:
    S = ctx.data.surface
    return bool(len(S)) and bool(np.min(np.linalg.norm(S - X[j], axis=1)) < radius)


def _hang(X, chain, ctx):
    a = chain[0]
    dims = ctx.dims
    down = 0.5 * (X[L_HIP] + X[R_HIP]) - 0.5 * (X[L_SHOULDER] + X[R_SHOULDER])
    down = down / max(np.linalg.norm(down), 1e-9)
    if chain[0] in (L_HIP, R_HIP):
        down = np.array([0.0, 1.0, 0.0])
    L = dims.length(chain[0], chain[1]) + dims.length(chain[1], chain[2])
    return _ik(X, chain, X[a] + 0.97 * L * down, dims, np.array([0.0, 0.0, 1.0]))


def _take_over(X, ctx):
    cands = []
    for ca, cb in ((_CHAINS["l_arm"], _CHAINS["r_arm"]), (_CHAINS["r_arm"], _CHAINS["l_arm"]),
                   (_CHAINS["l_leg"], _CHAINS["r_leg"]), (_CHAINS["r_leg"], _CHAINS["l_leg"])):
        ea, eb = ca[2], cb[2]
        if _supported(X, ea, ctx) or not _supported(X, eb, ctx):
            continue
        if np.linalg.norm(X[eb] - X[ca[0]]) >= np.linalg.norm(X[eb] - X[cb[0]]):
            continue
        Y = _hang(X, cb, ctx)
        pole = X[cb[1]] - 0.5 * (X[cb[0]] + X[cb[2]])
        cands.append(_ik(Y, ca, X[eb], ctx.dims, pole if np.linalg.norm(pole) > 1e-3 else np.array([0, 0.3, 1.0])))
    return cands


def _swap(X, pairs):
    Y = X.copy()
    for a, b in pairs:
        Y[a], Y[b] = X[b].copy(), X[a].copy()
    return Y


def _swap_hands(X, ctx):
    Y = _swap(X, [(L_ELBOW, R_ELBOW), (L_HAND, R_HAND)])
    return [Y]


def _swap_legs(X, ctx):
    return [_swap(X, [(L_KNEE, R_KNEE), (L_FOOT, R_FOOT)])]


def _mirror(X, ctx):
    return [mirror13(X)]


def _arm_down(X, ctx):
    tr = ctx.tracker
    if tr is None or tr.X is None:
        return []
    cands = []
    data = ctx.data
    for chain, sh_other in (((L_SHOULDER, L_ELBOW, L_HAND), R_SHOULDER), ((R_SHOULDER, R_ELBOW, R_HAND), L_SHOULDER)):
        hand = X[chain[2]]
        if len(data.surface) and np.min(np.linalg.norm(data.surface - hand, axis=1)) < 0.12:
            continue
        a = chain[0]
        out = X[a] - X[sh_other]
        out = out / max(np.linalg.norm(out), 1e-9)
        L = ctx.dims.length(chain[0], chain[1]) + ctx.dims.length(chain[1], chain[2])
        target = X[a] + 0.97 * L * np.array([0.0, 1.0, 0.0]) + 0.08 * out
        cands.append(_ik(X, chain, target, ctx.dims, np.array([0.0, 0.0, 1.0])))
    return cands


def _head_to_peak(X, ctx):
    prof = ctx.profile
    if prof.head is None:
        return []
    q = prof.points[prof.head]
    if np.linalg.norm(X[HEAD, :2] - q[:2]) < 2 * ctx.dims.radius("head"):
        return []
    Y = X.copy()
    inward = -prof.direction(prof.head)
    Y[HEAD, :2] = (q + inward * ctx.dims.radius("head"))[:2]
    return [Y]


def _reinit(X, ctx):
    """The initial-pose search on this frame, from a random clustering of the grid."""
    tr = ctx.tracker
    if tr is None:
        return []
    cfg = tr.config.init
    kp = key_points(ctx.grid, ctx.profile, tr.rng, cfg)
    pts = ctx.grid.mean[ctx.grid.filled]
    c, axes, _ = principal_direction(pts)
    heads = head_candidates(kp, c, axes[0], ctx.profile, cfg, ctx.grid)
    poses = initial_poses(ctx.grid, kp, heads[:1], c, axes[0], tr.ground_y, False, cfg)
    return [p.X.copy() for p in poses]


def default_moves() -> list:
    """The moves in their initial order (their records reorder them while tracking)."""
    return [Move("limb_to_data", _limb_to_data), Move("take_over", _take_over), Move("limb_to_peak", _limb_to_peak),
            Move("swap_hands", _swap_hands), Move("swap_legs", _swap_legs),
            Move("arm_down", _arm_down), Move("head_to_peak", _head_to_peak), Move("mirror", _mirror),
            Move("reinit", _reinit)]
