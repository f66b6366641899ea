"""Writing a dataset folder (:mod:`toolkit.io.dataset` describes the layout; every file atomically)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.io.atomic import atomic_save_npz, atomic_write_png, atomic_write_text
from toolkit.io.calibration import write_calibration_toml
from toolkit.io.dataset import Dataset
from toolkit.io.field_model import write_field_model
from toolkit.io.frames import depth_to_mm
from toolkit.io.layout import (
    NOVEL_RESERVED,
    DatasetLayout,
    camera_of,
    check_image,
    check_index,
    check_joints2d,
    check_joints3d,
    check_people,
)
from toolkit.io.video import DEFAULT_FOURCC, VideoWriter

__all__ = ["DatasetWriter"]


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

    def write_instances(self, camera: str, index: int, ids: np.ndarray) -> Path:
        """Write ``groundtruth/instances/<camera>/NNNNNN.png``: which person each pixel shows.

        Parameters
        ----------
        ids : ndarray of shape (H, W), integer
            0 background, ``k`` = person ``k - 1`` of ``people.npz`` (the front-most body),
            at most 255.
        """
        cam = self._truth_cam("write_instances", camera)
        index = check_index("DatasetWriter.write_instances: index", index)
        where = f"DatasetWriter.write_instances({camera!r}, {index}): ids"
        return atomic_write_png(
            self.layout.instances(camera, index), self._labels(where, ids, cam)
        )

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

    def write_novel_instances(self, camera: str, index: int, ids: np.ndarray) -> Path:
        """Write ``groundtruth/novel/instances/<camera>/NNNNNN.png`` (uint8 person ids)."""
        cam = self._novel_cam("write_novel_instances", camera)
        index = check_index("DatasetWriter.write_novel_instances: index", index)
        where = f"DatasetWriter.write_novel_instances({camera!r}, {index}): ids"
        return atomic_write_png(
            self.layout.novel_instances(camera, index), self._labels(where, ids, cam)
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

    def write_people(self, joints: np.ndarray, names: Sequence[str]) -> Path:
        """Write ``groundtruth/people.npz``: every person's joints.

        Parameters
        ----------
        joints : ndarray of shape (P, T, J, 3)
            World joints in metres (z up) of the ``P`` people (person ``p`` is instance id
            ``p + 1``); NaN where a person is absent.
        names : sequence of str, length J
        """
        self._open_check("write_people")
        j, n = check_people("DatasetWriter.write_people", joints, list(names))
        return atomic_save_npz(self.layout.people, joints=j, names=n)

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
        """Write the ground's painted lines (a :class:`~toolkit.io.field_model.FieldModel`) to ``field_model.json``."""
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
    def close(self) -> Dataset:
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

