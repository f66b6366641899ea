"""RTMPose through ``rtmlib`` (ONNX Runtime), for users who have its model files.

``rtmlib`` downloads its models from the internet when given none; here the two ONNX files are
required (a person detector such as YOLOX, and an RTMPose model), so a run never reaches the network.
Pose2Sim's default (``Body_with_feet``, HALPE-26 keypoints, ``balanced`` mode) is YOLOX-m with
RTMPose-m; give ``layout="halpe_26"`` for it, ``"coco_17"`` for the body-only models and
``"coco_133"`` for whole-body ones.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toolkit.detection.types import Detection
from toolkit.errors import InputError

__all__ = ["RTMLibPoseDetector", "DET_INPUT_SIZE", "POSE_INPUT_SIZE"]

#: Input sizes (width, height) of rtmlib's YOLOX and RTMPose models.
DET_INPUT_SIZE = (640, 640)
POSE_INPUT_SIZE = (192, 256)
LAYOUTS = ("coco_17", "halpe_26", "coco_133")


class RTMLibPoseDetector:
    """Several people per image: a person detector's boxes, then RTMPose in each box.

    Parameters
    ----------
    det_model, pose_model : path-like
        The ONNX files of the person detector (YOLOX) and of the pose model (RTMPose).
    layout : str
        The pose model's keypoints, one of ``coco_17``, ``halpe_26``, ``coco_133``.
    det_input_size, pose_input_size : tuple of int
        The models' input sizes (width, height).
    min_box_score : float
        Boxes below this score are dropped (when the detector returns scores).
    """

    name = "rtmlib"

    def __init__(self, det_model=None, pose_model=None, layout: str = "halpe_26",
                 det_input_size=DET_INPUT_SIZE, pose_input_size=POSE_INPUT_SIZE, min_box_score: float = 0.3):
        try:
            import rtmlib
        except ImportError as e:
            raise InputError("detector 'rtmlib'", "the rtmlib and onnxruntime packages (pip install rtmlib)",
                             f"{e}") from None
        for what, p in (("det_model", det_model), ("pose_model", pose_model)):
            if p is None or not Path(p).is_file():
                raise InputError(f"detector 'rtmlib': {what}", "an ONNX file on disk (rtmlib would download one)",
                                 "none given" if p is None else f"{p}: no such file")
        if layout not in LAYOUTS:
            raise InputError("detector 'rtmlib': layout", f"one of {LAYOUTS}", repr(layout))
        self.layout = layout
        self.model = f"{Path(det_model).name} + {Path(pose_model).name} (rtmlib {getattr(rtmlib, '__version__', '?')})"
        self.min_box_score = float(min_box_score)
        self._det = rtmlib.YOLOX(onnx_model=str(det_model), model_input_size=tuple(det_input_size),
                                 backend="onnxruntime", device="cpu")
        self._pose = rtmlib.RTMPose(onnx_model=str(pose_model), model_input_size=tuple(pose_input_size),
                                    backend="onnxruntime", device="cpu")

    def detect(self, image: np.ndarray) -> list[Detection]:
        """The people in ``image`` (H, W, 3) uint8 RGB, most confident first."""
        image = np.ascontiguousarray(np.asarray(image)[..., ::-1])  # rtmlib takes OpenCV's BGR
        boxes = self._det(image)
        if isinstance(boxes, tuple):  # some rtmlib versions return (boxes, scores)
            boxes, scores = boxes
            boxes = np.asarray(boxes)[np.asarray(scores) >= self.min_box_score]
        boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
        if len(boxes) == 0:
            return []
        keypoints, scores = self._pose(image, bboxes=boxes)
        people = [Detection(keypoints=np.column_stack([k, np.clip(s, 0.0, 1.0)]).astype(np.float64),
                            score=float(np.mean(np.clip(s, 0.0, 1.0))))
                  for k, s in zip(np.asarray(keypoints), np.asarray(scores))]
        people.sort(key=lambda d: -d.score)
        return people

    def close(self) -> None:
        """Free the models."""
        self._det = self._pose = None
