"""Seam correction (source 000 §3.3).

A pixel of a part segmentation is a *seam pixel* when one of its 4-neighbours
carries another part label of the same subject and the two depths differ by
less than φ (:data:`~toolkit.billboards.config.SEAM_DEPTH_M`, 3 cm).  Seam
pixels are rendered for both adjacent billboards, which closes the cracks that
projective texturing otherwise opens between neighbouring fans.

Part membership is stored as a bit mask per pixel: bit ``k`` set means the pixel
contributes to part id ``k`` (1..15).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.billboards.config import SEAM_DEPTH_M
from toolkit.errors import InputError
from toolkit.observe import Observer, as_observer


@dataclass(frozen=True, eq=False)
class SeamMap:
    """Seam pixels of one segmentation.

    Attributes
    ----------
    mask : ndarray of shape (H, W), bool
        Seam pixels.
    membership : ndarray of shape (H, W), uint16
        Bit ``k`` set when the pixel contributes to part ``k``: its own label,
        plus the labels of the 4-neighbours it forms a seam with.
    """

    mask: np.ndarray
    membership: np.ndarray

    @property
    def count(self) -> int:
        return int(self.mask.sum())


def _check_labels(labels, where="labels") -> np.ndarray:
    lab = np.asarray(labels)
    if lab.ndim != 2 or not np.issubdtype(lab.dtype, np.integer):
        raise InputError(where, "an (H, W) integer part-label image", f"shape {lab.shape}, dtype {lab.dtype}")
    if lab.size and (lab.min() < 0 or lab.max() > 15):
        raise InputError(where, "part ids in 0..15", f"range {lab.min()}..{lab.max()}")
    return lab


def membership_of(labels: np.ndarray) -> np.ndarray:
    """Bit-mask membership (H, W) uint16 of a label image without seams (bit ``label``; 0 for background)."""
    lab = _check_labels(labels).astype(np.uint16)
    return np.where(lab > 0, np.left_shift(np.uint16(1), lab), np.uint16(0)).astype(np.uint16)


def detect_seams(labels: np.ndarray, depth: np.ndarray, subject: np.ndarray | None = None,
                 threshold: float = SEAM_DEPTH_M, *, camera: str | None = None,
                 observer: Observer | None = None) -> SeamMap:
    """Find the seam pixels of a part segmentation.

    Parameters
    ----------
    labels : ndarray of shape (H, W), integer
        Part ids (0 = background).
    depth : ndarray of shape (H, W), float
        Depth per pixel in metres (the fitted template's, or ground truth);
        NaN where unknown (such pixels never form seams).
    subject : ndarray of shape (H, W), integer, optional
        Subject id per pixel; None = one subject (every labelled pixel).
    threshold : float
        φ in metres.
    camera : str, optional
        Camera name, only for the report.
    observer : Observer, optional
        Receives ``mask`` (name ``"seams"``) and a ``scalar`` seam count.

    Returns
    -------
    SeamMap
    """
    lab = _check_labels(labels)
    d = np.asarray(depth, dtype=np.float64)
    if d.shape != lab.shape:
        raise InputError("depth", f"shape {lab.shape} (the labels')", f"shape {d.shape}")
    if subject is None:
        subj = (lab > 0).astype(np.int32)
    else:
        subj = np.asarray(subject)
        if subj.shape != lab.shape:
            raise InputError("subject", f"shape {lab.shape} (the labels')", f"shape {subj.shape}")
    if not threshold > 0:
        raise InputError("threshold", "a positive depth difference in metres", f"{threshold}")
    member = membership_of(lab)
    mask = np.zeros(lab.shape, bool)
    H, W = lab.shape
    for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        ys = slice(max(dy, 0), H + min(dy, 0))
        xs = slice(max(dx, 0), W + min(dx, 0))
        yn = slice(max(-dy, 0), H + min(-dy, 0))
        xn = slice(max(-dx, 0), W + min(-dx, 0))
        # pixel at (ys, xs); its neighbour at (yn, xn) = pixel + (-dy, -dx)
        l0, l1 = lab[ys, xs], lab[yn, xn]
        with np.errstate(invalid="ignore"):
            close = np.abs(d[ys, xs] - d[yn, xn]) < threshold
        seam = (l0 > 0) & (l1 > 0) & (l0 != l1) & (subj[ys, xs] == subj[yn, xn]) & (subj[ys, xs] > 0) & close
        mask[ys, xs] |= seam
        bits = np.left_shift(np.uint16(1), l1.astype(np.uint16))
        member[ys, xs] |= np.where(seam, bits, np.uint16(0)).astype(np.uint16)
    obs = as_observer(observer)
    extra = {} if camera is None else {"camera": camera}
    obs.report("mask", mask=mask, name="seams", **extra)
    obs.report("scalar", name="seams/count" + ("" if camera is None else f"/{camera}"), value=float(mask.sum()))
    return SeamMap(mask=mask, membership=member)
