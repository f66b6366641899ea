"""Joint centres from marker trajectories (source 004): marker sets, synthetic captures, labelling, centres."""

from toolkit.markers.capture import MarkerCapture, load_marker_capture
from toolkit.markers.functional import JointCentresConfig, JointCentresResult, joint_centres
from toolkit.markers.label import LabelConfig, label_capture
from toolkit.markers.marker_sets import MARKER_SETS, MarkerSet, Placement, get_marker_set
from toolkit.markers.trajectories import (
    BRIDGED,
    FROM_FILE,
    MISSING,
    TRINOCULAR,
    TWO_VIEW,
    MarkerTrajectories,
)

__all__ = ["MARKER_SETS", "MarkerSet", "Placement", "get_marker_set", "MarkerTrajectories", "MISSING",
           "TRINOCULAR", "TWO_VIEW", "BRIDGED", "FROM_FILE", "MarkerCapture", "load_marker_capture",
           "JointCentresConfig", "JointCentresResult", "joint_centres", "LabelConfig", "label_capture"]
