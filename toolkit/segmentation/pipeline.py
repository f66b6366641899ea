"""Segmentation of every camera and frame of a dataset, from stage-1 or ground-truth poses."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.segmentation.segment import SegmentationConfig, SegmentationResult, segment_frame
from toolkit.template import PoseDatabase, Template

#: What the template is fitted to in each view: the multi-view 3D joints projected through the view's
#: (corrected) camera, or that view's own stage-1 2D pose (the source's per-view fit).
TEMPLATE_POSES = ("multiview", "per_view")


@dataclass(frozen=True)
class PoseSource:
    """The poses the template is fitted to, for a whole sequence.

    Attributes
    ----------
    rig : Rig
        Cameras to project through (the ones stage 1 used for stage-1 poses, true ones for
        ground truth); the names and order of every frame's cameras.
    joints3d : ndarray of shape (T, 14, 3) or None
        World, metres, NaN = missing.
    joints2d : mapping of str -> ndarray of shape (T, 14, 2), optional
        Per camera, 2D poses in image pixels (stage 1's offsets included), NaN = missing;
        default: ``joints3d`` projected.
    rigs : sequence of Rig, optional
        Per frame, ``rig`` corrected by that frame's stage-1 offsets
        (:func:`toolkit.multiview.corrected_rig`); default: ``rig`` in every frame.
    name : str
        ``"stage1"``, ``"groundtruth"`` or ``"none"`` (for messages).
    """

    rig: Rig
    joints3d: np.ndarray | None = None
    joints2d: Mapping[str, np.ndarray] | None = None
    rigs: tuple[Rig, ...] | None = None
    name: str = "stage1"

    def __post_init__(self):
        n = len(self.rig)
        if self.joints3d is not None:
            J = np.asarray(self.joints3d)
            if J.ndim != 3 or J.shape[1:] != (14, 3):
                raise InputError(f"{self.name}: joints3d", "an array of shape (T, 14, 3)", f"shape {J.shape}")
        for t, r in enumerate(self.rigs or ()):
            if not isinstance(r, Rig) or r.names != self.rig.names:
                raise InputError(f"{self.name}: rigs[{t}]", f"a Rig of the cameras {self.rig.names} ({n})",
                                 repr(getattr(r, "names", r)))
        for cam, a in (self.joints2d or {}).items():
            if np.asarray(a).ndim != 3 or np.asarray(a).shape[1:] != (14, 2):
                raise InputError(f"{self.name}: joints2d[{cam!r}]", "an array of shape (T, 14, 2)",
                                 f"shape {np.asarray(a).shape}")

    def view(self, camera: str, t: int):
        """``(camera, joints3d (14, 3) or None, joints2d (14, 2) or None)`` for frame ``t``."""
        cam = (self.rigs[t] if self.rigs is not None and t < len(self.rigs) else self.rig)[camera]
        J = None
        if self.joints3d is not None and t < len(self.joints3d):
            J = np.asarray(self.joints3d[t], float)
        x = None
        if self.joints2d is not None and camera in self.joints2d and t < len(self.joints2d[camera]):
            x = np.asarray(self.joints2d[camera][t], float)
            if not np.isfinite(x).any():
                x = None
        return cam, J, x


def segment_views(frames: Callable[[str, int], np.ndarray], silhouettes: Callable[[str, int], np.ndarray],
                  poses: PoseSource, n_frames: int, template: Template,
                  config: SegmentationConfig = SegmentationConfig(), observer=None,
                  database: PoseDatabase | None = None, cameras=None,
                  frame_indices=None) -> Iterator[tuple[int, str, SegmentationResult]]:
    """Segment every camera of every frame.

    Parameters
    ----------
    frames, silhouettes : callable (camera, t) -> (H, W, 3) uint8 / (H, W) bool
    poses : PoseSource
    n_frames : int
    template, config, observer, database
        As for :func:`segment_frame`.
    cameras : sequence of str, optional
        Default: every camera of ``poses.rig``.
    frame_indices : sequence of int, optional
        The frames to segment, in order (default: ``0 .. n_frames - 1``; a
        resumed run passes those without results).

    Yields
    ------
    (t, camera, SegmentationResult)
    """
    names = list(poses.rig.names if cameras is None else cameras)
    for t in (range(int(n_frames)) if frame_indices is None else frame_indices):
        for c in names:
            cam, J, x = poses.view(c, t)
            yield t, c, segment_frame(frames(c, t), silhouettes(c, t), J, cam, template, config, observer,
                                      joints2d=x, database=database, frame=t)
