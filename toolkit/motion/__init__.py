"""Motion: kinematics of the 14-joint skeleton, a procedural motion library, BVH import/export."""

from toolkit.motion.bvh import (
    CMU_UNIT_M,
    BvhMotion,
    bvh_to_skeleton14,
    motion_from_bvh,
    parse_bvh,
    read_bvh,
)
from toolkit.motion.bvh_write import write_bvh
from toolkit.motion.kinematics import (
    KNEE_MIN_FLEXION,
    Pose14,
    align_to_ground,
    bone_lengths14,
    forward_kinematics,
    inverse_kinematics,
    leg_reach,
    resample,
    sequence_bone_lengths,
    set_bone_lengths,
    two_bone_ik,
)
from toolkit.motion.library import MOTIONS, SCENE_MOTIONS, Motion, generate_motion, synthesize_motion

__all__ = ["CMU_UNIT_M", "BvhMotion", "bvh_to_skeleton14", "motion_from_bvh", "parse_bvh", "read_bvh",
           "write_bvh", "KNEE_MIN_FLEXION", "Pose14", "align_to_ground", "bone_lengths14",
           "forward_kinematics", "inverse_kinematics", "leg_reach", "resample", "sequence_bone_lengths",
           "set_bone_lengths", "two_bone_ik", "MOTIONS", "SCENE_MOTIONS", "Motion", "generate_motion",
           "synthesize_motion"]
