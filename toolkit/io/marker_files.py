"""Files of an optical marker capture (issue 17): 2D blobs per camera, and their ground truth.

Layout of a capture folder (written by ``recipes/make_scene.py`` for a spec
with a ``[markers]`` table)::

    markers/calibration.toml              the (measured) rig; [metadata] fps, n_frames, marker_set
    markers/detections/<camera>.npz       centres (N, 2) float64 pixels, frame (N,) int32 ascending,
                                          image_size (2,) int (width, height)
    groundtruth/calibration.toml          the true rig
    groundtruth/markers3d.npz             labels (M,), positions (T, M, 3) metres, segment (M,), fps ()
    groundtruth/joints3d.npz              joints (T, 14, 3) metres, names (14,)
    groundtruth/marker_detections/<camera>.npz
                                          marker (N,) int32: the true marker of each blob (row of the
                                          camera's detections file), -1 for a ghost
    groundtruth/marker_capture.json       what was drawn (occlusion share achieved, ghost count, ...)

Within a frame the blobs of a camera are in random order (the order says
nothing about identity).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.io.atomic import atomic_save_npz
from toolkit.io.layout import check_joints3d, load_npz

__all__ = ["MARKERS_DIR", "DETECTIONS_DIR", "MARKER_TRUTH", "DETECTION_TRUTH_DIR", "CALIBRATION",
           "write_marker_detections", "read_marker_detections", "write_marker_truth", "read_marker_truth",
           "write_detection_truth", "read_detection_truth", "write_joints3d_file"]

#: Paths relative to a capture folder.
MARKERS_DIR = Path("markers")
CALIBRATION = MARKERS_DIR / "calibration.toml"
DETECTIONS_DIR = MARKERS_DIR / "detections"
MARKER_TRUTH = Path("groundtruth") / "markers3d.npz"
DETECTION_TRUTH_DIR = Path("groundtruth") / "marker_detections"


def _field(d: dict, path, key: str) -> np.ndarray:
    if key not in d:
        raise InputError(f"{path}: {key}", f"a '{key}' array", f"fields {sorted(d)}")
    return d[key]


def write_marker_detections(path: str | os.PathLike, centres: np.ndarray, frame: np.ndarray,
                            image_size: tuple[int, int]) -> Path:
    """Write one camera's 2D blobs.

    Parameters
    ----------
    path : str or PathLike
    centres : ndarray of shape (N, 2)
        Pixels.
    frame : ndarray of shape (N,)
        Frame index of each blob, ascending.
    image_size : tuple of int
        ``(width, height)``.
    """
    c = np.asarray(centres, np.float64).reshape(-1, 2)
    f = np.asarray(frame, np.int32).ravel()
    if len(c) != len(f) or (len(f) > 1 and np.any(np.diff(f) < 0)):
        raise InputError(f"{path}: frame", f"{len(c)} ascending frame indices", f"{len(f)} values")
    return atomic_save_npz(path, centres=c, frame=f, image_size=np.asarray(image_size, np.int64))


def read_marker_detections(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """Read one camera's 2D blobs: ``(centres (N, 2), frame (N,), (width, height))``.

    Raises
    ------
    InputError
        Naming the file and the field: missing, mis-shaped, unsorted frames, negative frames.
    """
    p = Path(path)
    d = load_npz(p)
    c = np.asarray(_field(d, p, "centres"), float)
    f = np.asarray(_field(d, p, "frame"))
    s = np.asarray(_field(d, p, "image_size"))
    if c.ndim != 2 or c.shape[1] != 2 or not np.all(np.isfinite(c)):
        raise InputError(f"{p}: centres", "a finite array of shape (N, 2)", f"shape {c.shape}")
    if f.shape != (len(c),) or not np.issubdtype(f.dtype, np.integer):
        raise InputError(f"{p}: frame", f"{len(c)} integer frame indices", f"shape {f.shape}, dtype {f.dtype}")
    if len(f) and (f.min() < 0 or np.any(np.diff(f) < 0)):
        raise InputError(f"{p}: frame", "non-negative frame indices in ascending order", "unsorted or negative")
    if s.shape != (2,) or not np.issubdtype(s.dtype, np.integer) or np.any(s <= 0):
        raise InputError(f"{p}: image_size", "(width, height) as two positive integers", repr(s.tolist()))
    return c, f.astype(np.int64), (int(s[0]), int(s[1]))


def write_marker_truth(path: str | os.PathLike, labels, positions: np.ndarray, segment, fps: float,
                       marker_set: str) -> Path:
    """Write ``groundtruth/markers3d.npz``: ``labels`` (M,), ``positions`` (T, M, 3) m, ``segment`` (M,), ``fps``, ``set``."""
    return atomic_save_npz(path, labels=np.array(list(labels), dtype=str), positions=np.asarray(positions, float),
                           segment=np.array(list(segment), dtype=str), fps=np.float64(fps),
                           set=np.array(marker_set))


def read_marker_truth(path: str | os.PathLike) -> dict:
    """Read ``groundtruth/markers3d.npz`` as a dict (``labels`` tuple, ``positions``, ``segment`` tuple, ``fps``)."""
    p = Path(path)
    d = load_npz(p)
    labels = tuple(np.asarray(_field(d, p, "labels")).astype(str).tolist())
    pos = np.asarray(_field(d, p, "positions"), float)
    seg = tuple(np.asarray(_field(d, p, "segment")).astype(str).tolist())
    if pos.ndim != 3 or pos.shape[1:] != (len(labels), 3):
        raise InputError(f"{p}: positions", f"an array of shape (T, {len(labels)}, 3)", f"shape {pos.shape}")
    if len(seg) != len(labels):
        raise InputError(f"{p}: segment", f"{len(labels)} segment names", f"{len(seg)}")
    fps = float(d["fps"]) if "fps" in d else float("nan")
    return {"labels": labels, "positions": pos, "segment": seg, "fps": fps,
            "set": str(d["set"]) if "set" in d else ""}


def write_detection_truth(path: str | os.PathLike, marker: np.ndarray) -> Path:
    """Write ``groundtruth/marker_detections/<camera>.npz``: ``marker`` (N,) int32, -1 for a ghost."""
    return atomic_save_npz(path, marker=np.asarray(marker, np.int32).ravel())


def read_detection_truth(path: str | os.PathLike, n_markers: int | None = None) -> np.ndarray:
    """Read the true marker index of each blob (N,), -1 for a ghost."""
    p = Path(path)
    m = np.asarray(_field(load_npz(p), p, "marker"))
    if m.ndim != 1 or not np.issubdtype(m.dtype, np.integer) or (len(m) and m.min() < -1):
        raise InputError(f"{p}: marker", "marker indices (N,) >= -1", f"shape {m.shape}, dtype {m.dtype}")
    if n_markers is not None and len(m) and m.max() >= n_markers:
        raise InputError(f"{p}: marker", f"indices below {n_markers}", str(int(m.max())))
    return m.astype(np.int64)


def write_joints3d_file(path: str | os.PathLike, joints: np.ndarray, names) -> Path:
    """Write a ``joints3d.npz`` in the dataset format (``joints`` (T, J, 3) metres, ``names`` (J,))."""
    j, n = check_joints3d(str(path), joints, list(names))
    return atomic_save_npz(path, joints=j, names=n)
