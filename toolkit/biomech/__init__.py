"""Biomechanics and animation out of any system's 3D joints: joint angles, OpenSim, BVH and glTF.

* :mod:`toolkit.biomech.segments`: anatomical segment frames from joint centres (and optional markers);
* :mod:`toolkit.biomech.angles`: the project's own joint angles (Plug-in Gait names and signs);
* :mod:`toolkit.biomech.mapping`: each system's joints and markers as the models' landmarks;
* :mod:`toolkit.biomech.files`: a run's 3D output in, ``angles.csv`` out;
* :mod:`toolkit.biomech.export`: BVH and glTF of an estimate, rest pose from its bone lengths;
* :mod:`toolkit.biomech.opensim_model`: scaling and inverse kinematics with OpenSim (optional extra).
"""

from toolkit.biomech.angles import ANGLE_DEFINITIONS, JointAngles, angle_rms, cardan_zxy, joint_angles
from toolkit.biomech.mapping import MARKER_LANDMARKS, joints_to_points, marker_points
from toolkit.biomech.segments import segment_frames

__all__ = ["ANGLE_DEFINITIONS", "JointAngles", "angle_rms", "cardan_zxy", "joint_angles", "MARKER_LANDMARKS",
           "joints_to_points", "marker_points", "segment_frames"]
