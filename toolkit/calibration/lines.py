"""Detect painted field lines in an image as sub-pixel centre-line points.

White lines on grass are thin, bright and unsaturated.  The detector takes
the "whiteness" of each pixel (its smallest RGB channel), keeps what stands
out from its neighbourhood (a morphological white top-hat, OpenCV), smooths
it, and finds the centre line with Steger's ridge test: at a ridge pixel the
Hessian has one strongly negative eigenvalue, whose eigenvector n is the line
normal, and the extremum of the second-order Taylor expansion along n lies
within the pixel.  Each detected point comes with that normal, so a model
point can be compared with the line by its point-to-line distance.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolkit.errors import InputError
from toolkit.foreground.background import check_rgb


@dataclass(frozen=True)
class LineDetectorConfig:
    """Parameters of :func:`detect_line_points`.

    Attributes
    ----------
    max_width_px : int
        Widest line expected, pixels; the top-hat window is twice this plus one.
    min_contrast : float
        Minimum top-hat response (0-255 whiteness above the local background).
    max_saturation : float
        Pixels more saturated than this (HSV, 0-255) are not line paint.
    sigma_px : float
        Gaussian smoothing before the Hessian, pixels (about half the typical width).
    min_curvature : float
        Minimum |second derivative| across the line (per pixel squared, on the
        0-255 scale), rejecting flat plateaus and noise.
    min_length_px : int
        Ridge pixels in 8-connected pieces shorter than this are dropped
        (isolated bright specks of grass texture or sensor noise).
    """

    max_width_px: int = 12
    min_contrast: float = 40.0
    max_saturation: float = 90.0
    sigma_px: float = 1.5
    min_curvature: float = 1.0
    min_length_px: int = 8

    def __post_init__(self):
        if not (isinstance(self.max_width_px, int) and self.max_width_px >= 1):
            raise InputError("LineDetectorConfig.max_width_px", "an integer >= 1", repr(self.max_width_px))
        if not (isinstance(self.min_length_px, int) and self.min_length_px >= 1):
            raise InputError("LineDetectorConfig.min_length_px", "an integer >= 1", repr(self.min_length_px))
        for name in ("min_contrast", "max_saturation", "sigma_px", "min_curvature"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise InputError(f"LineDetectorConfig.{name}", "a finite value >= 0", repr(v))


@dataclass(frozen=True)
class LinePoints:
    """Centre-line points of the detected lines.

    Attributes
    ----------
    points : ndarray of shape (N, 2)
        Sub-pixel positions (pixel-centre convention).
    normals : ndarray of shape (N, 2)
        Unit normals of the line at each point (sign arbitrary).
    strength : ndarray of shape (N,)
        Top-hat response at the point (0-255).
    mask : ndarray of shape (H, W) bool
        Pixels that passed the paint test (for display).
    """

    points: np.ndarray
    normals: np.ndarray
    strength: np.ndarray
    mask: np.ndarray

    def __len__(self) -> int:
        return int(self.points.shape[0])


def detect_line_points(image: np.ndarray, config: LineDetectorConfig = LineDetectorConfig(),
                       region: np.ndarray | None = None) -> LinePoints:
    """Centre-line points of white lines in an RGB image.

    Parameters
    ----------
    image : ndarray of shape (H, W, 3) uint8
        RGB image of the (empty) scene, e.g. a clean plate or a learned background.
    config : LineDetectorConfig
    region : ndarray of shape (H, W) bool, optional
        Where to look (e.g. everything but the subject); default everywhere.

    Returns
    -------
    LinePoints
    """
    img = check_rgb(image, "detect_line_points: image")
    white = img.min(axis=2)
    k = 2 * config.max_width_px + 1
    tophat = cv2.morphologyEx(white, cv2.MORPH_TOPHAT, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    sat = cv2.cvtColor(img, cv2.COLOR_RGB2HSV)[..., 1]
    paint = (tophat >= config.min_contrast) & (sat <= config.max_saturation)
    if region is not None:
        region = np.asarray(region, bool)
        if region.shape != paint.shape:
            raise InputError("detect_line_points: region", f"a bool mask of shape {paint.shape}", f"{region.shape}")
        paint &= region
    # grow the paint mask a little so the ridge of a thin line survives smoothing
    paint_d = cv2.dilate(paint.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    f = cv2.GaussianBlur(tophat.astype(np.float32), (0, 0), config.sigma_px)
    fx = cv2.Sobel(f, cv2.CV_32F, 1, 0, ksize=3, scale=1 / 8)
    fy = cv2.Sobel(f, cv2.CV_32F, 0, 1, ksize=3, scale=1 / 8)
    fxx = cv2.Sobel(f, cv2.CV_32F, 2, 0, ksize=3, scale=1 / 4)
    fyy = cv2.Sobel(f, cv2.CV_32F, 0, 2, ksize=3, scale=1 / 4)
    fxy = cv2.Sobel(f, cv2.CV_32F, 1, 1, ksize=3, scale=1 / 4)
    ys, xs = np.nonzero(paint_d)
    empty = LinePoints(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), paint)
    if xs.size == 0:
        return empty
    a, b, c = fxx[ys, xs].astype(np.float64), fxy[ys, xs].astype(np.float64), fyy[ys, xs].astype(np.float64)
    # most negative eigenvalue of [[a, b], [b, c]] and its eigenvector (the line normal)
    half_tr, det_d = (a + c) / 2, np.sqrt(((a - c) / 2) ** 2 + b ** 2)
    lam = half_tr - det_d
    nx, ny = b, lam - a
    alt = np.abs(nx) + np.abs(ny) < 1e-12
    nx, ny = np.where(alt, lam - c, nx), np.where(alt, b, ny)
    norm = np.hypot(nx, ny)
    norm[norm == 0] = 1.0
    nx, ny = nx / norm, ny / norm
    gx, gy = fx[ys, xs].astype(np.float64), fy[ys, xs].astype(np.float64)
    denom = a * nx * nx + 2 * b * nx * ny + c * ny * ny
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -(gx * nx + gy * ny) / denom
    ok = (lam < -config.min_curvature) & np.isfinite(t) & (np.abs(t * nx) <= 0.5) & (np.abs(t * ny) <= 0.5)
    ok &= tophat[ys, xs] >= config.min_contrast * 0.5
    if ok.any() and config.min_length_px > 1:
        ridge = np.zeros(paint.shape, np.uint8)
        ridge[ys[ok], xs[ok]] = 1
        _, comp, stats, _ = cv2.connectedComponentsWithStats(ridge, connectivity=8)
        long_enough = stats[:, cv2.CC_STAT_AREA] >= config.min_length_px
        ok[ok] = long_enough[comp[ys[ok], xs[ok]]]
    if not ok.any():
        return empty
    pts = np.stack([xs[ok] + t[ok] * nx[ok], ys[ok] + t[ok] * ny[ok]], axis=1)
    normals = np.stack([nx[ok], ny[ok]], axis=1)
    return LinePoints(pts, normals, tophat[ys[ok], xs[ok]].astype(np.float64), paint)
