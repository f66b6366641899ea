"""Chroma keying: everything that is not the screen colour is foreground."""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.errors import InputError
from toolkit.foreground.config import ChromaKeyConfig


def _rgb(image: np.ndarray, where: str) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise InputError(where, "an RGB uint8 image (H, W, 3)", f"shape {img.shape}, dtype {img.dtype}")
    return img


def screen_mask(image: np.ndarray, config: ChromaKeyConfig | None = None) -> np.ndarray:
    """Pixels of the screen colour, (H, W) bool.

    Parameters
    ----------
    image : ndarray of shape (H, W, 3), uint8 RGB
    config : ChromaKeyConfig, optional
        A hue range with ``lo > hi`` wraps around 0 (for red screens).
    """
    cfg = config or ChromaKeyConfig()
    hsv = cv2.cvtColor(_rgb(image, "image"), cv2.COLOR_RGB2HSV)
    h, s, v = hsv[..., 0], hsv[..., 1], hsv[..., 2]
    lo, hi = cfg.hue_range
    hue_ok = (h >= lo) & (h <= hi) if lo <= hi else (h >= lo) | (h <= hi)
    return hue_ok & (s >= cfg.sat_min) & (v >= cfg.val_min)


def chroma_key(image: np.ndarray, config: ChromaKeyConfig | None = None) -> np.ndarray:
    """Foreground of a chroma-keyed image: not the screen colour, (H, W) bool."""
    return ~screen_mask(image, config)
