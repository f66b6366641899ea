"""Skeleton fitting and tracking in depth-camera point clouds (source 001).

A markerless 13-point skeleton fitted and tracked over time in the point cloud
of a depth camera, with a fitting cost that does not depend on the depth
resolution.  Stages, one module each:

=================  ============================================================
module             stage
=================  ============================================================
``orus``           the orthographic user grid (fixed bin size)
``curvature``      curvature centres and osculating spheres
``radial``         the radial-distance profile and its peaks
``init``           the initial pose (key points, head candidates, back-tracking)
``primitives``     the body primitives (capsules, spheres, torso) and distances to them
``energy``         the fitting energy as stacked residual blocks
``constraints``    topological, geometric, velocity, collision constraints
``fit``            local Levenberg-Marquardt and guided global changes
``moves``          the guided configuration changes
``stabilise``      threshold-gated progressive filtering
``complete``       completion of unseen points (Kalman, gravity, IK, limits)
``tracker``        the per-frame pipeline and its states
``evaluate``       scores against ground truth, plausibility, pictures
=================  ============================================================

Shared with other systems and re-exported here: depth files and intrinsics
(:mod:`toolkit.io.depth_readers`), depth to points, the view frame, the user
mask and normal maps (:mod:`toolkit.pointcloud`), the 13 control points, body
primitives' radii and dimensions (:mod:`toolkit.body.control_points`).

See ``docs/depth_tracking.md``.
"""

from toolkit.pointcloud.cloud import ViewFrame, depth_to_points, principal_direction, user_cloud
from toolkit.depth.complete import CompletionConfig, PointKalman, complete
from toolkit.depth.constraints import ConstraintConfig, LengthEstimator, constraint_violations
from toolkit.depth.curvature import CONCAVE, CONVEX, PLANAR, CurvatureConfig, curvature_centres
from toolkit.depth.energy import EnergyConfig, fit_data
from toolkit.depth.fit import FitConfig, GlobalSearch, fit_local, levenberg_marquardt
from toolkit.depth.init import InitConfig
from toolkit.pointcloud.mask import BackgroundModel, MaskConfig, user_mask
from toolkit.body.control_points import BodyDimensions, control_points, rest_pose13
from toolkit.pointcloud.normals import grid_normals, normal_map
from toolkit.depth.orus import ORUS_BIN_SIZE_M, OrusConfig, OrusGrid, build_orus
from toolkit.depth.radial import RadialConfig, radial_profile
from toolkit.io.depth_readers import (
    KINECT_V1_FOCAL_PX,
    DepthCameraInfo,
    DepthInput,
    default_depth_camera,
    depth_intrinsics_text,
    list_depth_frames,
    open_depth_input,
    read_depth,
    read_depth_intrinsics,
)
from toolkit.depth.stabilise import Stabiliser, StabiliserConfig
from toolkit.depth.tracker import (
    LOST,
    NO_PERSON_FLAT,
    RECOVERING,
    STATE_NAMES,
    TRACKING,
    DepthTracker,
    FrameResult,
    TrackerConfig,
    TrackResult,
    track_sequence,
)

__all__ = [
    "CONCAVE",
    "CONVEX",
    "KINECT_V1_FOCAL_PX",
    "LOST",
    "NO_PERSON_FLAT",
    "ORUS_BIN_SIZE_M",
    "PLANAR",
    "RECOVERING",
    "STATE_NAMES",
    "TRACKING",
    "BackgroundModel",
    "BodyDimensions",
    "CompletionConfig",
    "ConstraintConfig",
    "CurvatureConfig",
    "DepthCameraInfo",
    "DepthInput",
    "DepthTracker",
    "EnergyConfig",
    "FitConfig",
    "FrameResult",
    "GlobalSearch",
    "InitConfig",
    "LengthEstimator",
    "MaskConfig",
    "OrusConfig",
    "OrusGrid",
    "PointKalman",
    "RadialConfig",
    "Stabiliser",
    "StabiliserConfig",
    "TrackResult",
    "TrackerConfig",
    "ViewFrame",
    "build_orus",
    "complete",
    "constraint_violations",
    "control_points",
    "curvature_centres",
    "default_depth_camera",
    "depth_intrinsics_text",
    "depth_to_points",
    "fit_data",
    "fit_local",
    "grid_normals",
    "levenberg_marquardt",
    "list_depth_frames",
    "normal_map",
    "open_depth_input",
    "principal_direction",
    "radial_profile",
    "read_depth",
    "read_depth_intrinsics",
    "rest_pose13",
    "track_sequence",
    "user_cloud",
    "user_mask",
]
