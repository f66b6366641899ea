"""Calibration: from scratch (boards, scene points, people) and refinement on the static scene.

Calibration from scratch (issue 21, docs/calibration.md): :mod:`~toolkit.calibration.boards`,
:mod:`~toolkit.calibration.intrinsics`, :mod:`~toolkit.calibration.extrinsics`,
:mod:`~toolkit.calibration.bundle`, :mod:`~toolkit.calibration.checks`.

Runs before stage 1 when a dataset has a field model (``field_model.json``):
the measured broadcast cameras are corrected on the painted pitch lines, so
stage 1's per-view offsets only have to absorb what is left.
"""

from toolkit.calibration.boards import Board, BoardDetection, board_frames, detect_board, detect_in_frames, read_board_toml
from toolkit.calibration.checks import cameras_under_floor, mirrored_person_warning, person_chirality
from toolkit.calibration.extrinsics import (
    ExtrinsicsResult,
    PeopleConfig,
    extrinsics_from_boards,
    extrinsics_from_people,
    extrinsics_from_scene_points,
    similarity_align,
)
from toolkit.calibration.intrinsics import IntrinsicsConfig, IntrinsicsResult, calibrate_intrinsics
from toolkit.calibration.scene_points import read_scene_points
from toolkit.calibration.dataset import (
    USED_CALIBRATION,
    background_image,
    cameras_for_run,
    refined_cameras,
    describe,
    refine_dataset,
    stage_rig,
)
from toolkit.calibration.field import soccer_pitch
from toolkit.io.field_model import FieldModel, read_field_model, write_field_model  # the file type, re-exported
from toolkit.calibration.lines import LineDetectorConfig, LinePoints, detect_line_points
from toolkit.calibration.refine import (
    RefineConfig,
    Refinement,
    apply_correction,
    calibration_error_px,
    refine_camera,
    refine_rig,
)

__all__ = ["Board", "BoardDetection", "board_frames", "detect_board", "detect_in_frames", "read_board_toml",
           "cameras_under_floor", "mirrored_person_warning", "person_chirality", "ExtrinsicsResult", "PeopleConfig",
           "extrinsics_from_boards", "extrinsics_from_people", "extrinsics_from_scene_points", "similarity_align",
           "IntrinsicsConfig", "IntrinsicsResult", "calibrate_intrinsics", "read_scene_points",
           "USED_CALIBRATION", "background_image", "cameras_for_run", "refined_cameras", "describe", "refine_dataset", "stage_rig", "FieldModel", "read_field_model", "soccer_pitch", "write_field_model",
           "LineDetectorConfig", "LinePoints", "detect_line_points", "RefineConfig", "Refinement",
           "apply_correction", "calibration_error_px", "refine_camera", "refine_rig"]
