"""2D person keypoints detected in images and videos, offline, and cameras synchronised from them.

* :mod:`toolkit.detection.backends`: the detector interface (:class:`PoseDetector`), the
  :class:`Detection` it returns, and :func:`make_detector` choosing a backend by name;
* :mod:`toolkit.detection.mediapipe_pose`: the default backend, MediaPipe's BlazePose (full) run
  through the Tasks API from the model files that ship inside the ``mediapipe`` wheel (no download),
  several people per image;
* :mod:`toolkit.detection.rtmlib_pose`: RTMPose through ``rtmlib`` with model files the user gives;
* :mod:`toolkit.detection.sync`: each camera's frame offset from the keypoints' motion.

Nothing here imports rerun or writes files: :mod:`toolkit.pipeline.detect_keypoints` runs a detector
over videos and writes OpenPose-style JSON (docs/detection.md).
"""

from toolkit.detection.backends import BACKENDS, Detection, PoseDetector, make_detector

__all__ = ["BACKENDS", "Detection", "PoseDetector", "make_detector"]
