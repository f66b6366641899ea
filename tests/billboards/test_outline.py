"""A segment's outline from each row's end pixels equals the hull of every pixel's corners (issue 20)."""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.billboards.build import segment_outline


def _all_corners_hull(member: np.ndarray) -> np.ndarray:
    """The outline as it was computed before (the reference): every pixel's four corners."""
    ys, xs = np.nonzero(member)
    if xs.size == 0:
        return np.zeros((0, 2))
    pts = np.concatenate([np.stack([xs + dx, ys + dy], -1) for dx in (-0.5, 0.5) for dy in (-0.5, 0.5)])
    return cv2.convexHull(pts.astype(np.float32)).reshape(-1, 2).astype(np.float64)


def _segments(rng: np.random.Generator) -> list:
    cases = [np.zeros((4, 4), bool), np.ones((1, 1), bool), np.ones((1, 7), bool), np.ones((7, 1), bool),
             np.eye(9, dtype=bool), np.eye(9, dtype=bool)[::-1]]
    body = np.zeros((120, 90), np.uint8)  # a limb-like blob: a thick rotated bar and a disc
    cv2.line(body, (10, 15), (70, 100), 1, 9)
    cv2.circle(body, (60, 30), 12, 1, -1)
    cases.append(body > 0)
    for _ in range(150):
        h, w = rng.integers(1, 40, 2)
        m = rng.random((h, w)) < rng.uniform(0.01, 0.9)  # sparse to dense, several pieces
        cases += [m, cv2.dilate(m.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0]
    return cases


def test_outline_equals_the_hull_of_every_pixel_corner():
    for m in _segments(np.random.default_rng(4)):
        got, ref = segment_outline(m), _all_corners_hull(m)
        assert got.dtype == ref.dtype and got.shape == ref.shape and got.tobytes() == ref.tobytes()
