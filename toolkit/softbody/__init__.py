"""Articulated soft-object (metaball) body models fitted to 3D point clouds (source 002).

* :mod:`~toolkit.softbody.model` -- the kinematic chain, the metaballs, the parameters;
* :mod:`~toolkit.softbody.distance` -- point-to-surface distance and its analytic Jacobian;
* :mod:`~toolkit.softbody.init` -- scaling and posing from 3D joints or 2D joints in two images;
* :mod:`~toolkit.softbody.mesh` -- the surface as a triangle mesh (marching cubes), surface samples;
* :mod:`~toolkit.softbody.track` -- frame-to-frame tracking of the pose, lost frames searched for again;
* :mod:`~toolkit.softbody.confidence` -- how far a tracked frame can be trusted (residuals, coverage,
  silhouettes);
* :mod:`~toolkit.softbody.reinit` -- 3D joints from 2D detections in calibrated views (starts and restarts);
* :mod:`~toolkit.softbody.global_fit` -- all frames at once, with lengths and widths.
"""

from toolkit.softbody.distance import distance, distance_and_jacobian
from toolkit.softbody.global_fit import GlobalFitConfig, SoftBodyFit, global_fit
from toolkit.softbody.init import init_from_2d, model_from_joints, params_from_pose14
from toolkit.softbody.mesh import sample_surface, surface_mesh
from toolkit.softbody.model import (
    DOF_NAMES,
    LENGTH_NAMES,
    N_PARAMS,
    WIDTH_GROUPS,
    SoftBodyModel,
    SoftBodyParams,
)
from toolkit.softbody.track import FRAME_STATES, SoftBodyTrack, TrackConfig, track_sequence

__all__ = ["DOF_NAMES", "LENGTH_NAMES", "N_PARAMS", "WIDTH_GROUPS", "SoftBodyModel", "SoftBodyParams",
           "distance", "distance_and_jacobian", "init_from_2d", "model_from_joints", "params_from_pose14",
           "GlobalFitConfig", "SoftBodyFit", "global_fit", "sample_surface", "surface_mesh", "FRAME_STATES",
           "SoftBodyTrack", "TrackConfig", "track_sequence"]
