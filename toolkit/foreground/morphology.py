"""Morphological clean-up of raw foreground masks."""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.errors import InputError
from toolkit.foreground.config import MorphologyConfig


def disk(radius: int) -> np.ndarray:
    """Elliptical structuring element of the given radius (pixels), uint8."""
    r = int(radius)
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


def fill_holes(mask: np.ndarray) -> np.ndarray:
    """Fill the background regions not connected to the image border."""
    m = np.asarray(mask, bool)
    h, w = m.shape
    # pad so that the whole border is one background region
    pad = np.zeros((h + 2, w + 2), np.uint8)
    pad[1:-1, 1:-1] = m
    n, lab = cv2.connectedComponents((pad == 0).astype(np.uint8), connectivity=4)
    outside = lab == lab[0, 0]
    return (~outside)[1:-1, 1:-1]


def keep_largest_components(mask: np.ndarray, keep: int, min_fraction: float = 0.0,
                            merge_fraction: float = 0.0) -> np.ndarray:
    """Keep the subject's connected components.

    Parameters
    ----------
    mask : ndarray of shape (H, W)
    keep : int
        The ``keep`` largest 8-connected components are kept (0 = all).
    min_fraction : float
        Components smaller than this fraction of the largest are dropped.
    merge_fraction : float
        A component closer to a kept one than ``merge_fraction`` times that component's
        bounding-box height joins it (a limb separated from the body by a thin gap), in any
        number of steps.

    Returns
    -------
    ndarray of shape (H, W) of bool
    """
    m = np.asarray(mask, bool)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(m.astype(np.uint8), connectivity=8)
    if n <= 1:
        return m.copy()
    areas = stats[1:, cv2.CC_STAT_AREA]
    order = np.argsort(areas)[::-1]
    big = order[areas[order] >= min_fraction * areas.max()]
    kept = list(big[:keep] if keep else big)
    if merge_fraction > 0 and keep:
        others = [c for c in big if c not in kept]
        grow = True
        while grow and others:
            grow = False
            for c in list(kept):
                r = int(np.ceil(merge_fraction * stats[c + 1, cv2.CC_STAT_HEIGHT]))
                near = cv2.dilate((lab == c + 1).astype(np.uint8), disk(r)) > 0
                for o in list(others):
                    if near[lab == o + 1].any():
                        kept.append(o)
                        others.remove(o)
                        grow = True
    return np.isin(lab, np.array(kept) + 1)


def clean_mask(mask: np.ndarray, config: MorphologyConfig | None = None) -> np.ndarray:
    """Opening, closing, component selection and hole filling.

    Parameters
    ----------
    mask : ndarray of shape (H, W)
        Non-zero = foreground.
    config : MorphologyConfig, optional

    Returns
    -------
    ndarray of shape (H, W) of bool
    """
    cfg = config or MorphologyConfig()
    m = np.asarray(mask)
    if m.ndim != 2:
        raise InputError("mask", "a 2D array (H, W)", f"shape {m.shape}")
    m = m.astype(bool).astype(np.uint8)
    if cfg.open_radius_px:
        m = cv2.morphologyEx(m, cv2.MORPH_OPEN, disk(cfg.open_radius_px))
    if cfg.close_radius_px:
        # pad so that closing does not glue the silhouette to the image border
        r = cfg.close_radius_px
        p = cv2.copyMakeBorder(m, r, r, r, r, cv2.BORDER_CONSTANT, value=0)
        m = cv2.morphologyEx(p, cv2.MORPH_CLOSE, disk(r))[r:-r, r:-r]
    out = m.astype(bool)
    if cfg.keep_components or cfg.min_component_fraction:
        out = keep_largest_components(out, cfg.keep_components, cfg.min_component_fraction,
                                      cfg.merge_fraction)
    if cfg.fill_holes:
        out = fill_holes(out)
    return out
