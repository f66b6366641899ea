"""Foreground extraction: background models, chroma keying, morphological clean-up,
motion compensation by optical flow, silhouettes with bounding boxes and states
(source 000, §2.1).  See ``docs/stage1_multiview.md``.
"""

from toolkit.foreground.background import BackgroundModel, sample_indices
from toolkit.foreground.chroma import chroma_key, screen_mask
from toolkit.foreground.config import (
    BACKGROUND_METHODS,
    FULL_FRACTION,
    GREEN_HUE_RANGE,
    GREEN_SAT_MIN,
    GREEN_VAL_MIN,
    MIN_SILHOUETTE_PX,
    BackgroundConfig,
    ChromaKeyConfig,
    ForegroundConfig,
    MorphologyConfig,
    MotionConfig,
    SilhouetteConfig,
)
from toolkit.foreground.extract import ForegroundExtractor, extract_silhouettes
from toolkit.foreground.morphology import clean_mask, fill_holes, keep_largest_components
from toolkit.foreground.motion import dense_flow, warp_previous_mask
from toolkit.foreground.seeded import (
    RefineConfig,
    SeededConfig,
    SeededMask,
    SeededSegmenter,
    body_scale,
    refine_masks,
    seed_trimap,
)
from toolkit.foreground.silhouette import STATES, Silhouette, bounding_box, mask_iou, silhouette_from_mask

__all__ = [
    "BackgroundModel", "sample_indices", "chroma_key", "screen_mask",
    "BACKGROUND_METHODS", "FULL_FRACTION", "GREEN_HUE_RANGE", "GREEN_SAT_MIN", "GREEN_VAL_MIN",
    "MIN_SILHOUETTE_PX", "BackgroundConfig", "ChromaKeyConfig", "ForegroundConfig", "MorphologyConfig",
    "MotionConfig", "SilhouetteConfig", "ForegroundExtractor", "extract_silhouettes", "clean_mask",
    "fill_holes", "keep_largest_components", "dense_flow", "warp_previous_mask", "STATES", "Silhouette",
    "bounding_box", "mask_iou", "silhouette_from_mask",
    "RefineConfig", "SeededConfig", "SeededMask", "SeededSegmenter", "body_scale", "refine_masks", "seed_trimap",
]
