"""Background models learned over a video.

* ``"median"``: the per-pixel median of an even subsample of frames; a pixel is
  foreground when its colour distance (max over RGB channels) to the median
  exceeds both a fixed floor and a multiple of the pixel's own robust spread
  over the samples.  A subject that stands still on a pixel for more than half
  of the samples becomes background there (use chroma keying or more samples).
* ``"mog2"``, ``"knn"``: OpenCV's adaptive mixture and k-nearest-neighbour
  subtractors, trained on the same samples and then applied without learning,
  so the subject never fades into the background; their shadow label counts as
  background.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from toolkit.errors import InputError
from toolkit.foreground.config import BackgroundConfig

#: Scale from the median absolute deviation to a standard deviation (normal noise).
MAD_TO_SIGMA = 1.4826
#: Frames fed to the OpenCV subtractors while training (the samples, cycled); also their history.
SUBTRACTOR_TRAINING_FRAMES = 200
#: Margin around the strong foreground left out of the frame's noise estimate, pixels.
NOISE_MARGIN_PX = 7
#: The noise estimate reads every this many rows and columns (a 1080p frame still gives
#: ~130 000 samples).
NOISE_SAMPLE_STEP_PX = 4
#: Share of the OpenCV subtractors' weight (MOG2) or stored samples (KNN) a colour needs to
#: be background: a majority, like the median model.
SUBTRACTOR_MAJORITY = 0.5


def frame_count(frames) -> int:
    """Number of frames of a sequence (array, list, :class:`~toolkit.io.VideoReader`)."""
    try:
        return len(frames)
    except TypeError:
        raise InputError("frames", "a sequence of frames with a length (array, list, VideoReader)",
                         type(frames).__name__) from None


def frame_at(frames, i: int) -> np.ndarray:
    """Frame ``i`` of an array, list or object with ``read(i)``."""
    if hasattr(frames, "read") and not isinstance(frames, (np.ndarray, list, tuple)):
        return np.asarray(frames.read(i))
    return np.asarray(frames[i])


def check_rgb(image, where: str, size: tuple[int, int] | None = None) -> np.ndarray:
    """Validate an RGB uint8 image, optionally of a given (H, W)."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise InputError(where, "an RGB uint8 image (H, W, 3)", f"shape {img.shape}, dtype {img.dtype}")
    if size is not None and img.shape[:2] != tuple(size):
        raise InputError(where, f"an image of size (H, W) = {tuple(size)}",
                         f"{img.shape[:2]}")
    return img


def sample_indices(n_frames: int, n_samples: int) -> np.ndarray:
    """``n_samples`` frame indices spread evenly over ``n_frames`` (all when fewer)."""
    if n_frames < 1:
        raise InputError("frames", "at least one frame", "none")
    return np.unique(np.round(np.linspace(0, n_frames - 1, min(n_samples, n_frames))).astype(int))


class BackgroundModel:
    """A background learned from frames of one static camera.

    Use :meth:`fit`; then :meth:`foreground` per frame.

    Attributes
    ----------
    config : BackgroundConfig
    background : ndarray of shape (H, W, 3), uint8
        The median image (median method) or OpenCV's background image.
    threshold : ndarray of shape (H, W) or None
        Median method: per-pixel colour-distance threshold (0-255 units).
    """

    def __init__(self, config: BackgroundConfig, background: np.ndarray, threshold: np.ndarray | None,
                 subtractor=None):
        self.config = config
        self.background = background
        self.threshold = threshold
        self._subtractor = subtractor

    @property
    def size(self) -> tuple[int, int]:
        """Image (H, W)."""
        return self.background.shape[:2]

    @classmethod
    def fit(cls, frames: Sequence[np.ndarray] | np.ndarray, config: BackgroundConfig | None = None
            ) -> "BackgroundModel":
        """Learn the background from an even subsample of ``frames``.

        Parameters
        ----------
        frames : sequence of ndarray of shape (H, W, 3), uint8 RGB
            An array ``(T, H, W, 3)``, a list, or a :class:`~toolkit.io.VideoReader`.
        config : BackgroundConfig, optional

        Returns
        -------
        BackgroundModel
        """
        cfg = config or BackgroundConfig()
        idx = sample_indices(frame_count(frames), cfg.n_samples)
        first = check_rgb(frame_at(frames, int(idx[0])), f"frames[{idx[0]}]")
        samples = [first] + [check_rgb(frame_at(frames, int(i)), f"frames[{i}]", first.shape[:2]) for i in idx[1:]]
        if cfg.method == "median":
            stack = np.stack(samples).astype(np.int16)
            med = np.median(stack, axis=0)
            spread = np.median(np.abs(stack - med[None]), axis=0).max(axis=-1) * MAD_TO_SIGMA
            thr = np.maximum(cfg.min_threshold, cfg.sigma_factor * spread)
            return cls(cfg, np.round(med).astype(np.uint8), thr.astype(np.float32))
        if cfg.method == "mog2":
            sub = cv2.createBackgroundSubtractorMOG2(history=SUBTRACTOR_TRAINING_FRAMES, varThreshold=cfg.mog2_var_threshold,
                                                     detectShadows=True)
            # a mode is background only when it holds most of the weight: a subject passing
            # a pixel in up to half of the samples stays foreground (as with the median)
            sub.setBackgroundRatio(SUBTRACTOR_MAJORITY)
        else:
            sub = cv2.createBackgroundSubtractorKNN(history=SUBTRACTOR_TRAINING_FRAMES, dist2Threshold=cfg.knn_dist2_threshold,
                                                    detectShadows=True)
            sub.setkNNSamples(int(np.ceil(SUBTRACTOR_MAJORITY * sub.getNSamples())))
        # OpenCV's subtractors weigh early frames heavily; cycling over the samples makes each
        # mode's weight converge to how often the pixel showed it
        bgr = [cv2.cvtColor(s, cv2.COLOR_RGB2BGR) for s in samples]
        for _ in range(max(1, -(-SUBTRACTOR_TRAINING_FRAMES // len(bgr)))):
            for s in bgr:
                sub.apply(s, learningRate=-1)
        bg = cv2.cvtColor(sub.getBackgroundImage(), cv2.COLOR_BGR2RGB)
        return cls(cfg, bg, None, sub)

    def distance(self, frame: np.ndarray) -> np.ndarray:
        """Colour distance to the background, max over RGB channels, (H, W) float32 (0-255)."""
        img = check_rgb(frame, "frame", self.size)
        r, g, b = cv2.split(cv2.absdiff(img, self.background))
        return cv2.max(cv2.max(r, g), b).astype(np.float32)

    def foreground(self, frame: np.ndarray, prior: np.ndarray | None = None,
                   prior_threshold_scale: float = 1.0) -> np.ndarray:
        """Raw foreground mask of one frame, (H, W) bool.

        Parameters
        ----------
        frame : ndarray of shape (H, W, 3), uint8 RGB
        prior : ndarray of shape (H, W) of bool, optional
            Median method: where the subject is expected (e.g. the warped previous mask),
            the threshold is multiplied by ``prior_threshold_scale``.  Ignored by the
            OpenCV subtractors (see :class:`~toolkit.foreground.ForegroundExtractor`).
        prior_threshold_scale : float
        """
        img = check_rgb(frame, "frame", self.size)
        if self._subtractor is None:
            thr = self.threshold
            if prior is not None:
                thr = np.where(np.asarray(prior, bool), thr * prior_threshold_scale, thr)
            strong = self.distance(img) > thr
            return self._with_weak_evidence(img, strong)
        out = self._subtractor.apply(cv2.cvtColor(img, cv2.COLOR_RGB2BGR), learningRate=0)
        return out == 255  # 127 = shadow

    def weak_threshold(self, smoothed: np.ndarray, strong: np.ndarray) -> float:
        """Weak-evidence threshold of one frame (0-255): the frame's own background noise.

        Parameters
        ----------
        smoothed : ndarray of shape (H, W, 3), float32
            The smoothed signed difference to the background.
        strong : ndarray of shape (H, W) of bool
            Strong foreground, left out of the noise estimate with a margin.

        Returns
        -------
        float
            ``max(weak_min_threshold, weak_sigma_factor * sigma)`` with ``sigma`` the largest
            per-channel robust standard deviation (median absolute value x 1.4826) of
            ``smoothed`` away from the strong foreground.
        """
        cfg = self.config
        away = cv2.dilate(strong.astype(np.uint8), np.ones((2 * NOISE_MARGIN_PX + 1,) * 2, np.uint8)) == 0
        step = NOISE_SAMPLE_STEP_PX
        sub, sub_away = smoothed[::step, ::step], away[::step, ::step]
        sample = sub[sub_away] if sub_away.any() else sub.reshape(-1, 3)
        sigma = float(np.max(np.median(np.abs(sample), axis=0))) * MAD_TO_SIGMA
        return max(cfg.weak_min_threshold, cfg.weak_sigma_factor * sigma)

    def _with_weak_evidence(self, img: np.ndarray, strong: np.ndarray) -> np.ndarray:
        """Strong foreground plus the weak-evidence regions that touch it (hysteresis)."""
        cfg = self.config
        if not cfg.weak_sigma_factor or not strong.any():
            return strong
        diff = img.astype(np.float32) - self.background.astype(np.float32)
        smoothed = cv2.GaussianBlur(diff, (0, 0), cfg.weak_blur_px)
        r, g, b = cv2.split(np.abs(smoothed))
        weak = cv2.max(cv2.max(r, g), b) > self.weak_threshold(smoothed, strong)
        n, lab = cv2.connectedComponents((weak | strong).astype(np.uint8), connectivity=8)
        keep = np.zeros(max(n, 256), np.uint8)
        keep[np.unique(lab[strong])] = 1
        keep[0] = 0
        if n <= 256:  # a table lookup on uint8 labels is ~10x faster than fancy indexing
            return cv2.LUT(lab.astype(np.uint8), keep[:256]) > 0
        return keep[lab] > 0

    def trim_border(self, frame: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """Drop border pixels that are more background than subject (median model).

        Each pixel of the mask's outer layer is compared with the background ``B`` and the
        subject's colour ``F`` next to it (the mean of the mask's interior pixels in a
        ``border_window_px`` window): its opacity is the projection
        ``alpha = (I - B) . (F - B) / |F - B|^2``; where ``|F - B|`` reaches
        ``border_min_contrast`` and ``alpha < border_alpha`` the pixel leaves.  Repeated
        ``border_passes`` times.

        Parameters
        ----------
        frame : ndarray of shape (H, W, 3), uint8 RGB
        mask : ndarray of shape (H, W) of bool

        Returns
        -------
        ndarray of shape (H, W) of bool
            The mask itself for the OpenCV subtractors or with the trimming off.
        """
        cfg = self.config
        img = check_rgb(frame, "frame", self.size)
        m = np.asarray(mask, bool)
        if self._subtractor is not None or not cfg.border_alpha or not m.any():
            return m
        # only the mask's neighbourhood matters: work in its bounding box plus the window
        rows, cols = np.flatnonzero(m.any(axis=1)), np.flatnonzero(m.any(axis=0))
        pad = cfg.border_window_px
        y0, y1 = max(rows[0] - pad, 0), min(rows[-1] + pad + 1, m.shape[0])
        x0, x1 = max(cols[0] - pad, 0), min(cols[-1] + pad + 1, m.shape[1])
        full, m = m, m[y0:y1, x0:x1].copy()
        I = img[y0:y1, x0:x1].astype(np.float32)
        B = self.background[y0:y1, x0:x1].astype(np.float32)
        IB = I - B
        win = (cfg.border_window_px, cfg.border_window_px)
        for _ in range(cfg.border_passes):
            interior = cv2.erode(m.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(np.float32)
            cnt = cv2.boxFilter(interior, -1, win, normalize=False)
            F = cv2.boxFilter(I * interior[..., None], -1, win, normalize=False) / np.maximum(cnt, 1e-6)[..., None]
            FB = F - B
            den = np.sum(FB * FB, axis=-1)
            alpha = np.sum(IB * FB, axis=-1) / np.maximum(den, 1e-6)
            judged = m & (interior == 0) & (cnt > 0) & (den >= cfg.border_min_contrast ** 2)
            drop = judged & (alpha < cfg.border_alpha)
            if not drop.any():
                break
            m = m & ~drop
        out = full.copy()
        out[y0:y1, x0:x1] = m
        return out
