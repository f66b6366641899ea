"""Silhouettes: a binary mask, its bounding box and an explicit state."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError
from toolkit.foreground.config import SilhouetteConfig

#: Silhouette states.  ``"ok"``: usable; ``"empty"``: nobody (or too small);
#: ``"full"``: most of the image, not a person; ``"touches_border"``: the subject is cut by
#: the image edge (leaving or entering), usable with care.
STATES = ("ok", "empty", "full", "touches_border")


@dataclass(frozen=True, eq=False)
class Silhouette:
    """The subject's silhouette in one frame of one camera.

    Attributes
    ----------
    mask : ndarray of shape (H, W) of bool
    bbox : tuple of int or None
        ``(x0, y0, x1, y1)`` pixel indices with ``x1``, ``y1`` exclusive, so the crop is
        ``mask[y0:y1, x0:x1]``; ``None`` when the mask is empty.
    state : str
        One of :data:`STATES`.
    area_px : int
        Foreground pixels.
    """

    mask: np.ndarray
    bbox: tuple[int, int, int, int] | None
    state: str
    area_px: int

    @property
    def usable(self) -> bool:
        """``state`` is ``"ok"`` or ``"touches_border"``."""
        return self.state in ("ok", "touches_border")

    def __bool__(self) -> bool:
        return self.usable


def bounding_box(mask: np.ndarray) -> tuple[int, int, int, int] | None:
    """``(x0, y0, x1, y1)`` (x1, y1 exclusive) of the true pixels, or None."""
    m = np.asarray(mask, bool)
    rows = np.flatnonzero(m.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(m.any(axis=0))
    return int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1


def silhouette_from_mask(mask: np.ndarray, config: SilhouetteConfig | None = None) -> Silhouette:
    """Wrap a binary mask with its bounding box and state.

    Parameters
    ----------
    mask : ndarray of shape (H, W)
        Non-zero = subject.
    config : SilhouetteConfig, optional

    Returns
    -------
    Silhouette
        ``"empty"`` (bbox None when nothing at all) below ``min_area_px``; ``"full"`` above
        ``full_fraction`` of the image; ``"touches_border"`` when the box reaches the edge.
    """
    cfg = config or SilhouetteConfig()
    m = np.asarray(mask)
    if m.ndim != 2 or m.size == 0:
        raise InputError("mask", "a non-empty 2D array (H, W)", f"shape {m.shape}")
    m = m.astype(bool)
    area = int(m.sum())
    box = bounding_box(m)
    h, w = m.shape
    if area < cfg.min_area_px:
        state = "empty"
    elif area > cfg.full_fraction * m.size:
        state = "full"
    else:
        x0, y0, x1, y1 = box
        e = cfg.border_margin_px
        state = "touches_border" if (x0 <= e or y0 <= e or x1 >= w - e or y1 >= h - e) else "ok"
    return Silhouette(mask=m, bbox=box, state=state, area_px=area)


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two binary masks (1.0 when both are empty)."""
    a = np.asarray(a, bool)
    b = np.asarray(b, bool)
    if a.shape != b.shape:
        raise InputError("mask_iou", "masks of equal shape", f"{a.shape} and {b.shape}")
    union = np.logical_or(a, b).sum()
    return 1.0 if union == 0 else float(np.logical_and(a, b).sum() / union)
