"""Multi-view selection of 2D pose candidates with per-view offsets (source 000, §2.1, claims 5-6).

See ``docs/stage1_multiview.md``.
"""

from toolkit.multiview.config import (
    FLIP_MODES,
    KEYPOINT_SIGMA_PX,
    MAX_OFFSET_PX,
    OFFSET_PRIOR_PX,
    REFINED_OFFSET_PRIOR_PX,
    REFINE_TOP,
    RESIDUALS,
    SOURCE_K,
    SOURCE_MAX_OFFSET_PX,
    MultiViewConfig,
)
from toolkit.multiview.keypoints import MIN_JOINT_CONFIDENCE, MIN_VIEW_CONFIDENCE, keypoints_to_candidates
from toolkit.multiview.offsets import (
    OffsetFit,
    corrected_rig,
    fit_offsets,
    gauge_basis,
    image_offsets,
    mean_ray_distance,
    offsets_modulo_gauge,
    triangulate_views,
)
from toolkit.multiview.selection import (
    MultiViewSelection,
    extend_candidates,
    flip_permutation,
    score_combinations,
    select_multiview,
)
from toolkit.multiview.sequence import MultiViewTracker, select_sequence, stack_selections

__all__ = [
    "FLIP_MODES", "KEYPOINT_SIGMA_PX", "MAX_OFFSET_PX", "OFFSET_PRIOR_PX", "REFINED_OFFSET_PRIOR_PX", "REFINE_TOP", "RESIDUALS",
    "SOURCE_K", "SOURCE_MAX_OFFSET_PX", "MultiViewConfig",
    "MIN_JOINT_CONFIDENCE", "MIN_VIEW_CONFIDENCE", "keypoints_to_candidates",
    "OffsetFit", "corrected_rig", "fit_offsets", "gauge_basis", "image_offsets", "mean_ray_distance", "offsets_modulo_gauge", "triangulate_views",
    "MultiViewSelection", "extend_candidates", "flip_permutation", "score_combinations", "select_multiview",
    "MultiViewTracker", "select_sequence", "stack_selections",
]
