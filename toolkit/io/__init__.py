"""File input and output: calibration files, videos, the dataset layout, field models, atomic writes.

Only this subpackage reads and writes files; every write is atomic.
"""

from toolkit.io.atomic import (
    atomic_path,
    atomic_save_npz,
    atomic_write_bytes,
    atomic_write_png,
    atomic_write_text,
    encode_png,
    temp_path,
)
from toolkit.io.calibration import (
    calibration_toml_text,
    read_calibration,
    read_calibration_metadata,
    read_calibration_toml,
    read_calibration_yaml,
    write_calibration,
    write_calibration_toml,
    write_calibration_yaml,
)
from toolkit.io.dataset import Dataset, DatasetLayout
from toolkit.io.field_model import FieldModel, read_field_model, write_field_model
from toolkit.io.frames import depth_to_mm, frame_filename, mm_to_depth, read_png
from toolkit.io.pose2sim_import import ImportResult, import_pose2sim_trial
from toolkit.io.video import (
    VideoInfo,
    VideoReader,
    VideoWriter,
    count_frames,
    probe_video,
    write_video,
)
from toolkit.io.writer import DatasetWriter

__all__ = [
    "atomic_path",
    "atomic_save_npz",
    "atomic_write_bytes",
    "atomic_write_png",
    "atomic_write_text",
    "encode_png",
    "temp_path",
    "calibration_toml_text",
    "read_calibration",
    "read_calibration_metadata",
    "read_calibration_toml",
    "read_calibration_yaml",
    "write_calibration",
    "write_calibration_toml",
    "write_calibration_yaml",
    "Dataset",
    "DatasetLayout",
    "DatasetWriter",
    "FieldModel",
    "read_field_model",
    "write_field_model",
    "depth_to_mm",
    "frame_filename",
    "mm_to_depth",
    "read_png",
    "ImportResult",
    "import_pose2sim_trial",
    "VideoInfo",
    "VideoReader",
    "VideoWriter",
    "count_frames",
    "probe_video",
    "write_video",
]
