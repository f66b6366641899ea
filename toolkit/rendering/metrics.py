"""Image quality inside the subject's bounding box: PSNR and SSIM."""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.errors import InputError

#: Pixels added around the ground-truth mask's bounding box.
BBOX_MARGIN_PX = 4
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
