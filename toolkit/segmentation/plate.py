"""The silhouette's border checked against the background plate and the parts' colour models.

Stage 1's silhouettes are a thresholded colour distance to the background,
cleaned by morphology: they take in blended border pixels (anti-aliasing,
motion blur), shadows and the gaps between limbs that the hole filling closes,
and on a thin broadcast limb (4-6 px wide) one pixel too many or too few
moves the part's IoU by 20-40 %.  With the background plate ``B`` and the
parts' colour mixtures, each pixel's colour ``I`` is explained as a blend

    I = alpha F + (1 - alpha) B

where ``F`` is the mixture component mean (of any part) nearest to ``I``: the
subject's colour that best explains it.  ``alpha`` is the projection of
``I - B`` on ``F - B``.  A silhouette pixel with ``alpha < 0.5`` is more plate
than subject and leaves the silhouette.  Where the subject's colour is too
close to the plate's (``|F - B| < min_contrast``: a kit like the pitch)
colour cannot tell, and the body template does: a pixel of the template's
thinned projection missing from the silhouette joins it (stage 1 loses
7-23 % of a kit like the pitch), any other keeps stage 1's decision.
Optionally pixels of a ring just outside the silhouette with
``alpha >= join_alpha`` join it (off by default: on MP4 frames the subject's
colour bleeds 1-2 px outwards, measured -0.03 part IoU).
"""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.errors import InputError
from toolkit.segmentation.colour import PartColourModels


def component_means(models: PartColourModels) -> np.ndarray:
    """Every mixture component's mean, all parts together, (K, D) in feature units."""
    means = [g.means_ for g in models.models.values()]
    return np.concatenate(means, 0) if means else np.zeros((0, 3))


def plate_alpha(features: np.ndarray, plate_features: np.ndarray, means: np.ndarray,
                min_contrast: float) -> np.ndarray:
    """Opacity of the subject in each pixel, NaN where the subject and the plate are too alike.

    Parameters
    ----------
    features : ndarray of shape (N, D)
        The pixels' colour features.
    plate_features : ndarray of shape (N, D)
        The background plate's features at the same pixels.
    means : ndarray of shape (K, D)
        Subject colours (:func:`component_means`).
    min_contrast : float
        Smallest ``|F - B|`` (feature units) for which ``alpha`` is computed.

    Returns
    -------
    ndarray of shape (N,), float
        ``alpha`` clipped to [0, 1]; NaN where undecidable (or no means).
    """
    f = np.asarray(features, float)
    b = np.asarray(plate_features, float)
    m = np.asarray(means, float)
    if f.ndim != 2 or b.shape != f.shape or m.ndim != 2 or (len(m) and m.shape[1] != f.shape[1]):
        raise InputError("plate_alpha: features, plate_features, means", "(N, D), (N, D) and (K, D)",
                         f"{f.shape}, {b.shape} and {m.shape}")
    out = np.full(len(f), np.nan)
    if len(m) == 0 or len(f) == 0:
        return out
    d2 = ((f[:, None, :] - m[None, :, :]) ** 2).sum(-1)
    F = m[d2.argmin(1)]
    fb = F - b
    n2 = (fb * fb).sum(1)
    ok = n2 >= float(min_contrast) ** 2
    out[ok] = np.clip(((f - b) * fb).sum(1)[ok] / n2[ok], 0.0, 1.0)
    return out


def refine_silhouette(silhouette: np.ndarray, features: np.ndarray, plate_features: np.ndarray,
                      models: PartColourModels, min_contrast: float, ring_px: int = 0,
                      template_core: np.ndarray | None = None, leave_alpha: float = 0.5,
                      join_alpha: float = 0.5) -> np.ndarray:
    """Silhouette with plate-like pixels removed and template or subject-like pixels added.

    Parameters
    ----------
    silhouette : ndarray of shape (H, W), bool
    features, plate_features : ndarray of shape (H, W, D)
        Colour features of the image and of the background plate.
    models : PartColourModels
        The parts' colour mixtures (their component means are the subject's colours).
    min_contrast : float
        See :func:`plate_alpha`.
    ring_px : int
        Width of the outer ring where pixels may join, pixels (0 = none join).
    template_core : ndarray of shape (H, W), bool, optional
        Pixels the body template surely covers (its thinned projection): outside
        the silhouette they join it unless their colour says plate
        (``alpha < join_alpha``); where kit and plate are alike the template decides.
    leave_alpha, join_alpha : float
        A silhouette pixel with ``alpha < leave_alpha`` leaves; a ring or
        template pixel with ``alpha >= join_alpha`` joins.

    Returns
    -------
    ndarray of shape (H, W), bool
    """
    sil = np.asarray(silhouette, bool)
    if features.shape[:2] != sil.shape or plate_features.shape != features.shape:
        raise InputError("refine_silhouette: features, plate_features",
                         f"(H, W, D) arrays with (H, W) = {sil.shape}", f"{features.shape} and {plate_features.shape}")
    means = component_means(models)
    if len(means) == 0 or not sil.any():
        return sil.copy()
    ring = np.zeros_like(sil)
    if ring_px > 0:
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * ring_px + 1,) * 2)
        ring = cv2.dilate(sil.astype(np.uint8), k) > 0
        ring &= ~sil
    core = np.zeros_like(sil) if template_core is None else (np.asarray(template_core, bool) & ~sil)
    cand = sil | ring | core
    a = plate_alpha(features[cand], plate_features[cand], means, min_contrast)
    keep = np.where(np.isnan(a), sil[cand] | core[cand], np.where(sil[cand], a >= leave_alpha, a >= join_alpha))
    out = np.zeros_like(sil)
    out[cand] = keep
    return out
