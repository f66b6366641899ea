"""The dataset folder layout: the contract between generator, pipeline and real footage.

::

    <root>/
      calibration.toml                 cameras as measured (Pose2Sim TOML)
      videos/<camera>.mp4              one per camera, all with the same frame count
      scene.toml                       optional: the scene spec that generated the data
      scene.rrd                        optional: a rerun recording
      groundtruth/                     only for synthetic data
        calibration.toml               true cameras (same names as the measured ones)
        joints3d.npz                   joints (T, J, 3) metres, world z up; names (J,)
        joints2d.npz                   one (T, J, 2) pixel array per camera, key = camera name
        masks/<camera>/NNNNNN.png      uint8, 0 background / 255 subject
        parts/<camera>/NNNNNN.png      uint8, 0 background / k = body-part id
        depth/<camera>/NNNNNN.png      uint16 millimetres, 0 = no depth
        novel/calibration.toml         virtual cameras for free-viewpoint evaluation
        novel/<camera>/NNNNNN.png      RGB images seen by the virtual cameras
        novel/masks/<camera>/NNNNNN.png
        novel/parts/<camera>/NNNNNN.png

Frames are numbered from 000000.  Real footage uses the same layout without
``groundtruth/``.  See ``docs/dataset_layout.md`` for units and conventions.

:class:`DatasetWriter` writes it (every file atomically); :meth:`Dataset.open`
reads and validates it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterator, Mapping, Sequence

import numpy as np

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.io.atomic import atomic_save_npz, atomic_write_png, atomic_write_text
from toolkit.io.calibration import read_calibration_toml, write_calibration_toml
from toolkit.io.frames import FRAME_DIGITS, depth_to_mm, frame_filename, mm_to_depth, read_png
from toolkit.io.layout import (
    FPS_RELATIVE_TOLERANCE,
    NOVEL_RESERVED,
    DatasetLayout,
    camera_of,
    check_image,
    check_index,
    check_joints2d,
    check_joints3d,
    load_npz,
)
from toolkit.io.video import DEFAULT_FOURCC, VideoReader, VideoWriter, probe_video

__all__ = ["DatasetLayout", "DatasetWriter", "Dataset", "FPS_RELATIVE_TOLERANCE"]


# ------------------------------------------------------------------ writer
class DatasetWriter:
    """Write a dataset in the layout of this module, every file atomically.

    Parameters
    ----------
    root : str or PathLike
        Dataset folder (created if missing; files already there are replaced).
    fps : float
        Frame rate of the videos.
    fourcc : str
        Video codec (default :data:`toolkit.io.video.DEFAULT_FOURCC`).

    Notes
    -----
    Call :meth:`write_calibration` before the first frame.  Frames of each
    camera stream into ``videos/<camera>.mp4`` in index order.  :meth:`close`
    finishes the videos and then opens the result with :meth:`Dataset.open`,
    so a writer never leaves behind a dataset the reader would reject.  Used
    as a context manager, an exception discards the unfinished videos.

    Examples
    --------
    >>> with DatasetWriter("out/scene01", fps=25) as w:     # doctest: +SKIP
    ...     w.write_calibration(rig)
    ...     for i, images in enumerate(render()):
    ...         for cam in rig:
    ...             w.write_frame(cam.name, i, images[cam.name])
    """

    def __init__(self, root: str | os.PathLike, fps: float, *, fourcc: str = DEFAULT_FOURCC):
        self.layout = DatasetLayout(Path(root))
        if not (
            isinstance(fps, (int, float, np.integer, np.floating)) and np.isfinite(fps) and fps > 0
        ):
            raise InputError("DatasetWriter: fps", "a positive finite frame rate", repr(fps))
        self.fps = float(fps)
        self.fourcc = fourcc
        self.layout.root.mkdir(parents=True, exist_ok=True)
        self._rig: Rig | None = None
        self._gt_rig: Rig | None = None
        self._novel_rig: Rig | None = None
        self._videos: dict[str, VideoWriter] = {}
        self._closed = False

    @property
    def root(self) -> Path:
        return self.layout.root

    def _open_check(self, what: str) -> None:
        if self._closed:
            raise InputError(
                f"DatasetWriter({self.root}).{what}", "an open writer", "a closed writer"
            )

    def _measured(self, what: str) -> Rig:
        self._open_check(what)
        if self._rig is None:
            raise InputError(
                f"DatasetWriter({self.root}).{what}",
                "write_calibration() called first",
                "no calibration yet",
            )
        return self._rig

    def _truth_cam(self, what: str, camera: str) -> Camera:
        rig = self._gt_rig if self._gt_rig is not None else self._measured(what)
        self._open_check(what)
        return camera_of(rig, camera, f"DatasetWriter.{what}: camera")

    def _novel_cam(self, what: str, camera: str) -> Camera:
        self._open_check(what)
        if self._novel_rig is None:
            raise InputError(
                f"DatasetWriter({self.root}).{what}",
                "write_novel_calibration() called first",
                "no novel calibration yet",
            )
        return camera_of(self._novel_rig, camera, f"DatasetWriter.{what}: camera")

    # -- calibrations
    def write_calibration(self, rig: Rig) -> Path:
        """Write ``calibration.toml``: the cameras as measured (what the pipeline gets)."""
        self._open_check("write_calibration")
        if self._videos and set(rig.names) != set(self._rig.names):
            raise InputError(
                "DatasetWriter.write_calibration: rig",
                f"the cameras {self._rig.names} already receiving frames",
                f"{rig.names}",
            )
        path = write_calibration_toml(self.layout.calibration, rig)
        self._rig = rig
        return path

    def write_gt_calibration(self, rig: Rig) -> Path:
        """Write ``groundtruth/calibration.toml``: the true cameras."""
        self._open_check("write_gt_calibration")
        path = write_calibration_toml(self.layout.gt_calibration, rig)
        self._gt_rig = rig
        return path

    def write_novel_calibration(self, rig: Rig) -> Path:
        """Write ``groundtruth/novel/calibration.toml``: the virtual cameras."""
        self._open_check("write_novel_calibration")
        reserved = sorted(set(rig.names) & set(NOVEL_RESERVED))
        if reserved:
            raise InputError(
                "DatasetWriter.write_novel_calibration: rig",
                f"no camera named {NOVEL_RESERVED} (folders of the layout)",
                f"{reserved}",
            )
        path = write_calibration_toml(self.layout.novel_calibration, rig)
        self._novel_rig = rig
        return path

    # -- videos
    def write_frame(self, camera: str, index: int, rgb: np.ndarray) -> None:
        """Append frame ``index`` of ``camera`` to ``videos/<camera>.mp4``.

        Parameters
        ----------
        camera : str
            A camera of the measured calibration.
        index : int
            Must be the number of frames already written for this camera.
        rgb : ndarray of shape (H, W, 3), uint8
            RGB image of the camera's size.
        """
        cam = camera_of(self._measured("write_frame"), camera, "DatasetWriter.write_frame: camera")
        index = check_index("DatasetWriter.write_frame: index", index)
        writer = self._videos.get(camera)
        done = 0 if writer is None else writer.n_frames
        if index != done:
            raise InputError(
                f"DatasetWriter.write_frame({camera!r}): index",
                f"the next frame {done} (videos are written in order)",
                str(index),
            )
        rgb = check_image(f"DatasetWriter.write_frame({camera!r}, {index}): rgb", rgb, cam, 3)
        if writer is None:
            writer = self._videos[camera] = VideoWriter(
                self.layout.video(camera), self.fps, fourcc=self.fourcc
            )
        writer.write(rgb)

    def frames_written(self, camera: str) -> int:
        """How many frames of ``camera`` have been written."""
        w = self._videos.get(camera)
        return 0 if w is None else w.n_frames

    # -- ground-truth images
    def write_mask(self, camera: str, index: int, mask: np.ndarray) -> Path:
        """Write ``groundtruth/masks/<camera>/NNNNNN.png`` (0 / 255) from an (H, W) mask.

        Any non-zero (or True) value marks the subject.
        """
        cam = self._truth_cam("write_mask", camera)
        index = check_index("DatasetWriter.write_mask: index", index)
        m = check_image(f"DatasetWriter.write_mask({camera!r}, {index}): mask", mask, cam, 1)
        return atomic_write_png(
            self.layout.mask(camera, index), np.where(m != 0, 255, 0).astype(np.uint8)
        )

    def write_parts(self, camera: str, index: int, labels: np.ndarray) -> Path:
        """Write ``groundtruth/parts/<camera>/NNNNNN.png`` from (H, W) int labels in [0, 255]."""
        cam = self._truth_cam("write_parts", camera)
        index = check_index("DatasetWriter.write_parts: index", index)
        return atomic_write_png(
            self.layout.parts(camera, index),
            self._labels(f"DatasetWriter.write_parts({camera!r}, {index}): labels", labels, cam),
        )

    def write_depth(self, camera: str, index: int, depth_m: np.ndarray) -> Path:
        """Write ``groundtruth/depth/<camera>/NNNNNN.png`` as uint16 millimetres.

        Parameters
        ----------
        depth_m : ndarray of shape (H, W)
            Camera-frame z in metres; NaN, inf, 0 and depths of 65.535 m or more
            are stored as 0 (no depth).  Negative values raise InputError.
        """
        cam = self._truth_cam("write_depth", camera)
        index = check_index("DatasetWriter.write_depth: index", index)
        where = f"DatasetWriter.write_depth({camera!r}, {index}): depth_m"
        d = check_image(where, depth_m, cam, 1)
        return atomic_write_png(self.layout.depth(camera, index), depth_to_mm(d, where))

    @staticmethod
    def _labels(where: str, labels, cam: Camera) -> np.ndarray:
        a = check_image(where, labels, cam, 1)
        if not (np.issubdtype(a.dtype, np.integer) or a.dtype == bool):
            raise InputError(where, "integer part labels", f"dtype {a.dtype}")
        if a.size and (a.min() < 0 or a.max() > 255):
            raise InputError(where, "labels in [0, 255]", f"range [{a.min()}, {a.max()}]")
        return a.astype(np.uint8)

    # -- novel views
    def write_novel_image(self, camera: str, index: int, rgb: np.ndarray) -> Path:
        """Write ``groundtruth/novel/<camera>/NNNNNN.png`` (RGB uint8, lossless)."""
        cam = self._novel_cam("write_novel_image", camera)
        index = check_index("DatasetWriter.write_novel_image: index", index)
        where = f"DatasetWriter.write_novel_image({camera!r}, {index}): rgb"
        a = check_image(where, rgb, cam, 3)
        if a.dtype != np.uint8:
            raise InputError(where, "a uint8 RGB image", f"dtype {a.dtype}")
        return atomic_write_png(self.layout.novel_image(camera, index), a)

    def write_novel_mask(self, camera: str, index: int, mask: np.ndarray) -> Path:
        """Write ``groundtruth/novel/masks/<camera>/NNNNNN.png`` (0 / 255)."""
        cam = self._novel_cam("write_novel_mask", camera)
        index = check_index("DatasetWriter.write_novel_mask: index", index)
        m = check_image(f"DatasetWriter.write_novel_mask({camera!r}, {index}): mask", mask, cam, 1)
        return atomic_write_png(
            self.layout.novel_mask(camera, index), np.where(m != 0, 255, 0).astype(np.uint8)
        )

    def write_novel_parts(self, camera: str, index: int, labels: np.ndarray) -> Path:
        """Write ``groundtruth/novel/parts/<camera>/NNNNNN.png`` (uint8 part ids)."""
        cam = self._novel_cam("write_novel_parts", camera)
        index = check_index("DatasetWriter.write_novel_parts: index", index)
        where = f"DatasetWriter.write_novel_parts({camera!r}, {index}): labels"
        return atomic_write_png(
            self.layout.novel_parts(camera, index), self._labels(where, labels, cam)
        )

    # -- joints and scene
    def write_joints3d(self, joints: np.ndarray, names: Sequence[str]) -> Path:
        """Write ``groundtruth/joints3d.npz``.

        Parameters
        ----------
        joints : ndarray of shape (T, J, 3)
            World joints in metres (z up); NaN for missing.
        names : sequence of str, length J
        """
        self._open_check("write_joints3d")
        j, n = check_joints3d("DatasetWriter.write_joints3d", joints, list(names))
        return atomic_save_npz(self.layout.joints3d, joints=j, names=n)

    def write_joints2d(self, joints2d: Mapping[str, np.ndarray]) -> Path:
        """Write ``groundtruth/joints2d.npz``: one (T, J, 2) pixel array per camera name."""
        rig = self._gt_rig if self._gt_rig is not None else self._measured("write_joints2d")
        if not joints2d:
            raise InputError(
                "DatasetWriter.write_joints2d: joints2d", "one array per camera", "an empty mapping"
            )
        out, shape = {}, None
        for key, a in joints2d.items():
            camera_of(rig, key, "DatasetWriter.write_joints2d: key")
            a = check_joints2d(
                "DatasetWriter.write_joints2d",
                key,
                a,
                None if shape is None else shape[0],
                None if shape is None else shape[1],
            )
            shape = a.shape
            out[key] = a
        return atomic_save_npz(self.layout.joints2d, **out)

    def write_background(self, camera: str, rgb: np.ndarray) -> Path:
        """Write the clean plate of ``camera`` (the empty scene) to ``background/<camera>.png``."""
        self._open_check("write_background")
        cam = self._measured("write_background")[camera]
        img = np.asarray(rgb)
        w, h = cam.size
        if img.shape != (h, w, 3) or img.dtype != np.uint8:
            raise InputError(f"write_background: {camera}", f"a ({h}, {w}, 3) uint8 RGB image",
                             f"shape {img.shape}, dtype {img.dtype}")
        return atomic_write_png(self.layout.background_dir / f"{camera}.png", img)

    def write_field_model(self, model) -> Path:
        """Write the ground's painted lines (a :class:`toolkit.calibration.FieldModel`) to ``field_model.json``."""
        from toolkit.calibration.field import write_field_model

        self._open_check("write_field_model")
        return write_field_model(self.layout.field_model, model)

    def write_scene_toml(self, text: str) -> Path:
        """Write ``scene.toml`` (a copy of the scene spec)."""
        self._open_check("write_scene_toml")
        return atomic_write_text(self.layout.scene_toml, text)

    @property
    def scene_rrd_path(self) -> Path:
        """Where a rerun recording of the scene belongs (``scene.rrd``)."""
        return self.layout.scene_rrd

    # -- end
    def close(self) -> "Dataset":
        """Finish the videos and validate the dataset by opening it.

        Returns
        -------
        Dataset
            The dataset just written (close it, or use it as a context manager).

        Raises
        ------
        InputError
            Whatever :meth:`Dataset.open` rejects (a camera without frames,
            videos of different lengths, joints of the wrong length, ...).
        """
        self._open_check("close")
        self._closed = True
        for w in self._videos.values():
            w.close()
        return Dataset.open(self.root)

    def abort(self) -> None:
        """Discard unfinished videos (files already written stay)."""
        for w in self._videos.values():
            w.abort()
        self._closed = True

    def __enter__(self) -> "DatasetWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None:
            self.abort()
        elif not self._closed:
            self.close().close()


# ------------------------------------------------------------------ reader
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
        if ds.has_groundtruth:
            ds._validate_groundtruth()
        return ds

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
        for kind in (L.MASKS, L.PARTS, L.DEPTH):
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

    def _validate_frame_folders(self, folder: Path, names: list[str]) -> None:
        if not folder.exists():
            return
        for p in sorted(folder.iterdir()):
            if p.name.startswith("."):
                continue
            if not p.is_dir() or p.name not in names:
                raise InputError(str(p), f"a folder named after a camera {names}", f"{p.name!r}")
            self._validate_frames(p)

    def _validate_frames(self, folder: Path) -> None:
        if not folder.is_dir():
            return
        for p in folder.iterdir():
            if p.name.startswith("."):
                continue  # temporary files of an interrupted atomic write
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

    def _read(self, path: Path, cam: Camera, channels: int, dtype) -> np.ndarray:
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

    # -- optional files
    def background(self, camera: str) -> np.ndarray | None:
        """The clean plate of ``camera`` (``background/<camera>.png``), (H, W, 3) uint8 RGB, or None."""
        cam = self.rig[camera]
        path = self.layout.background_dir / f"{camera}.png"
        if not path.is_file():
            return None
        return self._read(path, cam, 3, np.uint8)

    def field_model(self):
        """The ground's painted lines (``field_model.json``) as a :class:`toolkit.calibration.FieldModel`, or None."""
        from toolkit.calibration.field import read_field_model

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
