"""The 3D joint error every stage, run and benchmark reports: MPJPE, written once.

MPJPE (mean per-joint position error) is the mean Euclidean distance between
estimated and true joints over the joints (and frames) where both are known.
The aligned variant first removes each pose's mean translation: with
miscalibrated cameras the body's absolute position is set by the stage-1
offsets' gauge, which images cannot observe (docs/stage3_billboards.md).
"""

from __future__ import annotations

import numpy as np

from toolkit.errors import InputError


def _pair(joints, truth, where: str) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(joints, float)
    b = np.asarray(truth, float)
    if a.shape != b.shape or a.ndim < 2 or a.shape[-1] != 3:
        raise InputError(f"{where}: joints", f"shape {b.shape} (the ground truth's), (..., J, 3)", f"shape {a.shape}")
    return a, b


def joint_errors(joints, truth, *, aligned: bool = False) -> np.ndarray:
    """Distance of every joint to its true position, metres.

    Parameters
    ----------
    joints, truth : array_like of shape (..., J, 3)
        Metres, NaN = missing.
    aligned : bool
        Remove each pose's mean translation (over its joints known in both) first.

    Returns
    -------
    ndarray of shape (..., J)
        NaN where either joint is missing.

    Raises
    ------
    InputError
        The shapes differ or are not (..., J, 3).
    """
    a, b = _pair(joints, truth, "joint_errors")
    d = a - b
    if aligned:
        known = np.isfinite(d).all(axis=-1, keepdims=True)
        n = known.sum(axis=-2, keepdims=True)
        shift = np.where(known, d, 0.0).sum(axis=-2, keepdims=True) / np.maximum(n, 1)
        d = d - np.where(known.all(axis=-2, keepdims=True), d.mean(axis=-2, keepdims=True), shift)
    return np.linalg.norm(d, axis=-1)


def mpjpe(joints, truth, *, aligned: bool = False) -> float:
    """Mean per-joint position error, metres, over the joints known in both (NaN when none).

    Parameters
    ----------
    joints, truth : array_like of shape (..., J, 3)
        One pose (J, 3) or a sequence (T, J, 3), metres, NaN = missing.
    aligned : bool
        Remove each pose's mean translation first (:func:`joint_errors`).

    Returns
    -------
    float

    Raises
    ------
    InputError
        The shapes differ or are not (..., J, 3).
    """
    e = joint_errors(joints, truth, aligned=aligned)
    ok = np.isfinite(e)
    return float(e[ok].mean()) if ok.any() else float("nan")


def pose_errors(joints, truth) -> dict:
    """MPJPE of a sequence and how many frames have an estimate, for a run's ``metrics.json``.

    Parameters
    ----------
    joints, truth : array_like of shape (T, J, 3)
        Metres, NaN = missing.

    Returns
    -------
    dict
        ``{"mpjpe_m": mpjpe (NaN when no joint is known), "frames": frames whose every joint is estimated}``.

    Raises
    ------
    InputError
        The shapes differ.
    """
    a, b = _pair(joints, truth, "pose_errors")
    return {"mpjpe_m": mpjpe(a, b), "frames": int(np.isfinite(a).all(axis=(-1, -2)).sum())}
