"""3D joint optimisation by the billboard position score under anthropometric constraints (source 000 §3.2)."""

from toolkit.optimize.config import GRID_MIN_STEP_M, MIN_GAIN, SOURCE_SWEEPS, OptimizeConfig
from toolkit.optimize.search import STATUSES, JointStep, PoseResult, decisive_reason, optimize_joint, optimize_pose

__all__ = ["GRID_MIN_STEP_M", "MIN_GAIN", "SOURCE_SWEEPS", "OptimizeConfig", "STATUSES", "JointStep", "PoseResult",
           "decisive_reason", "optimize_joint", "optimize_pose"]
