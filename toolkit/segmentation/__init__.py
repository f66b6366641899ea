"""Stage 2b: body-part segmentation with per-part Gaussian-mixture colour models (source 000 §2.3, claim 14)."""

from toolkit.segmentation.colour import COLOUR_SPACES, PartColourModels, colour_features, fit_part_models
from toolkit.segmentation.pipeline import TEMPLATE_POSES, PoseSource, segment_views
from toolkit.segmentation.plate import component_means, plate_alpha, refine_silhouette
from toolkit.segmentation.prior import (
    colour_confusion,
    colour_evidence,
    confusion_evidence,
    smooth_evidence,
    spatial_log_prior,
    template_distances,
)
from toolkit.segmentation.segment import (
    COLOUR_EVIDENCE,
    DEFAULT_COLOUR_SPACE,
    DEFAULT_COMPONENTS,
    FALLBACK_PART,
    RULES,
    SPATIAL_ANCHORS,
    SegmentationConfig,
    SegmentationResult,
    label_uncertain,
    part_iou,
    segment_frame,
)

__all__ = ["COLOUR_SPACES", "PartColourModels", "colour_features", "fit_part_models", "DEFAULT_COLOUR_SPACE",
           "DEFAULT_COMPONENTS", "FALLBACK_PART", "RULES", "SegmentationConfig", "SegmentationResult",
           "label_uncertain", "part_iou", "segment_frame", "PoseSource", "TEMPLATE_POSES", "segment_views",
           "COLOUR_EVIDENCE", "SPATIAL_ANCHORS", "colour_confusion", "colour_evidence", "confusion_evidence",
           "smooth_evidence", "spatial_log_prior", "template_distances", "component_means", "plate_alpha",
           "refine_silhouette"]
