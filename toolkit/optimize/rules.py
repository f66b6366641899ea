"""The anthropometric rules that involve the moving joint (source 000 §3.2).

The source phrases every rule per joint: the joint on or above the ground,
its symmetric bones within 10 %, its adjacent bone lengths and its distances
to unconnected joints within the standards.  When the rest of a noisy initial
pose already breaks a rule that does not involve the joint (say, asymmetric
forearms while the head moves), ``AnthropometricConstraints.valid_positions``
rejects every candidate of every joint and the search cannot start; this
module checks only the rules in which the joint takes part.

It reads the per-joint rule tables of
:class:`~toolkit.anthropometry.AnthropometricConstraints` (``_by_joint``,
``_c``), which have no public accessor yet.
"""

from __future__ import annotations

import numpy as np

from toolkit.anthropometry import AnthropometricConstraints
from toolkit.anthropometry.constraints import (ASYMMETRIC, BELOW_GROUND, BONE_LENGTH, JOINT_DISTANCE,
                                               NON_FINITE, OK, REASONS)
from toolkit.errors import check_shape


def joint_rule_reasons(cons: AnthropometricConstraints, joints: np.ndarray, joint: int,
                       positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Check candidate positions of one joint against the rules that involve it.

    Parameters
    ----------
    cons : AnthropometricConstraints
    joints : ndarray of shape (n_joints, 3)
        Current pose, metres (the entry at ``joint`` is ignored).
    joint : int
    positions : ndarray of shape (N, 3)
        Candidates, metres.

    Returns
    -------
    valid : ndarray of shape (N,), bool
    reasons : ndarray of shape (N,), int8
        First broken rule kind (:data:`~toolkit.anthropometry.constraints.REASONS`), 0 if none.
    """
    base = np.asarray(joints, float)
    check_shape("joints", base, (cons.skeleton.n_joints, 3))
    pos = np.asarray(positions, float)
    check_shape("positions", pos, (None, 3))
    touch, other, _, stouch, _ = cons._by_joint[joint]
    cc = cons._c
    m = np.zeros((pos.shape[0], len(REASONS)), bool)
    m[:, NON_FINITE] = ~np.isfinite(pos).all(axis=1)
    m[:, BELOW_GROUND] = pos[:, 2] < cc.floor[joint]
    if touch.size:
        d = np.linalg.norm(pos[:, None, :] - base[other][None], axis=-1)
        bad = (d < cc.pair_lo[touch]) | (d > cc.pair_hi[touch])
        codes = cc.pair_code[touch]
        m[:, BONE_LENGTH] = bad[:, codes == BONE_LENGTH].any(axis=1)
        m[:, JOINT_DISTANCE] = bad[:, codes == JOINT_DISTANCE].any(axis=1)
    for s in cc.sym[stouch]:
        ends = []
        for a, b in ((s[0], s[1]), (s[2], s[3])):
            pa = pos if a == joint else np.broadcast_to(base[a], pos.shape)
            pb = pos if b == joint else np.broadcast_to(base[b], pos.shape)
            ends.append(np.linalg.norm(pb - pa, axis=-1))
        m[:, ASYMMETRIC] |= np.maximum(*ends) > (1.0 + cons.symmetric_tolerance) * np.minimum(*ends)
    reasons = np.where(m.any(axis=1), m.argmax(axis=1), OK).astype(np.int8)
    return reasons == OK, reasons
