"""Image quality of a rendered subject: PSNR and SSIM in its bounding box, PSNR on it, coverage.

* :func:`bbox_scores`: PSNR and SSIM inside the ground-truth mask's bounding box
  (plus :data:`BBOX_MARGIN_PX`);
* :func:`subject_scores`: PSNR over the ground-truth mask dilated by
  :data:`SUBJECT_DILATION_PX` (the subject and its border, where a method can
  be wrong; the background far from it is the same plate for every method) and
  the *coverage*: the share of the true mask where the rendered opacity
  exceeds :data:`COVERAGE_ALPHA` (1 = the subject is fully there, 0 = missing).
"""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.errors import InputError

#: Pixels added around the ground-truth mask's bounding box.
BBOX_MARGIN_PX = 4
#: Pixels the ground-truth mask is dilated by for the subject-region PSNR (issue 13: "mask + 2 px").
SUBJECT_DILATION_PX = 2
#: Rendered opacity above which a true subject pixel counts as covered.
COVERAGE_ALPHA = 0.5
#: SSIM constants (Wang et al. 2004) for 8-bit images: (0.01 L)^2 and (0.03 L)^2, L = 255.
SSIM_C1 = (0.01 * 255) ** 2
SSIM_C2 = (0.03 * 255) ** 2
#: Gaussian window of SSIM, standard deviation in pixels (Wang et al. 2004: 1.5).
SSIM_SIGMA = 1.5


def mask_bbox(mask: np.ndarray, margin: int = BBOX_MARGIN_PX) -> tuple[int, int, int, int] | None:
    """``(x0, y0, x1, y1)`` of the non-zero pixels plus ``margin``, clipped; None for an empty mask."""
    m = np.asarray(mask).astype(bool)
    if not m.any():
        return None
    ys, xs = np.nonzero(m)
    h, w = m.shape
    return (max(xs.min() - margin, 0), max(ys.min() - margin, 0), min(xs.max() + margin + 1, w),
            min(ys.max() + margin + 1, h))


def _pair(a, b, where):
    a = np.asarray(a)
    b = np.asarray(b)
    if a.shape != b.shape or a.ndim != 3 or a.shape[2] != 3:
        raise InputError(where, "two (H, W, 3) images of the same shape", f"{a.shape} and {b.shape}")
    return a.astype(np.float64), b.astype(np.float64)


def psnr(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Peak signal-to-noise ratio in dB (peak 255), over ``mask`` pixels if given; inf when identical."""
    a, b = _pair(image, reference, "psnr: image, reference")
    d = (a - b) ** 2
    d = d[np.asarray(mask, bool)] if mask is not None else d.reshape(-1, 3)
    if d.size == 0:
        return float("nan")
    mse = float(d.mean())
    return float("inf") if mse == 0 else float(10 * np.log10(255.0 ** 2 / mse))


def ssim(image: np.ndarray, reference: np.ndarray) -> float:
    """Mean structural similarity of two RGB images (per channel, Gaussian window), in [-1, 1]."""
    a, b = _pair(image, reference, "ssim: image, reference")
    blur = lambda x: cv2.GaussianBlur(x, (0, 0), SSIM_SIGMA)  # noqa: E731
    mu_a, mu_b = blur(a), blur(b)
    saa = blur(a * a) - mu_a ** 2
    sbb = blur(b * b) - mu_b ** 2
    sab = blur(a * b) - mu_a * mu_b
    s = ((2 * mu_a * mu_b + SSIM_C1) * (2 * sab + SSIM_C2)) / ((mu_a ** 2 + mu_b ** 2 + SSIM_C1) * (saa + sbb + SSIM_C2))
    return float(s.mean())


def bbox_scores(image: np.ndarray, reference: np.ndarray, gt_mask: np.ndarray) -> dict:
    """PSNR and SSIM inside the bounding box of ``gt_mask``: ``{"psnr": dB, "ssim": ...}`` (NaN if empty)."""
    box = mask_bbox(gt_mask)
    if box is None:
        return {"psnr": float("nan"), "ssim": float("nan")}
    x0, y0, x1, y1 = box
    a, b = image[y0:y1, x0:x1], reference[y0:y1, x0:x1]
    return {"psnr": psnr(a, b), "ssim": ssim(a, b)}


def subject_scores(image: np.ndarray, reference: np.ndarray, gt_mask: np.ndarray, alpha: np.ndarray) -> dict:
    """PSNR on the subject and how much of it the rendering covers.

    Parameters
    ----------
    image : ndarray of shape (H, W, 3)
        The rendered view (subject over the background), uint8 or float 0..255.
    reference : ndarray of shape (H, W, 3)
        The ground-truth view.
    gt_mask : ndarray of shape (H, W)
        True subject pixels (bool or 0/1).
    alpha : ndarray of shape (H, W)
        Rendered opacity of the subject, in [0, 1] (float) or 0..255 (uint8).

    Returns
    -------
    dict
        ``psnr_subject``: PSNR in dB over ``gt_mask`` dilated by
        :data:`SUBJECT_DILATION_PX` (a 5x5 square for 2 px; NaN when the mask is
        empty, inf when identical there); ``coverage``: share of ``gt_mask``
        where the opacity exceeds :data:`COVERAGE_ALPHA` (NaN when the mask is empty).

    Raises
    ------
    InputError
        When the shapes disagree.

    Examples
    --------
    >>> import numpy as np
    >>> ref = np.zeros((8, 8, 3), np.uint8); m = np.zeros((8, 8), bool); m[3:5, 3:5] = True
    >>> a = m.astype(np.float32); a[3, 3] = 0.2
    >>> subject_scores(ref + 10, ref, m, a)["coverage"]
    0.75
    """
    image, reference = np.asarray(image), np.asarray(reference)
    if image.shape != reference.shape or image.ndim != 3 or image.shape[2] != 3:
        raise InputError("subject_scores: image, reference", "two (H, W, 3) images of the same shape",
                         f"{image.shape} and {reference.shape}")
    m = np.asarray(gt_mask)
    a = np.asarray(alpha)
    if m.shape != image.shape[:2]:
        raise InputError("subject_scores: gt_mask", f"shape {image.shape[:2]} (the image's)", f"shape {m.shape}")
    if a.shape != m.shape:
        raise InputError("subject_scores: alpha", f"shape {m.shape} (the mask's)", f"shape {a.shape}")
    m = m.astype(bool)
    # everything below happens within the dilated mask's box: the same pixels, in the same order
    box = mask_bbox(m, SUBJECT_DILATION_PX)
    if box is None:
        return {"psnr_subject": float("nan"), "coverage": float("nan")}
    x0, y0, x1, y1 = box
    m, a = m[y0:y1, x0:x1], a[y0:y1, x0:x1]
    a = a.astype(np.float64) / 255.0 if a.dtype == np.uint8 else a.astype(np.float64)
    k = 2 * SUBJECT_DILATION_PX + 1
    region = cv2.dilate(m.astype(np.uint8), np.ones((k, k), np.uint8)) > 0
    return {"psnr_subject": psnr(image[y0:y1, x0:x1], reference[y0:y1, x0:x1], region),
            "coverage": float(np.mean(a[m] > COVERAGE_ALPHA))}
