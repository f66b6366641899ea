"""The detector interface and the choice of a backend by name.

A backend turns one image into the people it finds: per person the keypoints of its layout (one of
:data:`toolkit.skeleton.mappings.DETECTOR_FORMATS`) with a confidence each.  Backends are created by
name with :func:`make_detector`, so recipes and configs select them with a string:

==============  ==================================================================================
name            what it runs
==============  ==================================================================================
``mediapipe``   BlazePose full (33 keypoints, ``blazepose_33``), MediaPipe Tasks, model files from
                the installed wheel; the default (docs/detection.md says why)
``rtmlib``      RTMPose / RTMO through ``rtmlib`` (ONNX), model files given by the user
                (``det_model``, ``pose_model``): ``rtmlib`` would download them otherwise
==============  ==================================================================================
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from toolkit.detection.types import Detection
from toolkit.errors import InputError

__all__ = ["Detection", "PoseDetector", "BACKENDS", "make_detector"]


@runtime_checkable
class PoseDetector(Protocol):
    """What every backend provides.

    Attributes
    ----------
    name : str
        The backend's name (a key of :data:`BACKENDS`).
    layout : str
        The keypoint layout of its detections, one of ``toolkit.skeleton.mappings.DETECTOR_FORMATS``.
    model : str
        Which model files it runs (recorded in ``detection.json``).
    """

    name: str
    layout: str
    model: str

    def detect(self, image: np.ndarray) -> list[Detection]:
        """The people in ``image`` (H, W, 3) uint8 RGB (the toolkit's order), most confident first."""

    def close(self) -> None:
        """Free the model."""


def _mediapipe(**options) -> PoseDetector:
    from toolkit.detection.mediapipe_pose import MediaPipePoseDetector

    return MediaPipePoseDetector(**options)


def _rtmlib(**options) -> PoseDetector:
    from toolkit.detection.rtmlib_pose import RTMLibPoseDetector

    return RTMLibPoseDetector(**options)


#: Backend names and their factories.
BACKENDS = {"mediapipe": _mediapipe, "rtmlib": _rtmlib}


def make_detector(name: str = "mediapipe", **options) -> PoseDetector:
    """A detector by backend name.

    Parameters
    ----------
    name : str
        A key of :data:`BACKENDS`.
    **options
        The backend's own options (see its class).

    Raises
    ------
    InputError
        An unknown name, or a backend that cannot run here (its package or model missing), naming what
        to install or give.
    """
    if name not in BACKENDS:
        raise InputError("detector (--detector)", f"one of {sorted(BACKENDS)}", repr(name))
    return BACKENDS[name](**options)
