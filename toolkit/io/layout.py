"""Paths and per-file contracts of the dataset layout (see :mod:`toolkit.io.dataset`).

:class:`DatasetLayout` names every path of a dataset folder once; the checks
below are shared by :class:`toolkit.io.dataset.DatasetWriter` and
:class:`toolkit.io.dataset.Dataset`, so that the writer refuses what the
reader would reject.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.io.frames import FRAME_DIGITS, frame_filename

__all__ = [
    "DatasetLayout",
    "FPS_RELATIVE_TOLERANCE",
    "KEYPOINT_RECORDS",
    "MAX_PEOPLE",
    "NOVEL_RESERVED",
    "STRAY_FILES",
    "is_stray",
    "camera_of",
    "check_image",
    "check_index",
    "check_joints2d",
    "check_joints3d",
    "check_people",
    "load_npz",
]

#: Relative frame-rate difference tolerated between the videos of one dataset
#: (containers round rates such as 30000/1001 differently).
FPS_RELATIVE_TOLERANCE = 1e-3
#: Names reserved inside ``groundtruth/novel/`` (a novel camera cannot be called so).
NOVEL_RESERVED = ("masks", "parts", "instances")
#: Files ``recipes/detect_keypoints.py`` writes beside the camera folders of a keypoints folder (what it did,
#: the cameras' frame offsets): allowed in a dataset's ``keypoints/``.
KEYPOINT_RECORDS = ("detection.json", "sync.json")
#: Most people an instance map can tell apart (ids 1..255 in a uint8 PNG).
MAX_PEOPLE = 255
#: Files operating systems and file browsers leave in folders (lower case): readers skip them with a warning
#: instead of refusing the folder, and run fingerprints leave them out.
STRAY_FILES = frozenset({"thumbs.db", "ehthumbs.db", "desktop.ini", ".ds_store", "icon\r", ".directory"})


def is_stray(path: str | Path) -> bool:
    """Whether ``path`` is a file an operating system left (:data:`STRAY_FILES`), not data."""
    name = Path(path).name.lower()
    return name in STRAY_FILES or name.startswith("._")  # macOS resource forks on foreign disks


@dataclass(frozen=True)
class DatasetLayout:
    """Every path of the dataset layout, defined once.

    Parameters
    ----------
    root : Path
        The dataset folder.
    """

    root: Path

    CALIBRATION = "calibration.toml"
    VIDEOS = "videos"
    VIDEO_SUFFIX = ".mp4"
    GROUNDTRUTH = "groundtruth"
    JOINTS3D = "joints3d.npz"
    JOINTS2D = "joints2d.npz"
    PEOPLE = "people.npz"
    MASKS = "masks"
    INSTANCES = "instances"
    PARTS = "parts"
    DEPTH = "depth"
    NOVEL = "novel"
    SCENE_TOML = "scene.toml"
    FIELD_MODEL = "field_model.json"
    SCENE_RRD = "scene.rrd"
    KEYPOINTS = "keypoints"

    def __post_init__(self):
        object.__setattr__(self, "root", Path(self.root))

    @property
    def background_dir(self) -> Path:
        """``background/``: optional clean plates ``<camera>.png`` (the empty scene)."""
        return self.root / "background"

    @property
    def calibration(self) -> Path:
        return self.root / self.CALIBRATION

    @property
    def keypoints_dir(self) -> Path:
        """``keypoints/``: optional 2D keypoints of a detector, one folder per camera."""
        return self.root / self.KEYPOINTS

    def keypoint_dir(self, camera: str) -> Path:
        """``keypoints/<camera>/``: one JSON file per frame (OpenPose or MMPose per image)."""
        return self.keypoints_dir / camera

    @property
    def masks_dir(self) -> Path:
        """``masks/``: optional subject masks from elsewhere (not ``groundtruth/masks/``)."""
        return self.root / self.MASKS

    def input_mask(self, camera: str, index: int) -> Path:
        """``masks/<camera>/NNNNNN.png``: a given subject mask (uint8, non-zero = subject)."""
        return self.masks_dir / camera / frame_filename(index)

    @property
    def videos(self) -> Path:
        return self.root / self.VIDEOS

    def video(self, camera: str) -> Path:
        return self.videos / f"{camera}{self.VIDEO_SUFFIX}"

    @property
    def scene_toml(self) -> Path:
        return self.root / self.SCENE_TOML

    @property
    def field_model(self) -> Path:
        """``field_model.json``: optional painted lines of the ground (:mod:`toolkit.io.field_model`)."""
        return self.root / self.FIELD_MODEL

    @property
    def scene_rrd(self) -> Path:
        return self.root / self.SCENE_RRD

    @property
    def groundtruth(self) -> Path:
        return self.root / self.GROUNDTRUTH

    @property
    def gt_calibration(self) -> Path:
        return self.groundtruth / self.CALIBRATION

    @property
    def joints3d(self) -> Path:
        return self.groundtruth / self.JOINTS3D

    @property
    def joints2d(self) -> Path:
        return self.groundtruth / self.JOINTS2D

    @property
    def people(self) -> Path:
        """``groundtruth/people.npz``: every person's joints (scenes with several people)."""
        return self.groundtruth / self.PEOPLE

    def mask(self, camera: str, index: int) -> Path:
        return self.groundtruth / self.MASKS / camera / frame_filename(index)

    def instances(self, camera: str, index: int) -> Path:
        """``groundtruth/instances/<camera>/NNNNNN.png``: uint8, 0 background, k = person k - 1."""
        return self.groundtruth / self.INSTANCES / camera / frame_filename(index)

    def parts(self, camera: str, index: int) -> Path:
        return self.groundtruth / self.PARTS / camera / frame_filename(index)

    def depth(self, camera: str, index: int) -> Path:
        return self.groundtruth / self.DEPTH / camera / frame_filename(index)

    @property
    def novel(self) -> Path:
        return self.groundtruth / self.NOVEL

    @property
    def novel_calibration(self) -> Path:
        return self.novel / self.CALIBRATION

    def novel_image(self, camera: str, index: int) -> Path:
        return self.novel / camera / frame_filename(index)

    def novel_mask(self, camera: str, index: int) -> Path:
        return self.novel / self.MASKS / camera / frame_filename(index)

    def novel_parts(self, camera: str, index: int) -> Path:
        return self.novel / self.PARTS / camera / frame_filename(index)

    def novel_instances(self, camera: str, index: int) -> Path:
        return self.novel / self.INSTANCES / camera / frame_filename(index)


# ------------------------------------------------------------ shared checks
def camera_of(rig: Rig, camera: str, where: str) -> Camera:
    """The camera named ``camera`` of ``rig``, or an InputError naming ``where``."""
    if camera not in rig.names:
        raise InputError(where, f"a camera of the calibration {rig.names}", repr(camera))
    return rig[camera]


def check_image(where: str, image: np.ndarray, cam: Camera, channels: int) -> np.ndarray:
    """``image`` of ``cam``'s size: (H, W) if ``channels == 1``, else (H, W, channels)."""
    a = np.asarray(image)
    w, h = cam.size
    shape = (h, w) if channels == 1 else (h, w, channels)
    if a.shape != shape:
        raise InputError(
            where, f"an image of shape {shape} (camera {cam.name!r} is {w}x{h})", f"shape {a.shape}"
        )
    return a


def check_index(where: str, index) -> int:
    """A frame index: an integer in [0, 10**FRAME_DIGITS)."""
    if (
        isinstance(index, bool)
        or not isinstance(index, (int, np.integer))
        or not 0 <= index < 10**FRAME_DIGITS
    ):
        raise InputError(where, f"a frame index in [0, {10**FRAME_DIGITS})", repr(index))
    return int(index)


def check_joints3d(where: str, joints, names) -> tuple[np.ndarray, np.ndarray]:
    """``joints`` (T, J, 3) as float64 and ``names`` (J,) as str, or an InputError."""
    j = np.asarray(joints)
    if j.ndim != 3 or j.shape[2] != 3 or not np.issubdtype(j.dtype, np.number):
        raise InputError(
            f"{where}: joints",
            "a numeric array of shape (T, J, 3) in metres",
            f"shape {j.shape}, dtype {j.dtype}",
        )
    n = np.asarray(names)
    if n.ndim != 1 or n.dtype.kind not in "UO" or len(n) != j.shape[1]:
        raise InputError(
            f"{where}: names",
            f"{j.shape[1]} joint names (one per joint of joints)",
            f"shape {n.shape}, dtype {n.dtype}",
        )
    return j.astype(np.float64), n.astype(str)


def check_people(where: str, joints, names) -> tuple[np.ndarray, np.ndarray]:
    """All people's joints ``(P, T, J, 3)`` as float64 and ``names`` (J,) as str, or an InputError.

    ``1 <= P <= MAX_PEOPLE`` (person ``p`` is instance id ``p + 1``).
    """
    j = np.asarray(joints)
    if (j.ndim != 4 or j.shape[3] != 3 or not np.issubdtype(j.dtype, np.number)
            or not 1 <= j.shape[0] <= MAX_PEOPLE):
        raise InputError(
            f"{where}: joints",
            f"a numeric array of shape (P, T, J, 3) in metres with 1 <= P <= {MAX_PEOPLE}",
            f"shape {j.shape}, dtype {j.dtype}",
        )
    n = np.asarray(names)
    if n.ndim != 1 or n.dtype.kind not in "UO" or len(n) != j.shape[2]:
        raise InputError(
            f"{where}: names",
            f"{j.shape[2]} joint names (one per joint of joints)",
            f"shape {n.shape}, dtype {n.dtype}",
        )
    return j.astype(np.float64), n.astype(str)


def check_joints2d(
    where: str, key: str, a, n_frames: int | None, n_joints: int | None
) -> np.ndarray:
    """One camera's 2D joints (T, J, 2) as float64; ``None`` sizes match anything."""
    a = np.asarray(a)
    t = "T" if n_frames is None else str(n_frames)
    jj = "J" if n_joints is None else str(n_joints)
    if (
        a.ndim != 3
        or a.shape[2] != 2
        or not np.issubdtype(a.dtype, np.number)
        or (n_frames is not None and a.shape[0] != n_frames)
        or (n_joints is not None and a.shape[1] != n_joints)
    ):
        raise InputError(
            f"{where}: {key}",
            f"a numeric array of shape ({t}, {jj}, 2) in pixels",
            f"shape {a.shape}, dtype {a.dtype}",
        )
    return a.astype(np.float64)


def load_npz(path: Path) -> dict[str, np.ndarray]:
    """All arrays of an ``.npz`` (no pickles), or an InputError naming the file."""
    if not path.is_file():
        raise InputError(str(path), "an existing .npz file", "no such file")
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as e:
        raise InputError(
            str(path), "a readable .npz archive (numpy.savez)", f"{type(e).__name__}: {e}"
        ) from None
