"""Multi-view selection over a video: the previous frame's offsets start the next fit.

Calibration error changes slowly (it is the same cameras), so the offsets of
frame ``t - 1`` are a good starting point for frame ``t``; the previous 3D
pose also breaks ties between mirror combinations (see
:mod:`toolkit.multiview.selection`).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.multiview.config import MultiViewConfig
from toolkit.multiview.selection import MultiViewSelection, select_multiview
from toolkit.observe import Observer
from toolkit.skeleton import SKELETON_14, Skeleton


class MultiViewTracker:
    """Frame-by-frame multi-view selection carrying offsets and pose forward.

    Parameters
    ----------
    rig : Rig
    config : MultiViewConfig, optional
    observer : Observer, optional
    skeleton : Skeleton

    Examples
    --------
    >>> tracker = MultiViewTracker(rig)                      # doctest: +SKIP
    >>> for t, cands in enumerate(candidates_per_frame):     # doctest: +SKIP
    ...     sel = tracker.step(cands, frame=t)
    """

    def __init__(self, rig: Rig, config: MultiViewConfig | None = None, observer: Observer | None = None,
                 skeleton: Skeleton = SKELETON_14):
        self.rig = rig
        self.config = config or MultiViewConfig()
        self.observer = observer
        self.skeleton = skeleton
        self.offsets: np.ndarray | None = None
        self.joints3d: np.ndarray | None = None

    def step(self, candidates: np.ndarray, weights: np.ndarray | None = None,
             frame: int | None = None) -> MultiViewSelection:
        """Select and triangulate one frame; see :func:`select_multiview` for shapes.

        A failed frame keeps the previous offsets and pose for the next one.
        """
        sel = select_multiview(candidates, self.rig, self.config, weights=weights,
                               initial_offsets=self.offsets, previous_joints3d=self.joints3d,
                               observer=self.observer, frame=frame, skeleton=self.skeleton)
        if sel.success:
            used = sel.views_used
            prev = np.zeros((len(self.rig), 2)) if self.offsets is None else self.offsets
            self.offsets = np.where(used[:, None], sel.offsets, prev)
            if np.isfinite(sel.joints3d).all():
                self.joints3d = sel.joints3d
            elif self.joints3d is not None:
                self.joints3d = np.where(np.isfinite(sel.joints3d), sel.joints3d, self.joints3d)
        return sel


def select_sequence(candidates: np.ndarray | Iterable[np.ndarray], rig: Rig,
                    config: MultiViewConfig | None = None, *, weights=None,
                    observer: Observer | None = None, skeleton: Skeleton = SKELETON_14) -> list[MultiViewSelection]:
    """:func:`select_multiview` on every frame, each starting from the previous frame's offsets.

    Parameters
    ----------
    candidates : ndarray of shape (n_frames, n_views, k, n_joints, 2), or an iterable of
        ``(n_views, k, n_joints, 2)`` arrays
    rig : Rig
    config : MultiViewConfig, optional
    weights : ndarray of shape (n_frames, n_views, k, n_joints), or an iterable, optional
    observer : Observer, optional
        Reports carry ``frame`` = the frame index.
    skeleton : Skeleton

    Returns
    -------
    list of MultiViewSelection
        One per frame.
    """
    tracker = MultiViewTracker(rig, config, observer, skeleton)
    frames = list(candidates)
    ws = [None] * len(frames) if weights is None else list(weights)
    if len(ws) != len(frames):
        raise InputError("weights", f"{len(frames)} frames (one per candidate frame)", f"{len(ws)}")
    return [tracker.step(c, w, frame=t) for t, (c, w) in enumerate(zip(frames, ws))]


def stack_selections(selections: list[MultiViewSelection], n_views: int,
                     n_joints: int = SKELETON_14.n_joints) -> dict[str, np.ndarray]:
    """Per-frame results as arrays (for writing ``.npz`` files).

    Parameters
    ----------
    selections : list of MultiViewSelection or None
        ``None`` marks a frame without an estimate.
    n_views, n_joints : int

    Returns
    -------
    dict of str to ndarray
        ``joints`` (T, n_joints, 3) m, ``offsets`` (T, n_views, 2) px, ``poses2d`` and
        ``poses2d_raw`` (n_views, T, n_joints, 2) px, ``ray_distances`` (T, n_views, n_joints) m,
        ``cost`` (T,) m, ``success`` (T,) bool, ``choice`` (T, n_views) int,
        ``flipped`` (T, n_views) bool.  Frames without an estimate are NaN (``success`` False).
    """
    T = len(selections)
    out = {
        "joints": np.full((T, n_joints, 3), np.nan),
        "offsets": np.full((T, n_views, 2), np.nan),
        "poses2d": np.full((n_views, T, n_joints, 2), np.nan),
        "poses2d_raw": np.full((n_views, T, n_joints, 2), np.nan),
        "ray_distances": np.full((T, n_views, n_joints), np.nan),
        "cost": np.full(T, np.nan),
        "success": np.zeros(T, bool),
        "choice": np.full((T, n_views), -1),
        "flipped": np.zeros((T, n_views), bool),
    }
    for t, s in enumerate(selections):
        if s is None:
            continue
        out["joints"][t] = s.joints3d
        out["offsets"][t] = np.where(s.views_used[:, None], s.offsets, np.nan)
        out["poses2d"][:, t] = s.poses2d
        out["poses2d_raw"][:, t] = s.poses2d_raw
        out["ray_distances"][t] = s.ray_distances
        out["cost"][t] = s.cost if np.isfinite(s.cost) else np.nan
        out["success"][t] = s.success
        out["choice"][t] = s.choice
        out["flipped"][t] = s.flipped
    return out
