"""Silhouette area against a clean plate: low-contrast kits and blended borders (issue 13).

The frames are rendered at 4x and area-averaged (anti-aliased borders, as the
scene generator's supersampling), blurred slightly and given sensor noise (as
a compressed video), and compared with the true mask (pixel centres on the
figure).
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from tests.foreground.foreground_scenes import draw_figure
from toolkit.foreground import BackgroundConfig, ForegroundConfig, ForegroundExtractor, mask_iou

#: Supersampling of the rendered test frames.
SUPERSAMPLE = 4
#: Sensor noise of the test frames (0-255), and the blur standing in for compression.
NOISE_SIGMA, BLUR_PX = 2.5, 0.6
#: Low-contrast kit: the shirt differs from the backdrop by this coherent shift (0-255 per channel),
#: below the median model's 25-unit floor.
KIT_SHIFT = np.array([-9.0, 14.0, -6.0])
#: Bounds met by the default foreground (measured 0.974-0.980 IoU, area ratio 1.003-1.014, seeds 0-3) ...
MIN_IOU_LOW_CONTRAST, AREA_RATIO_BOUNDS = 0.93, (0.95, 1.05)
#: ... and what the weak evidence must add over the strong threshold alone (measured: 0.29-0.42 IoU
#: without it, the shirt lost).
MIN_IOU_GAIN = 0.3
#: A high-contrast figure 90 px tall: blended border pixels must not make it larger than this
#: (measured 1.02-1.04 trimmed, 1.30 untrimmed).
MAX_AREA_RATIO_HIGH_CONTRAST = 1.06


def render(seed: int, kit_like_backdrop: bool, scale: float = 2.0, size=(200, 240)):
    """One frame, its clean plate and the true mask."""
    rng = np.random.default_rng(seed)
    w, h = size
    s = SUPERSAMPLE
    base = np.array([70.0, 140.0, 60.0]) + rng.uniform(-10, 10, 3)  # a grass-like backdrop
    plate = base + cv2.GaussianBlur(rng.normal(0, 30, (h, w, 3)), (0, 0), 1.5)
    big_plate = cv2.resize(plate, (w * s, h * s), interpolation=cv2.INTER_NEAREST)
    shirt = base + KIT_SHIFT if kit_like_backdrop else rng.uniform(150, 250, 3)
    colours = [shirt, rng.uniform(0, 60, 3), np.array([200.0, 160.0, 130.0])]
    big = big_plate.copy()
    big_mask = draw_figure(big, cx=w * s / 2, phase=float(rng.uniform(0, 2 * np.pi)), colors=colours,
                           scale=scale * s)
    img = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA)
    truth = cv2.resize(big_mask.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA) >= 0.5

    def finish(x):
        x = cv2.GaussianBlur(x, (0, 0), BLUR_PX) + rng.normal(0, NOISE_SIGMA, x.shape)
        return np.clip(np.round(x), 0, 255).astype(np.uint8)

    return finish(img), finish(plate), truth


def silhouette(frame, plate, config=None):
    return ForegroundExtractor(config or ForegroundConfig()).fit([plate]).extract(frame).mask


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_low_contrast_kit_keeps_its_area(seed):
    frame, plate, truth = render(seed, kit_like_backdrop=True)
    mask = silhouette(frame, plate)
    iou, ratio = mask_iou(mask, truth), mask.sum() / truth.sum()
    assert iou >= MIN_IOU_LOW_CONTRAST, f"IoU {iou:.3f}"
    assert AREA_RATIO_BOUNDS[0] <= ratio <= AREA_RATIO_BOUNDS[1], f"area ratio {ratio:.3f}"
    strong_only = ForegroundConfig(background=replace(BackgroundConfig(), weak_sigma_factor=0.0))
    iou_strong = mask_iou(silhouette(frame, plate, strong_only), truth)
    assert iou - iou_strong >= MIN_IOU_GAIN, f"weak evidence adds {iou - iou_strong:.3f} IoU"


@pytest.mark.parametrize("seed", [0, 1])
def test_blended_border_pixels_leave(seed):
    frame, plate, truth = render(seed, kit_like_backdrop=False, scale=1.0, size=(120, 130))
    mask = silhouette(frame, plate)
    untrimmed = silhouette(frame, plate, ForegroundConfig(background=replace(BackgroundConfig(), border_alpha=0.0)))
    ratio, ratio_untrimmed = mask.sum() / truth.sum(), untrimmed.sum() / truth.sum()
    assert ratio <= MAX_AREA_RATIO_HIGH_CONTRAST, f"area ratio {ratio:.3f} (untrimmed {ratio_untrimmed:.3f})"
    assert mask_iou(mask, truth) >= mask_iou(untrimmed, truth)


def test_border_options_are_checked():
    from toolkit.errors import InputError

    with pytest.raises(InputError, match="border_alpha"):
        BackgroundConfig(border_alpha=1.5)
    with pytest.raises(InputError, match="border_window_px"):
        BackgroundConfig(border_window_px=4)
    with pytest.raises(InputError, match="weak_blur_px"):
        BackgroundConfig(weak_blur_px=0.0)
