"""Stage 2a: the exact 3D template fit and the projected pre-segmented template (source 000 §2.2, claim 8)."""

from toolkit.template.database import (
    FRAMES_PER_MOTION,
    YAW_STEPS,
    ApproximatePose,
    PoseDatabase,
    approximate_pose,
    canonical_poses,
)
from toolkit.cameras import camera_with_offset  # where it lived before (stage 2's offset camera)
from toolkit.template.fit import (
    TemplatePose,
    default_database,
    exact_fit,
    fit_template_pose,
    standing_pose_in_box,
)
from toolkit.template.projection import (
    MIN_RADIUS_PX,
    N_PARTS,
    TEMPLATE_DETAIL,
    THIN_PART_FRACTION,
    THIN_THICK_FRACTION,
    Template,
    TemplateProjection,
    disc,
    subject_height_px,
    thin_thick,
)

__all__ = ["FRAMES_PER_MOTION", "YAW_STEPS", "ApproximatePose", "PoseDatabase", "approximate_pose",
           "canonical_poses", "TemplatePose", "camera_with_offset", "default_database", "exact_fit",
           "fit_template_pose", "standing_pose_in_box", "MIN_RADIUS_PX", "N_PARTS", "TEMPLATE_DETAIL",
           "THIN_PART_FRACTION", "THIN_THICK_FRACTION", "Template", "TemplateProjection", "disc",
           "subject_height_px", "thin_thick"]
