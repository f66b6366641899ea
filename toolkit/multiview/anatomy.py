"""Which way round a 3D skeleton's left/right labels are, from how its limbs bend.

Rays cannot tell a combination from its mirror (every view's left and right
exchanged): both give the same points with the labels swapped.  Anatomy can:
relative to the facing direction implied by the labels (left minus right,
crossed with up), knees bend forward and elbows backward.  With swapped labels
the facing direction turns round and both signs flip.  A straight-limbed pose
gives no information (score near zero).
"""

from __future__ import annotations

import numpy as np

from toolkit.skeleton import SKELETON_14, Skeleton

#: (proximal, middle, distal, sign): the middle joint lies on the ``sign`` side of the
#: proximal-distal line, along the facing direction (knees forward, elbows backward).
LIMB_BENDS = (("hip", "knee", "ankle", 1.0), ("shoulder", "elbow", "wrist", -1.0))


def facing_direction(joints3d: np.ndarray, skeleton: Skeleton = SKELETON_14, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Unit horizontal facing direction implied by the labels, (3,); NaN when undefined.

    ``(left - right) x up`` summed over hips and shoulders (a person facing +y with z up
    has left at -x: ``-x cross z = +y``).
    """
    X = np.asarray(joints3d, float)
    u = np.asarray(up, float) / np.linalg.norm(up)
    lr = np.zeros(3)
    for part in ("hip", "shoulder"):
        d = X[skeleton.index("l_" + part)] - X[skeleton.index("r_" + part)]
        if np.isfinite(d).all():
            lr += d
    f = np.cross(lr, u)
    f -= (f @ u) * u
    n = np.linalg.norm(f)
    return f / n if n > 1e-9 else np.full(3, np.nan)


def chirality_score(joints3d: np.ndarray, skeleton: Skeleton = SKELETON_14, up=(0.0, 0.0, 1.0)) -> float:
    """How well the limb bends agree with the labels' facing direction, metres.

    Parameters
    ----------
    joints3d : ndarray of shape (n_joints, 3)
    skeleton : Skeleton
        Needs ``l_``/``r_`` hips, knees, ankles, shoulders, elbows, wrists.
    up : array_like of shape (3,)
        World up.

    Returns
    -------
    float
        Sum over the four limbs of the middle joint's offset from its limb's line along
        the facing direction (signed: knees forward, elbows backward count positive).
        Positive: the labels are anatomically the right way round; negative: mirrored;
        near 0: straight limbs, undecided.  0 when the facing direction is undefined.
    """
    X = np.asarray(joints3d, float)
    f = facing_direction(X, skeleton, up)
    if not np.isfinite(f).all():
        return 0.0
    score = 0.0
    for a, b, c, sign in LIMB_BENDS:
        for side in ("l_", "r_"):
            pa, pb, pc = (X[skeleton.index(side + n)] for n in (a, b, c))
            if not (np.isfinite(pa).all() and np.isfinite(pb).all() and np.isfinite(pc).all()):
                continue
            axis = pc - pa
            L = np.linalg.norm(axis)
            if L < 1e-9:
                continue
            axis /= L
            off = (pb - pa) - ((pb - pa) @ axis) * axis
            score += sign * float(off @ f)
    return score
