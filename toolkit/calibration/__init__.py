"""Calibration refinement on the static scene: field models, line detection, camera refinement.

Runs before stage 1 when a dataset has a field model (``field_model.json``):
the measured broadcast cameras are corrected on the painted pitch lines, so
stage 1's per-view offsets only have to absorb what is left.
"""

from toolkit.calibration.dataset import (
    USED_CALIBRATION,
    background_image,
    cameras_for_run,
    refined_cameras,
    describe,
    refine_dataset,
    stage_rig,
)
from toolkit.calibration.field import FieldModel, read_field_model, soccer_pitch, write_field_model
from toolkit.calibration.lines import LineDetectorConfig, LinePoints, detect_line_points
from toolkit.calibration.refine import (
    RefineConfig,
    Refinement,
    apply_correction,
    calibration_error_px,
    refine_camera,
    refine_rig,
)

__all__ = ["USED_CALIBRATION", "background_image", "cameras_for_run", "refined_cameras", "describe", "refine_dataset", "stage_rig", "FieldModel", "read_field_model", "soccer_pitch", "write_field_model",
           "LineDetectorConfig", "LinePoints", "detect_line_points", "RefineConfig", "Refinement",
           "apply_correction", "calibration_error_px", "refine_camera", "refine_rig"]
