"""Synthetic foreground fixtures: a textured static background and a moving figure."""

from __future__ import annotations

import cv2
import numpy as np

#: Image size (width, height) of the fixtures.
SIZE = (160, 120)
#: Per-pixel sensor noise of the fixtures (0-255 units).
NOISE_SIGMA = 3.0
#: Global illumination flicker of the fixtures (relative gain).
FLICKER = 0.02


def textured_background(rng: np.random.Generator, size=SIZE) -> np.ndarray:
    """Smooth colour noise plus a few flat panels, float (H, W, 3) in 0-255."""
    w, h = size
    base = rng.uniform(60, 200, 3)
    noise = cv2.GaussianBlur(rng.normal(0, 40, (h, w, 3)), (0, 0), 3)
    img = base + noise
    for _ in range(6):
        x0, y0 = rng.integers(0, w - 20), rng.integers(0, h - 20)
        img[y0:y0 + rng.integers(10, 40), x0:x0 + rng.integers(10, 40)] = rng.uniform(20, 235, 3)
    return np.clip(img, 0, 255)


def draw_figure(img: np.ndarray, cx: float, phase: float, colors, scale: float = 1.0):
    """Draw a stick figure with thick limbs centred at x = cx; returns its mask."""
    h, w = img.shape[:2]
    mask = np.zeros((h, w), np.uint8)
    s = scale
    top = int(h * 0.15)
    hip = (int(cx), int(top + 50 * s))
    neck = (int(cx), int(top + 14 * s))
    swing = 14 * s * np.sin(phase)
    parts = [
        ("line", neck, hip, 9 * s, colors[0]),                                   # torso
        ("line", neck, (int(cx - 16 * s), int(top + 38 * s + swing / 3)), 4 * s, colors[0]),   # arms
        ("line", neck, (int(cx + 16 * s), int(top + 38 * s - swing / 3)), 4 * s, colors[0]),
        ("line", hip, (int(cx - swing), int(top + 85 * s)), 5 * s, colors[1]),   # legs
        ("line", hip, (int(cx + swing), int(top + 85 * s)), 5 * s, colors[1]),
        ("circle", (int(cx), int(top + 6 * s)), None, 7 * s, colors[2]),          # head
    ]
    for kind, a, b, r, col in parts:
        for target, value in ((img, tuple(float(c) for c in col)), (mask, 1)):
            if kind == "line":
                cv2.line(target, a, b, value, int(round(2 * r)), lineType=cv2.LINE_8)
            else:
                cv2.circle(target, a, int(round(r)), value, -1, lineType=cv2.LINE_8)
    return mask.astype(bool)


def moving_figure_video(seed: int, n_frames: int = 30, size=SIZE, x_range=(30, 130), colors=None,
                        background=None):
    """Frames (T, H, W, 3) uint8 RGB and ground-truth masks (T, H, W) bool."""
    rng = np.random.default_rng(seed)
    bg = textured_background(rng, size) if background is None else background.astype(float)
    cols = colors if colors is not None else [rng.uniform(0, 255, 3) for _ in range(3)]
    frames, masks = [], []
    for t in range(n_frames):
        img = bg.copy()
        cx = x_range[0] + (x_range[1] - x_range[0]) * t / max(n_frames - 1, 1)
        m = draw_figure(img, cx, 0.5 * t, cols)
        img = img * (1 + rng.uniform(-FLICKER, FLICKER)) + rng.normal(0, NOISE_SIGMA, img.shape)
        frames.append(np.clip(np.round(img), 0, 255).astype(np.uint8))
        masks.append(m)
    return np.stack(frames), np.stack(masks)
