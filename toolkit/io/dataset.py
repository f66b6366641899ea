"""The dataset folder layout: the contract between generator, pipeline and real footage.

::

    <root>/
      calibration.toml                 cameras as measured (Pose2Sim TOML)
      videos/<camera>.mp4              one per camera, all with the same frame count
      scene.toml                       optional: the scene spec that generated the data
      scene.rrd                        optional: a rerun recording
      keypoints/<camera>/              optional: a detector's 2D keypoints, one JSON file per frame
      masks/<camera>/NNNNNN.png        optional: subject masks from elsewhere, uint8, non-zero = subject
      groundtruth/                     only for synthetic data
        calibration.toml               true cameras (same names as the measured ones)
        joints3d.npz                   joints (T, J, 3) metres, world z up; names (J,)
        joints2d.npz                   one (T, J, 2) pixel array per camera, key = camera name
        people.npz                     optional, several people: joints (P, T, J, 3), names (J,);
                                       person 0 is the subject of joints3d.npz
        masks/<camera>/NNNNNN.png      uint8, 0 background / 255 subject (every person)
        parts/<camera>/NNNNNN.png      uint8, 0 background / k = body-part id
        instances/<camera>/NNNNNN.png  with people.npz: uint8, 0 background / k = person k - 1
        depth/<camera>/NNNNNN.png      uint16 millimetres, 0 = no depth
        novel/calibration.toml         virtual cameras for free-viewpoint evaluation
        novel/<camera>/NNNNNN.png      RGB images seen by the virtual cameras
        novel/masks/<camera>/NNNNNN.png
        novel/parts/<camera>/NNNNNN.png
        novel/instances/<camera>/NNNNNN.png

Frames are numbered from 000000.  Real footage uses the same layout without
``groundtruth/``.  See ``docs/dataset_layout.md`` for units and conventions.

:class:`~toolkit.io.writer.DatasetWriter` writes it (every file atomically); :meth:`Dataset.open`
reads and validates it.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Iterator

import numpy as np

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.io.calibration import read_calibration_toml
from toolkit.io.field_model import read_field_model
from toolkit.io.frames import FRAME_DIGITS, frame_filename, mm_to_depth, read_png
from toolkit.io.layout import (
    FPS_RELATIVE_TOLERANCE,
    KEYPOINT_RECORDS,
    NOVEL_RESERVED,
    DatasetLayout,
    camera_of,
    check_joints2d,
    check_joints3d,
    check_people,
    is_stray,
    load_npz,
)
from toolkit.io.video import VideoReader, probe_video
__all__ = ["DatasetLayout", "Dataset", "FPS_RELATIVE_TOLERANCE"]


def _stray(path: Path) -> bool:
    """Whether ``path`` is a file the operating system left (``Thumbs.db``): skipped, with a warning."""
    if not (path.is_file() and is_stray(path)):
        return False
    warnings.warn(f"{path}: ignored (a file the operating system left, not data)", stacklevel=3)
    return True


class Dataset:
    """A dataset folder, validated on opening.  Create with :meth:`open`.

    Attributes
    ----------
    layout : DatasetLayout
    rig : Rig
        Cameras as measured (``calibration.toml``).
    n_frames : int
        Frames per video (the same for all).
    fps : float
        Frame rate of the first camera's video.
    video_sizes : dict of str to tuple of int
        ``(width, height)`` of each video.
    """

    def __init__(
        self,
        layout: DatasetLayout,
        rig: Rig,
        n_frames: int,
        fps: float,
        video_sizes: dict[str, tuple[int, int]],
    ):
        self.layout = layout
        self.rig = rig
        self.n_frames = n_frames
        self.fps = fps
        self.video_sizes = video_sizes
        self._readers: dict[str, VideoReader] = {}
        self._gt_rig: Rig | None = None
        self._novel_rig: Rig | None = None
        self._joints3d: tuple[np.ndarray, np.ndarray] | None = None
        self._joints2d: dict[str, np.ndarray] | None = None
        self._people: tuple[np.ndarray, np.ndarray] | None = None

    # -- opening and validation
    @classmethod
    def open(cls, root: str | os.PathLike, *, check_sizes: bool = True) -> "Dataset":
        """Open and validate a dataset folder.

        Parameters
        ----------
        root : str or PathLike
        check_sizes : bool
            Require every video's frame size to equal its camera's calibrated
            size.  Turn off for footage whose calibration was made at another
            size (e.g. the Pose2Sim demo: 1088x1920 calibration, 1080x1920 videos).

        Returns
        -------
        Dataset

        Raises
        ------
        InputError
            Naming the path at fault: missing folder or ``calibration.toml``; a
            calibration camera without ``videos/<camera>.mp4``; a video whose
            name is not a camera; videos of different lengths (both cameras and
            counts named) or frame rates; a video size unlike its camera's; in
            ``groundtruth/``: a calibration with other cameras, an unreadable
            ``.npz``, a missing field, joint arrays of the wrong shape or length,
            image folders of unknown cameras or with badly named frames.
        """
        layout = DatasetLayout(Path(root))
        if not layout.root.is_dir():
            raise InputError(str(layout.root), "a dataset folder", "no such folder")
        rig = read_calibration_toml(layout.calibration)
        if not layout.videos.is_dir():
            raise InputError(
                str(layout.videos),
                f"a folder with one <camera>{layout.VIDEO_SUFFIX} per camera",
                "no such folder",
            )
        on_disk = {
            p.name[: -len(layout.VIDEO_SUFFIX)]: p
            for p in layout.videos.iterdir()
            if p.name.endswith(layout.VIDEO_SUFFIX) and not p.name.startswith(".")
        }
        for name in rig.names:
            if name not in on_disk:
                raise InputError(
                    str(layout.video(name)),
                    f"a video for camera {name!r} of {layout.calibration}",
                    "no such file",
                )
        for name, p in sorted(on_disk.items()):
            if name not in rig.names:
                raise InputError(
                    str(p),
                    f"a video named after a camera of {layout.calibration} {rig.names}",
                    f"camera {name!r}, not in the calibration",
                )
        infos = {name: probe_video(layout.video(name)) for name in rig.names}
        first = rig.names[0]
        for name, info in infos.items():
            if info.n_frames != infos[first].n_frames:
                raise InputError(
                    str(layout.videos),
                    "videos with the same number of frames",
                    f"{first!r} has {infos[first].n_frames} frames, {name!r} has {info.n_frames}",
                )
            if abs(info.fps - infos[first].fps) > FPS_RELATIVE_TOLERANCE * infos[first].fps:
                raise InputError(
                    str(layout.videos),
                    "videos with the same frame rate",
                    f"{first!r} at {infos[first].fps} fps, {name!r} at {info.fps} fps",
                )
            if check_sizes and info.size != rig[name].size:
                raise InputError(
                    str(info.path),
                    f"frames of {rig[name].size[0]}x{rig[name].size[1]} "
                    f"(camera {name!r} in {layout.calibration})",
                    f"{info.size[0]}x{info.size[1]}",
                )
        ds = cls(
            layout,
            rig,
            infos[first].n_frames,
            infos[first].fps,
            {n: i.size for n, i in infos.items()},
        )
        ds._validate_inputs()
        if ds.has_groundtruth:
            ds._validate_groundtruth()
        return ds

    def _validate_inputs(self) -> None:
        """The optional ``keypoints/`` and ``masks/`` folders: one folder per camera, frames named."""
        L = self.layout
        if L.keypoints_dir.exists():
            if not L.keypoints_dir.is_dir():
                raise InputError(str(L.keypoints_dir), "a folder of one keypoint folder per camera", "a file")
            for p in sorted(L.keypoints_dir.iterdir()):
                if p.name.startswith(".") or (p.is_file() and p.name in KEYPOINT_RECORDS) or _stray(p):
                    continue
                if not p.is_dir() or p.name not in self.rig.names:
                    raise InputError(str(p), f"a folder named after a camera {self.rig.names}", f"{p.name!r}")
        self._validate_frame_folders(L.masks_dir, self.rig.names)

    def _validate_groundtruth(self) -> None:
        L = self.layout
        if L.gt_calibration.exists():
            gt = read_calibration_toml(L.gt_calibration)
            if set(gt.names) != set(self.rig.names):
                raise InputError(
                    str(L.gt_calibration),
                    f"the cameras of {L.calibration}: {self.rig.names}",
                    f"{gt.names}",
                )
            self._gt_rig = gt
        n_joints = None
        if L.joints3d.exists():
            z = load_npz(L.joints3d)
            for key in ("joints", "names"):
                if key not in z:
                    raise InputError(
                        f"{L.joints3d}: {key}", f"a '{key}' array", f"fields {sorted(z)}"
                    )
            j, n = check_joints3d(str(L.joints3d), z["joints"], z["names"])
            if j.shape[0] != self.n_frames:
                raise InputError(
                    f"{L.joints3d}: joints",
                    f"{self.n_frames} frames (as the videos)",
                    f"shape {j.shape}",
                )
            self._joints3d = (j, n)
            n_joints = j.shape[1]
        if L.joints2d.exists():
            z = load_npz(L.joints2d)
            out = {}
            for key, a in z.items():
                if key not in self.rig.names:
                    raise InputError(
                        f"{L.joints2d}: {key}",
                        f"arrays named after cameras {self.rig.names}",
                        f"key {key!r}",
                    )
                a = check_joints2d(str(L.joints2d), key, a, self.n_frames, n_joints)
                n_joints = a.shape[1]
                out[key] = a
            self._joints2d = out
        if L.people.exists():
            self._people = self._load_people(n_joints)
        for kind in (L.MASKS, L.PARTS, L.DEPTH, L.INSTANCES):
            self._validate_frame_folders(L.groundtruth / kind, self.rig.names)
        if L.novel.exists():
            self._novel_rig = read_calibration_toml(L.novel_calibration)
            for p in sorted(L.novel.iterdir()):
                if (
                    p.is_dir()
                    and p.name not in NOVEL_RESERVED
                    and p.name not in self._novel_rig.names
                ):
                    raise InputError(
                        str(p),
                        f"a folder named after a camera of {L.novel_calibration} "
                        f"{self._novel_rig.names}",
                        f"folder {p.name!r}",
                    )
            for cam in self._novel_rig.names:
                self._validate_frames(L.novel / cam)
            for kind in NOVEL_RESERVED:
                self._validate_frame_folders(L.novel / kind, self._novel_rig.names)

    def _load_people(self, n_joints: int | None) -> tuple[np.ndarray, np.ndarray]:
        """``groundtruth/people.npz`` checked: (P, n_frames, J, 3), person 0 = ``joints3d.npz``."""
        L = self.layout
        z = load_npz(L.people)
        for key in ("joints", "names"):
            if key not in z:
                raise InputError(
                    f"{L.people}: {key}", f"a '{key}' array", f"fields {sorted(z)}"
                )
        j, n = check_people(str(L.people), z["joints"], z["names"])
        if j.shape[1] != self.n_frames or (n_joints is not None and j.shape[2] != n_joints):
            jj = "J" if n_joints is None else str(n_joints)
            raise InputError(
                f"{L.people}: joints",
                f"shape (P, {self.n_frames}, {jj}, 3) (frames as the videos, joints as "
                f"{L.JOINTS3D})",
                f"shape {j.shape}",
            )
        if self._joints3d is not None and not np.array_equal(
            j[0], self._joints3d[0], equal_nan=True
        ):
            raise InputError(
                f"{L.people}: joints[0]",
                f"the joints of {L.joints3d} (person 0 is the subject)",
                "other joints",
            )
        return j, n

    def _validate_frame_folders(self, folder: Path, names: list[str]) -> None:
        if not folder.exists():
            return
        for p in sorted(folder.iterdir()):
            if p.name.startswith(".") or _stray(p):
                continue
            if not p.is_dir() or p.name not in names:
                raise InputError(str(p), f"a folder named after a camera {names}", f"{p.name!r}")
            self._validate_frames(p)

    def _validate_frames(self, folder: Path) -> None:
        if not folder.is_dir():
            return
        for p in folder.iterdir():
            if p.name.startswith(".") or _stray(p):
                continue  # temporary files of an interrupted atomic write, files the OS left
            stem = p.name[:-4] if p.name.endswith(".png") else ""
            if len(stem) != FRAME_DIGITS or not stem.isdigit() or int(stem) >= self.n_frames:
                raise InputError(
                    str(p),
                    f"a frame file 000000.png .. {frame_filename(self.n_frames - 1)}",
                    f"{p.name!r}",
                )

    # -- cameras and videos
    @property
    def root(self) -> Path:
        return self.layout.root

    @property
    def camera_names(self) -> list[str]:
        """Camera names in calibration order."""
        return self.rig.names

    def video_path(self, camera: str) -> Path:
        camera_of(self.rig, camera, f"{self.root}: camera")
        return self.layout.video(camera)

    def _index(self, i) -> int:
        if (
            isinstance(i, bool)
            or not isinstance(i, (int, np.integer))
            or not 0 <= i < self.n_frames
        ):
            raise InputError(
                f"{self.root}: frame index", f"an integer in [0, {self.n_frames})", repr(i)
            )
        return int(i)

    def frames(self, camera: str) -> Iterator[np.ndarray]:
        """Iterate over the RGB ``(H, W, 3) uint8`` frames of a camera, from frame 0.

        Each call opens its own decoder, so several iterations may run at once.
        """
        path = self.video_path(camera)

        def gen():
            with VideoReader(path) as reader:
                yield from reader

        return gen()

    def frame(self, camera: str, i: int) -> np.ndarray:
        """Frame ``i`` of ``camera`` as RGB ``(H, W, 3) uint8`` (sequential access is cheapest)."""
        path = self.video_path(camera)
        i = self._index(i)
        if camera not in self._readers:
            self._readers[camera] = VideoReader(path)
        return self._readers[camera].read(i)

    # -- ground truth
    @property
    def has_groundtruth(self) -> bool:
        """Whether ``groundtruth/`` exists (synthetic data)."""
        return self.layout.groundtruth.is_dir()

    def _need(self, path: Path) -> None:
        if not self.has_groundtruth:
            raise InputError(
                str(self.layout.groundtruth),
                "a ground-truth folder (synthetic datasets only)",
                "no such folder",
            )
        if not path.exists():
            raise InputError(str(path), "a ground-truth file", "no such file")

    @property
    def gt_rig(self) -> Rig:
        """The true cameras (``groundtruth/calibration.toml``)."""
        if self._gt_rig is None:
            self._need(self.layout.gt_calibration)
        return self._gt_rig

    def _truth_cam(self, camera: str) -> Camera:
        rig = self._gt_rig if self._gt_rig is not None else self.rig
        return camera_of(rig, camera, f"{self.root}: camera")

    def gt_joints3d(self) -> np.ndarray:
        """True world joints, ``(n_frames, J, 3)`` metres (a copy); see :attr:`gt_joint_names`."""
        if self._joints3d is None:
            self._need(self.layout.joints3d)
        return self._joints3d[0].copy()

    @property
    def gt_joint_names(self) -> list[str]:
        """Joint names of :meth:`gt_joints3d`."""
        if self._joints3d is None:
            self._need(self.layout.joints3d)
        return list(self._joints3d[1])

    def gt_joints2d(self) -> dict[str, np.ndarray]:
        """True 2D joints per camera name, each ``(n_frames, J, 2)`` pixels (copies)."""
        if self._joints2d is None:
            self._need(self.layout.joints2d)
        return {k: v.copy() for k, v in self._joints2d.items()}

    def _read(self, path: Path, cam: Camera, channels: int, dtype, need: bool = True) -> np.ndarray:
        if need:  # a ground-truth file (the clean plates are inputs)
            self._need(path)
        img = read_png(path, channels=channels, dtype=dtype)
        w, h = cam.size
        if img.shape[:2] != (h, w):
            raise InputError(
                str(path),
                f"an image of {w}x{h} (camera {cam.name!r})",
                f"{img.shape[1]}x{img.shape[0]}",
            )
        return img

    @property
    def people_count(self) -> int:
        """How many people the ground truth tells apart: ``P`` of ``people.npz``, else 1."""
        return 1 if self._people is None else int(self._people[0].shape[0])

    def gt_people_joints3d(self) -> np.ndarray:
        """Every person's true world joints, ``(people_count, n_frames, J, 3)`` metres (a copy).

        Person ``p`` is instance id ``p + 1`` of :meth:`gt_instances`; NaN where a person is
        absent.  A dataset without ``people.npz`` has one person, the subject of
        :meth:`gt_joints3d`.
        """
        if self._people is not None:
            return self._people[0].copy()
        return self.gt_joints3d()[None]

    def _instances(self, path: Path, cam: Camera, mask) -> np.ndarray:
        if self._people is None and not path.exists():  # one person: the mask is the instance map
            return mask().astype(np.uint8)
        ids = self._read(path, cam, 1, np.uint8)
        if ids.max(initial=0) > self.people_count:
            raise InputError(
                str(path),
                f"person ids 0..{self.people_count} ({self.layout.PEOPLE} holds "
                f"{self.people_count})",
                f"id {int(ids.max())}",
            )
        return ids

    def gt_instances(self, camera: str, i: int) -> np.ndarray:
        """Which person each pixel shows, ``(H, W)`` uint8: 0 background, ``k`` = person ``k - 1``.

        The front-most body per pixel (``groundtruth/instances/``).  For a dataset without
        ``people.npz`` (one subject) it is the mask as 0 / 1.
        """
        i = self._index(i)
        cam = self._truth_cam(camera)
        path = self.layout.instances(camera, i)
        return self._instances(path, cam, lambda: self.gt_mask(camera, i))

    def gt_mask(self, camera: str, i: int) -> np.ndarray:
        """Subject mask, ``(H, W)`` bool (True where the stored value is non-zero)."""
        return (
            self._read(
                self.layout.mask(camera, self._index(i)), self._truth_cam(camera), 1, np.uint8
            )
            > 0
        )

    def gt_parts(self, camera: str, i: int) -> np.ndarray:
        """Body-part labels, ``(H, W)`` uint8: 0 background, k = part id."""
        return self._read(
            self.layout.parts(camera, self._index(i)), self._truth_cam(camera), 1, np.uint8
        )

    def gt_depth(self, camera: str, i: int) -> np.ndarray:
        """Camera-frame depth (z), ``(H, W)`` float32 metres; NaN where none (stored 0)."""
        mm = self._read(
            self.layout.depth(camera, self._index(i)), self._truth_cam(camera), 1, np.uint16
        )
        return mm_to_depth(mm)

    # -- novel views
    @property
    def novel_rig(self) -> Rig:
        """The virtual cameras (``groundtruth/novel/calibration.toml``)."""
        if self._novel_rig is None:
            self._need(self.layout.novel_calibration)
        return self._novel_rig

    def _novel_cam(self, camera: str) -> Camera:
        return camera_of(self.novel_rig, camera, f"{self.layout.novel}: camera")

    def novel_image(self, camera: str, i: int) -> np.ndarray:
        """What virtual camera ``camera`` sees at frame ``i``: ``(H, W, 3)`` uint8 RGB."""
        cam = self._novel_cam(camera)
        return self._read(self.layout.novel_image(camera, self._index(i)), cam, 3, np.uint8)

    def novel_mask(self, camera: str, i: int) -> np.ndarray:
        """Subject mask in a virtual camera, ``(H, W)`` bool."""
        cam = self._novel_cam(camera)
        return self._read(self.layout.novel_mask(camera, self._index(i)), cam, 1, np.uint8) > 0

    def novel_parts(self, camera: str, i: int) -> np.ndarray:
        """Body-part labels in a virtual camera, ``(H, W)`` uint8."""
        cam = self._novel_cam(camera)
        return self._read(self.layout.novel_parts(camera, self._index(i)), cam, 1, np.uint8)

    def novel_instances(self, camera: str, i: int) -> np.ndarray:
        """Which person each pixel of a virtual camera shows, ``(H, W)`` uint8 (see
        :meth:`gt_instances`)."""
        i = self._index(i)
        cam = self._novel_cam(camera)
        path = self.layout.novel_instances(camera, i)
        return self._instances(path, cam, lambda: self.novel_mask(camera, i))

    def frames_to_process(self, max_frames: int | None = None) -> int:
        """How many frames to process: all, or the first ``max_frames`` (the recipes' ``--max-frames``).

        Raises
        ------
        InputError
            If ``max_frames`` is given and below 1.
        """
        if max_frames is None:
            return self.n_frames
        if max_frames < 1:
            raise InputError("--max-frames", "a positive number of frames", str(max_frames))
        return min(int(max_frames), self.n_frames)

    # -- optional inputs: keypoints and masks
    @property
    def has_keypoints(self) -> bool:
        """Whether ``keypoints/`` holds a folder for at least one camera."""
        return any(self.keypoint_dir(c) is not None for c in self.rig.names)

    def keypoint_dir(self, camera: str) -> Path | None:
        """``keypoints/<camera>/`` (a detector's JSON files, one per frame), or None when absent."""
        camera_of(self.rig, camera, f"{self.root}: camera")
        p = self.layout.keypoint_dir(camera)
        return p if p.is_dir() else None

    @property
    def has_masks(self) -> bool:
        """Whether ``masks/`` (subject masks from elsewhere) exists."""
        return self.layout.masks_dir.is_dir()

    def mask(self, camera: str, i: int) -> np.ndarray | None:
        """The given subject mask ``masks/<camera>/NNNNNN.png`` as ``(H, W)`` bool, or None when absent.

        Raises
        ------
        InputError
            A mask of another size than the camera's.
        """
        cam = camera_of(self.rig, camera, f"{self.root}: camera")
        path = self.layout.input_mask(camera, self._index(i))
        if not path.is_file():
            return None
        img = read_png(path, channels=1, dtype=np.uint8)
        if img.shape[:2] != (cam.height, cam.width):
            raise InputError(str(path), f"an image of {cam.width}x{cam.height} (camera {camera!r})",
                             f"{img.shape[1]}x{img.shape[0]}")
        return img > 0

    # -- optional files
    def background(self, camera: str) -> np.ndarray | None:
        """The clean plate of ``camera`` (``background/<camera>.png``), (H, W, 3) uint8 RGB, or None."""
        cam = self.rig[camera]
        path = self.layout.background_dir / f"{camera}.png"
        if not path.is_file():
            return None
        return self._read(path, cam, 3, np.uint8, need=False)

    def field_model(self):
        """The ground's painted lines (``field_model.json``) as a :class:`~toolkit.io.field_model.FieldModel`, or None."""
        path = self.layout.field_model
        return read_field_model(path) if path.is_file() else None

    @property
    def scene_toml(self) -> Path | None:
        """``scene.toml`` if present."""
        return self.layout.scene_toml if self.layout.scene_toml.is_file() else None

    @property
    def scene_rrd(self) -> Path | None:
        """``scene.rrd`` if present."""
        return self.layout.scene_rrd if self.layout.scene_rrd.is_file() else None

    # -- resources
    def close(self) -> None:
        """Release the video decoders opened by :meth:`frame`."""
        for r in self._readers.values():
            r.close()
        self._readers.clear()

    def __enter__(self) -> "Dataset":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"Dataset({str(self.root)!r}, cameras={self.camera_names}, n_frames={self.n_frames}, "
            f"fps={self.fps:g}, groundtruth={self.has_groundtruth})"
        )

