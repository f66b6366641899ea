"""Each source camera's empty view, estimated from its own video with the people removed.

:func:`estimate_background` takes an even sample of a camera's frames (people
walking, standing, waving) and returns, per pixel, the colour of the empty
scene and how sure it is:

1. the per-pixel median of the samples (a person who moves away within half
   the samples is gone from it);
2. per sample, the pixels far from that median (the maximum channel difference
   over both :data:`CHANGE_FLOOR` and :data:`CHANGE_SIGMAS` robust deviations of
   the pixel, grown by :data:`CHANGE_GROW_PX`), and the pixels a caller
   excludes (the people found by a detector: :func:`people_exclusion`), are
   left out;
3. the median of what is left; the confidence is the share of samples left,
   reaching 1 at :data:`FULL_CONFIDENCE_SHARE`.  A pixel no sample shows empty
   keeps the first median with confidence 0: another camera should show that
   place (:class:`toolkit.scene.SceneModel` weights by confidence).

Images are RGB uint8 ``(H, W, 3)``; backgrounds float32 0..255.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.errors import InputError

__all__ = ["SourceBackground", "estimate_background", "people_exclusion", "CHANGE_FLOOR", "CHANGE_SIGMAS",
           "CHANGE_GROW_PX", "FULL_CONFIDENCE_SHARE", "SAMPLES"]

#: Frames sampled per camera (evenly over the run).
SAMPLES = 32
#: A sample's pixel differs from the median by at least this (max over RGB, grey levels) to be a person.
CHANGE_FLOOR = 20.0
#: ... and by this many of the pixel's own robust standard deviations over the samples.
CHANGE_SIGMAS = 3.0
#: Changed pixels are grown by this (pixels) before being left out: a person's soft edges and shadow.
CHANGE_GROW_PX = 4
#: Share of samples showing a pixel empty at which its confidence reaches 1.
FULL_CONFIDENCE_SHARE = 0.3
#: Fewer frames than this give no change evidence (the people are then left out by the exclusions only).
MIN_CHANGE_SAMPLES = 3
#: Rows processed at once (bounds the memory of the per-pixel medians).
ROW_BLOCK = 96


@dataclass(frozen=True, eq=False)
class SourceBackground:
    """One camera's estimated empty view.

    Attributes
    ----------
    image : ndarray of shape (H, W, 3) float32
        Colour of the empty scene, 0..255.
    confidence : ndarray of shape (H, W) float32
        In [0, 1]: the share of samples that showed the pixel empty, over
        :data:`FULL_CONFIDENCE_SHARE` (0: never seen empty).
    samples : int
        Frames it was estimated from.
    """

    image: np.ndarray
    confidence: np.ndarray
    samples: int


def _masked_median(stack: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel median of ``stack`` (S, h, W, 3) uint8 over the samples ``keep`` (S, h, W) bool.

    Returns the median (h, W, 3) float32 (NaN where no sample is kept) and the kept count (h, W).
    """
    s = stack.shape[0]
    v = stack.astype(np.uint16)
    v[~keep] = 999  # sorts after every colour
    v.sort(axis=0)
    n = keep.sum(0)
    lo = np.clip((n - 1) // 2, 0, s - 1)
    hi = np.clip(n // 2, 0, s - 1)
    a = np.take_along_axis(v, lo[None, ..., None].repeat(3, -1), 0)[0].astype(np.float32)
    b = np.take_along_axis(v, hi[None, ..., None].repeat(3, -1), 0)[0].astype(np.float32)
    med = 0.5 * (a + b)
    med[n == 0] = np.nan
    return med, n


def estimate_background(frames, exclude=None) -> SourceBackground:
    """The empty scene of one camera from a sample of its frames.

    Parameters
    ----------
    frames : sequence of ndarray of shape (H, W, 3) uint8
        Frames of one camera, RGB (at least :data:`MIN_CHANGE_SAMPLES` for the people's change from
        the median to count).
    exclude : sequence of (ndarray of shape (H, W) bool or None), optional
        Per frame, pixels known to show a person (left out of the estimate).

    Returns
    -------
    SourceBackground

    Raises
    ------
    InputError
        No frame, frames of different sizes, or exclusion masks of another size.
    """
    frames = [np.asarray(f) for f in frames]
    if not frames:
        raise InputError("estimate_background: frames", "at least one frame of one camera", "none")
    h, w = frames[0].shape[:2]
    for i, f in enumerate(frames):
        if f.shape != (h, w, 3) or f.dtype != np.uint8:
            raise InputError(f"estimate_background: frames[{i}]", f"RGB uint8 of shape {(h, w, 3)}",
                             f"{f.dtype} {f.shape}")
    stack = np.stack(frames)  # (S, H, W, 3) uint8
    s = stack.shape[0]
    excluded = np.zeros((s, h, w), bool)
    if exclude is not None:
        if len(exclude) != s:
            raise InputError("estimate_background: exclude", f"one mask (or None) per frame ({s})", f"{len(exclude)}")
        for i, m in enumerate(exclude):
            if m is None:
                continue
            m = np.asarray(m, bool)
            if m.shape != (h, w):
                raise InputError(f"estimate_background: exclude[{i}]", f"a mask of shape {(h, w)}", f"{m.shape}")
            excluded[i] = m
    # pass 1: the median of every sample, its robust spread, and each sample's changed pixels
    first = np.empty((h, w, 3), np.float32)
    changed = np.empty((s, h, w), bool)
    everything = np.ones((s, min(ROW_BLOCK, h), w), bool)
    for r0 in range(0, h, ROW_BLOCK):
        r1 = min(h, r0 + ROW_BLOCK)
        block = stack[:, r0:r1]
        med, _ = _masked_median(block, everything[:, :r1 - r0])
        first[r0:r1] = med
        dist = np.abs(block.astype(np.float32) - med[None]).max(-1)  # (S, h, W)
        spread = 1.4826 * np.median(dist, axis=0)
        # with fewer than MIN_CHANGE_SAMPLES frames a change says nothing: only the exclusions count
        changed[:, r0:r1] = (dist > np.maximum(CHANGE_FLOOR, CHANGE_SIGMAS * spread)[None]) \
            if s >= MIN_CHANGE_SAMPLES else False
    k = 2 * CHANGE_GROW_PX + 1
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
    keep = np.empty_like(changed)
    for i in range(s):
        grown = cv2.dilate(changed[i].astype(np.uint8), kernel) > 0
        keep[i] = ~(grown | excluded[i])
    # pass 2: the median of what is left
    image = np.empty((h, w, 3), np.float32)
    count = np.empty((h, w), np.int32)
    for r0 in range(0, h, ROW_BLOCK):
        r1 = min(h, r0 + ROW_BLOCK)
        med, n = _masked_median(stack[:, r0:r1], keep[:, r0:r1])
        image[r0:r1] = np.where(np.isnan(med), first[r0:r1], med)
        count[r0:r1] = n
    confidence = np.clip(count / (FULL_CONFIDENCE_SHARE * s), 0.0, 1.0).astype(np.float32)
    return SourceBackground(image, confidence, s)


def people_exclusion(people, size: tuple[int, int], min_confidence: float = 0.3,
                     grow: float = 0.25) -> np.ndarray:
    """Pixels of an image that the detected people may cover.

    Parameters
    ----------
    people : sequence of ndarray of shape (K, 3)
        Every person of one image: ``(x, y, confidence)`` per keypoint, pixels.
    size : tuple of int
        Image ``(width, height)``.
    min_confidence : float
        Keypoints below this are ignored.
    grow : float
        The convex hull of a person's keypoints is grown by this share of its height
        (keypoints sit inside the body: the head's top, the hands and the feet lie beyond).

    Returns
    -------
    ndarray of shape (H, W) bool
    """
    w, h = size
    out = np.zeros((h, w), np.uint8)
    for p in people:
        p = np.asarray(p, float)
        ok = np.isfinite(p).all(-1) & (p[:, 2] >= min_confidence)
        if ok.sum() < 3:
            continue
        xy = p[ok, :2]
        tall = float(xy[:, 1].max() - xy[:, 1].min())
        wide = float(xy[:, 0].max() - xy[:, 0].min())
        r = int(round(grow * max(tall, wide, 8.0)))
        # the hull grown by r: a distance transform on the person's box (any r costs the same)
        x0, y0 = (int(np.floor(v)) - r - 1 for v in xy.min(0))
        x1, y1 = (int(np.ceil(v)) + r + 2 for v in xy.max(0))
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        if x1 <= x0 or y1 <= y0:
            continue
        crop = np.full((y1 - y0, x1 - x0), 255, np.uint8)
        hull = cv2.convexHull(np.round(xy - [x0, y0]).astype(np.int32))
        cv2.fillConvexPoly(crop, hull, 0)
        grown = cv2.distanceTransform(crop, cv2.DIST_L2, 3) <= r
        out[y0:y1, x0:x1] |= grown.astype(np.uint8)
    return out > 0
