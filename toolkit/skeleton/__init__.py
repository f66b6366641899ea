"""Skeletons as data and mappings between skeleton conventions."""

from toolkit.skeleton.skeleton import (
    JOINTS_13,
    JOINTS_14,
    JOINTS_17,
    PARTS_14,
    SKELETON_13,
    SKELETON_14,
    SKELETON_17,
    TORSO_PATCH_13,
    Part,
    Skeleton,
)
from toolkit.skeleton.metrics import joint_errors, mpjpe, pose_errors

__all__ = ["JOINTS_13", "JOINTS_14", "JOINTS_17", "PARTS_14", "SKELETON_13", "SKELETON_14",
           "SKELETON_17", "TORSO_PATCH_13", "Part", "Skeleton", "joint_errors", "mpjpe", "pose_errors"]
