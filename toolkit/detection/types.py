"""What a detector returns: :class:`Detection`, one person found in one image."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Detection"]


@dataclass(frozen=True, eq=False)
class Detection:
    """One person found in one image.

    Attributes
    ----------
    keypoints : ndarray of shape (K, 3)
        ``(x, y, confidence)``: pixel coordinates (the centre of the top-left pixel at 0, 0) and a
        confidence in [0, 1]; NaN coordinates for keypoints the backend does not give.
    score : float
        The person's confidence in [0, 1] (the mean keypoint confidence when the backend has none).
    mask : ndarray of shape (H, W) of float32, optional
        The person's segmentation (probability per pixel) when the backend gives one and it was asked for.
    """

    keypoints: np.ndarray
    score: float
    mask: np.ndarray | None = None
