"""subject_scores works in the dilated mask's box: the same scores as over the whole image (issue 20)."""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.rendering.metrics import COVERAGE_ALPHA, SUBJECT_DILATION_PX, psnr, subject_scores


def _whole_image(image, reference, gt_mask, alpha) -> dict:
    """The scores as they were computed before (the reference): every array at full size."""
    m = np.asarray(gt_mask, bool)
    if not m.any():
        return {"psnr_subject": float("nan"), "coverage": float("nan")}
    a = alpha.astype(np.float64) / 255.0 if alpha.dtype == np.uint8 else alpha.astype(np.float64)
    k = 2 * SUBJECT_DILATION_PX + 1
    region = cv2.dilate(m.astype(np.uint8), np.ones((k, k), np.uint8)) > 0
    return {"psnr_subject": psnr(image, reference, region), "coverage": float(np.mean(a[m] > COVERAGE_ALPHA))}


def test_subject_scores_equal_the_whole_image_ones():
    rng = np.random.default_rng(9)
    for i in range(120):
        h, w = (int(v) for v in rng.integers(3, 90, 2))
        ref = rng.integers(0, 256, (h, w, 3)).astype(np.uint8)
        img = np.clip(ref.astype(int) + rng.integers(-40, 40, (h, w, 3)), 0, 255).astype(np.uint8)
        if i % 4 == 0:
            img = img.astype(np.float32) + 0.25  # float renders too
        if i % 9 == 0:
            img = ref.copy()  # identical: inf
        m = np.zeros((h, w), bool)
        if i % 7:  # every 7th mask empty: NaN
            y, x = rng.integers(0, h), rng.integers(0, w)  # boxes at and over the image's borders
            m[y:y + rng.integers(1, 30), x:x + rng.integers(1, 30)] = True
            m &= rng.random((h, w)) < 0.9
        alpha = rng.random((h, w)).astype(np.float32) if i % 2 else (rng.random((h, w)) * 255).astype(np.uint8)
        got, want = subject_scores(img, ref, m, alpha), _whole_image(img, ref, m, alpha)
        for k in want:
            assert (np.isnan(got[k]) and np.isnan(want[k])) or got[k] == want[k], (i, k)
