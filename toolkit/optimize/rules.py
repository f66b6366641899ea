"""The anthropometric rules that involve the moving joint (source 000 §3.2).

The source phrases every rule per joint: the joint on or above the ground,
its symmetric bones within 10 %, its adjacent bone lengths and its distances
to unconnected joints within the standards.  When the rest of a noisy initial
pose already breaks a rule that does not involve the joint (say, asymmetric
forearms while the head moves), ``AnthropometricConstraints.valid_positions``
rejects every candidate of every joint and the search cannot start; this
module checks only the rules in which the joint takes part.

It is :meth:`AnthropometricConstraints.valid_positions` with
``joint_rules_only=True``.
"""

from __future__ import annotations

import numpy as np

from toolkit.anthropometry import AnthropometricConstraints


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
    return cons.valid_positions(joints, joint, positions, joint_rules_only=True)
