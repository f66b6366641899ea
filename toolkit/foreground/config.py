"""Configuration of foreground extraction (source 000 §2.1: "a coarse segmentation of the
subject from the background, e.g. by chroma keying or background subtraction").

Every default is defined once, here, with its reason.  Images are RGB uint8
``(H, W, 3)``; thresholds are in the same 0-255 units.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toolkit.errors import InputError

#: Background methods: per-pixel median of a frame subsample, OpenCV MOG2, OpenCV KNN.
BACKGROUND_METHODS = ("median", "mog2", "knn")
#: Foreground methods of :class:`ForegroundConfig`.
FOREGROUND_METHODS = ("background", "chroma")
#: Dense optical-flow methods for motion compensation.
FLOW_METHODS = ("dis", "farneback")

#: Frames sampled (evenly over the video) to learn the background.  25 frames make the
#: median robust to a subject covering a pixel in up to 12 of them.
BACKGROUND_SAMPLES = 25
#: Smallest colour distance (max over RGB channels, 0-255) counted as foreground for the
#: median model; compression noise and small illumination changes stay below it.
MEDIAN_MIN_THRESHOLD = 25.0
#: Foreground when the distance also exceeds this many robust standard deviations of the
#: pixel's own variation over the samples (flickering screens, waving flags).
MEDIAN_SIGMA_FACTOR = 4.0

#: Median model, weak evidence (hysteresis): the colour difference to the background is
#: smoothed (Gaussian, :data:`WEAK_BLUR_PX`), and pixels whose smoothed difference exceeds
#: this many robust standard deviations of the frame's own background noise (measured on the
#: frame, away from the strong foreground) join the silhouette when they touch it.  A kit close
#: to the backdrop differs from it by a coherent shift that smoothing keeps while it averages
#: the compression noise away: on zoo seed 13 a grass-green kit's silhouette went from 0.76-0.87
#: to 0.86-0.96 IoU (docs/stage1_silhouettes.md, "Silhouette area").  0 turns it off.
WEAK_SIGMA_FACTOR = 4.0
#: Smallest weak threshold (0-255, smoothed max-channel difference), for noiseless renderings.
WEAK_MIN_THRESHOLD = 6.0
#: Standard deviation of the Gaussian smoothing of the weak evidence, pixels.
WEAK_BLUR_PX = 1.0
#: Median model, border trimming: a pixel on the silhouette's border is kept only when its
#: colour is at least this fraction of the way from the background to the subject's colour
#: next to it (its opacity, the projection of I - B on F - B).  Blended border pixels (anti-
#: aliasing, MPEG-4's colour bleed) otherwise make the silhouette 2-8 % too large at broadcast
#: scale, where a pixel's width is a tenth of a forearm.  0 turns it off.
BORDER_ALPHA = 0.5
#: Border trimming judges a pixel only where subject and background differ by at least this
#: much (Euclidean RGB, 0-255): with less contrast the opacity is noise.
BORDER_MIN_CONTRAST = 40.0
#: Border layers trimmed (each pass looks at the outermost layer again).
BORDER_PASSES = 2
#: Side of the window in which the subject's colour next to a border pixel is averaged, pixels.
BORDER_WINDOW_PX = 5

#: Chroma key for a green screen, OpenCV HSV units (H in 0-179, S and V in 0-255):
#: green hues 35-85 (70-170 degrees), saturation >= 60, value >= 40.  Darker or greyer
#: pixels are never keyed out, so shadows on the screen count as foreground: lower
#: ``sat_min`` for strongly lit screens.
GREEN_HUE_RANGE = (35, 85)
GREEN_SAT_MIN = 60
GREEN_VAL_MIN = 40

#: Morphological opening radius (pixels): removes isolated noise pixels.
OPEN_RADIUS_PX = 1
#: Morphological closing radius (pixels): bridges one-pixel gaps inside the body.  Larger
#: radii glue arms to the torso and legs together at broadcast scale (a player 80 px tall):
#: IoU 0.97 with 1 px, 0.93 with 3 px on the rendered test scenes (docs/stage1_multiview.md).
CLOSE_RADIUS_PX = 1
#: Connected components kept, largest first (one subject per view by default).
KEEP_COMPONENTS = 1
#: Components smaller than this fraction of the largest are dropped even when kept by count.
MIN_COMPONENT_FRACTION = 0.05
#: Fill background regions enclosed by the silhouette.  Off by default: the gap between an
#: arm touching the hip and the torso is background, and filling it cost more IoU than the
#: rare true holes gave.
FILL_HOLES = False
#: A component nearer to the subject than this fraction of the subject's bounding-box height
#: joins it (a limb cut off by a thin gap, e.g. a pitch line or a colour match): 0.15 of a
#: person's height is about a forearm's thickness times three.
MERGE_FRACTION = 0.15

#: Motion compensation: where the warped previous mask says "subject", the median model's
#: threshold is multiplied by this (weaker evidence suffices).
PRIOR_THRESHOLD_SCALE = 0.5
#: Motion compensation for binary detectors (MOG2, KNN, chroma): previous-mask pixels in
#: gaps of the current detection that a closing of this radius (pixels) would fill are added.
PRIOR_REACH_PX = 3

#: A silhouette smaller than this (pixels) is "empty".
MIN_SILHOUETTE_PX = 30
#: A silhouette covering more than this fraction of the image is "full" (a lighting change or
#: a camera move, not a person).
FULL_FRACTION = 0.6


def _positive(where, value, allow_zero=False):
    ok = np.isfinite(value) and (value >= 0 if allow_zero else value > 0)
    if not ok:
        raise InputError(where, "a finite value " + (">= 0" if allow_zero else "> 0"), repr(value))


@dataclass(frozen=True)
class BackgroundConfig:
    """Background model options.

    Parameters
    ----------
    method : str
        ``"median"`` (default, chosen by measured IoU, see ``docs/stage1_multiview.md``),
        ``"mog2"`` or ``"knn"`` (OpenCV subtractors trained on the samples, then applied
        without learning).
    n_samples : int
        Frames sampled evenly over the video to learn the background.
    min_threshold : float
        Median model: smallest colour distance counted as foreground (0-255).
    sigma_factor : float
        Median model: robust standard deviations of a pixel's variation counted as foreground.
    mog2_var_threshold : float
        OpenCV MOG2 ``varThreshold`` (squared Mahalanobis distance).
    knn_dist2_threshold : float
        OpenCV KNN ``dist2Threshold`` (squared distance).
    weak_sigma_factor : float
        Median model: weak evidence threshold in robust standard deviations of the frame's
        background noise (hysteresis, :data:`WEAK_SIGMA_FACTOR`); 0 turns it off.
    weak_min_threshold : float
        Median model: smallest weak threshold (0-255).
    weak_blur_px : float
        Median model: Gaussian smoothing of the weak evidence, pixels.
    border_alpha : float
        Median model: smallest opacity of a border pixel kept (:data:`BORDER_ALPHA`); 0 turns
        the trimming off.
    border_min_contrast : float
        Median model: border pixels are judged only where subject and background differ by
        at least this much (Euclidean RGB, 0-255).
    border_passes : int
        Border layers trimmed.
    border_window_px : int
        Window (odd side, pixels) averaging the subject's colour next to a border pixel.
    """

    method: str = "median"
    n_samples: int = BACKGROUND_SAMPLES
    min_threshold: float = MEDIAN_MIN_THRESHOLD
    sigma_factor: float = MEDIAN_SIGMA_FACTOR
    mog2_var_threshold: float = 16.0
    knn_dist2_threshold: float = 400.0
    weak_sigma_factor: float = WEAK_SIGMA_FACTOR
    weak_min_threshold: float = WEAK_MIN_THRESHOLD
    weak_blur_px: float = WEAK_BLUR_PX
    border_alpha: float = BORDER_ALPHA
    border_min_contrast: float = BORDER_MIN_CONTRAST
    border_passes: int = BORDER_PASSES
    border_window_px: int = BORDER_WINDOW_PX

    def __post_init__(self):
        if self.method not in BACKGROUND_METHODS:
            raise InputError("BackgroundConfig.method", f"one of {list(BACKGROUND_METHODS)}", repr(self.method))
        if int(self.n_samples) != self.n_samples or self.n_samples < 1:
            raise InputError("BackgroundConfig.n_samples", "an integer >= 1", repr(self.n_samples))
        for name in ("min_threshold", "sigma_factor", "mog2_var_threshold", "knn_dist2_threshold",
                     "weak_sigma_factor", "weak_min_threshold", "border_min_contrast"):
            _positive(f"BackgroundConfig.{name}", getattr(self, name), allow_zero=True)
        _positive("BackgroundConfig.weak_blur_px", self.weak_blur_px)
        if not 0 <= self.border_alpha < 1:
            raise InputError("BackgroundConfig.border_alpha", "a value in [0, 1)", repr(self.border_alpha))
        if int(self.border_passes) != self.border_passes or self.border_passes < 0:
            raise InputError("BackgroundConfig.border_passes", "an integer >= 0", repr(self.border_passes))
        w = self.border_window_px
        if int(w) != w or w < 3 or w % 2 == 0:
            raise InputError("BackgroundConfig.border_window_px", "an odd integer >= 3", repr(w))


@dataclass(frozen=True)
class ChromaKeyConfig:
    """HSV range of the screen colour (OpenCV units: H 0-179, S and V 0-255).

    Defaults key out a green screen (:data:`GREEN_HUE_RANGE`, :data:`GREEN_SAT_MIN`,
    :data:`GREEN_VAL_MIN`).  For blue, ``hue_range=(95, 130)``.
    """

    hue_range: tuple[int, int] = GREEN_HUE_RANGE
    sat_min: int = GREEN_SAT_MIN
    val_min: int = GREEN_VAL_MIN

    def __post_init__(self):
        lo, hi = self.hue_range
        if not (0 <= lo <= 179 and 0 <= hi <= 179):
            raise InputError("ChromaKeyConfig.hue_range", "hues in 0..179 (OpenCV units)", repr(self.hue_range))
        for name in ("sat_min", "val_min"):
            v = getattr(self, name)
            if not 0 <= v <= 255:
                raise InputError(f"ChromaKeyConfig.{name}", "a value in 0..255", repr(v))


@dataclass(frozen=True)
class MorphologyConfig:
    """Clean-up of a raw foreground mask.

    Parameters
    ----------
    open_radius_px, close_radius_px : int
        Radii of the elliptical opening and closing (0 disables either).
    keep_components : int
        Largest connected components kept (0 keeps all).
    min_component_fraction : float
        Drop components smaller than this fraction of the largest.
    merge_fraction : float
        Components within this fraction of a kept component's bounding-box height join it.
    fill_holes : bool
        Fill holes enclosed by the silhouette.
    """

    open_radius_px: int = OPEN_RADIUS_PX
    close_radius_px: int = CLOSE_RADIUS_PX
    keep_components: int = KEEP_COMPONENTS
    min_component_fraction: float = MIN_COMPONENT_FRACTION
    merge_fraction: float = MERGE_FRACTION
    fill_holes: bool = FILL_HOLES

    def __post_init__(self):
        for name in ("open_radius_px", "close_radius_px", "keep_components"):
            v = getattr(self, name)
            if int(v) != v or v < 0:
                raise InputError(f"MorphologyConfig.{name}", "an integer >= 0", repr(v))
        if not 0 <= self.min_component_fraction <= 1:
            raise InputError("MorphologyConfig.min_component_fraction", "a value in [0, 1]",
                             repr(self.min_component_fraction))
        if not (np.isfinite(self.merge_fraction) and self.merge_fraction >= 0):
            raise InputError("MorphologyConfig.merge_fraction", "a finite value >= 0", repr(self.merge_fraction))


@dataclass(frozen=True)
class MotionConfig:
    """Motion compensation: the previous frame's mask, warped by dense optical flow, as a prior.

    Parameters
    ----------
    enabled : bool
    method : str
        ``"dis"`` (OpenCV DIS, fast) or ``"farneback"``.
    prior_threshold_scale : float
        Median model: threshold factor where the prior says "subject".
    prior_reach_px : int
        Binary detectors: prior pixels in gaps of the detection narrower than about twice
        this (pixels) are added.
    """

    enabled: bool = False
    method: str = "dis"
    prior_threshold_scale: float = PRIOR_THRESHOLD_SCALE
    prior_reach_px: int = PRIOR_REACH_PX

    def __post_init__(self):
        if self.method not in FLOW_METHODS:
            raise InputError("MotionConfig.method", f"one of {list(FLOW_METHODS)}", repr(self.method))
        if not 0 < self.prior_threshold_scale <= 1:
            raise InputError("MotionConfig.prior_threshold_scale", "a value in (0, 1]",
                             repr(self.prior_threshold_scale))
        if int(self.prior_reach_px) != self.prior_reach_px or self.prior_reach_px < 0:
            raise InputError("MotionConfig.prior_reach_px", "an integer >= 0", repr(self.prior_reach_px))


@dataclass(frozen=True)
class SilhouetteConfig:
    """When a mask is a usable silhouette.

    Parameters
    ----------
    min_area_px : int
        Smaller masks are ``"empty"``.
    full_fraction : float
        Masks covering more of the image are ``"full"``.
    border_margin_px : int
        A bounding box within this many pixels of the image edge ``"touches_border"``.
    """

    min_area_px: int = MIN_SILHOUETTE_PX
    full_fraction: float = FULL_FRACTION
    border_margin_px: int = 0

    def __post_init__(self):
        if int(self.min_area_px) != self.min_area_px or self.min_area_px < 1:
            raise InputError("SilhouetteConfig.min_area_px", "an integer >= 1", repr(self.min_area_px))
        if not 0 < self.full_fraction <= 1:
            raise InputError("SilhouetteConfig.full_fraction", "a value in (0, 1]", repr(self.full_fraction))
        if int(self.border_margin_px) != self.border_margin_px or self.border_margin_px < 0:
            raise InputError("SilhouetteConfig.border_margin_px", "an integer >= 0", repr(self.border_margin_px))


@dataclass(frozen=True)
class ForegroundConfig:
    """Everything :class:`~toolkit.foreground.ForegroundExtractor` needs.

    Parameters
    ----------
    method : str
        ``"background"`` (background subtraction, default) or ``"chroma"`` (chroma key).
    background, chroma, morphology, motion, silhouette
        Options of each step.
    """

    method: str = "background"
    background: BackgroundConfig = field(default_factory=BackgroundConfig)
    chroma: ChromaKeyConfig = field(default_factory=ChromaKeyConfig)
    morphology: MorphologyConfig = field(default_factory=MorphologyConfig)
    motion: MotionConfig = field(default_factory=MotionConfig)
    silhouette: SilhouetteConfig = field(default_factory=SilhouetteConfig)

    def __post_init__(self):
        if self.method not in FOREGROUND_METHODS:
            raise InputError("ForegroundConfig.method", f"one of {list(FOREGROUND_METHODS)}", repr(self.method))
