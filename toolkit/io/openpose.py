"""Reader of OpenPose JSON output: one file per frame, one folder per camera.

OpenPose writes ``{"people": [{"pose_keypoints_2d": [x0, y0, c0, x1, ...]}, ...]}``
per frame, with ``(0, 0, 0)`` for undetected keypoints.  Here undetected
keypoints (and those with a NaN confidence) come back as ``(NaN, NaN, 0)``; a
negative confidence raises, naming the file.  A person without
``pose_keypoints_2d`` (Pose2Sim writes ``{}`` when it found nobody to
associate) and a frame without people are all-missing frames, not errors.

Frames of a folder are ordered by the last number in the file name
(``cam01.0012.json`` is frame 12; OpenPose writes ``..._000000000012_keypoints.json``);
files without a number are ordered by name and numbered by position.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.io.text import load_json

#: How to pick one person when a file holds several: the largest summed confidence.
PERSON_POLICIES = ("most_confident", "first")

_NUMBER = re.compile(r"(\d+)")


@dataclass(frozen=True, eq=False)
class OpenPoseFolder:
    """The keypoints of one camera.

    Attributes
    ----------
    folder : Path
    files : tuple of str
        File names, in frame order.
    frames : ndarray of shape (T,) of int
        Frame numbers.
    keypoints : ndarray of shape (T, K, 3)
        Pixels and confidence; NaN coordinates and 0 confidence where missing.
    """

    folder: Path
    files: tuple[str, ...]
    frames: np.ndarray
    keypoints: np.ndarray


def _frame_number(name: str) -> int | None:
    nums = _NUMBER.findall(Path(name).stem)
    return int(nums[-1]) if nums else None


def read_openpose_json(path: str | os.PathLike, n_keypoints: int | None = None,
                       person: str = "most_confident") -> np.ndarray:
    """Keypoints of one person in one OpenPose JSON file.

    Parameters
    ----------
    path : path-like
    n_keypoints : int, optional
        Expected keypoints per person (25 for BODY_25 and BODY_25B, 17 for COCO-17); a
        person with another count raises.  When ``None`` the count is taken from the file,
        and a file without any person returns an array of shape (0, 3).
    person : str
        ``"most_confident"`` (largest summed confidence) or ``"first"``.

    Returns
    -------
    ndarray of shape (K, 3)
        ``(x, y, confidence)``; NaN coordinates and confidence 0 for undetected keypoints,
        all missing when the file holds no person with keypoints.

    Raises
    ------
    InputError
        Unreadable or malformed JSON, or a wrong keypoint count, naming the file.
    """
    p = Path(path)
    if person not in PERSON_POLICIES:
        raise InputError("person", f"one of {list(PERSON_POLICIES)}", repr(person))
    data = load_json(p, "a readable OpenPose JSON file")
    if not isinstance(data, dict) or not isinstance(data.get("people", []), list):
        raise InputError(f"{p}: people", "a list of people", type(data.get("people") if isinstance(data, dict)
                                                               else data).__name__)
    people = []
    for i, pers in enumerate(data.get("people", [])):
        kp = pers.get("pose_keypoints_2d") if isinstance(pers, dict) else None
        if not kp:  # a person without keypoints counts as missing
            continue
        try:
            arr = np.asarray(kp, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"{p}: people[{i}].pose_keypoints_2d", "a list of numbers", repr(kp)[:80]) from None
        if arr.ndim != 1 or arr.size % 3:
            raise InputError(f"{p}: people[{i}].pose_keypoints_2d", "a flat list of (x, y, c) triples",
                             f"{arr.size} values")
        arr = arr.reshape(-1, 3)
        if n_keypoints is not None and len(arr) != n_keypoints:
            raise InputError(f"{p}: people[{i}].pose_keypoints_2d", f"{n_keypoints} keypoints for the chosen format",
                             f"{len(arr)}")
        bad = np.flatnonzero((arr[:, 2] < 0) | np.isinf(arr[:, 2]))
        if bad.size:  # no detector writes one: the file is not what it seems
            raise InputError(f"{p}: people[{i}].pose_keypoints_2d", "finite confidences >= 0 (0 = not detected)",
                             f"{arr[bad[0], 2]:g} at keypoint {int(bad[0])}")
        people.append(arr)
    if not people:
        empty = np.full((n_keypoints or 0, 3), np.nan)
        empty[:, 2] = 0.0
        return empty
    chosen = people[0] if person == "first" else max(people, key=lambda a: np.nansum(a[:, 2]))
    out = chosen.copy()
    missing = ~(out[:, 2] > 0) | ~np.isfinite(out[:, :2]).all(axis=1)
    out[missing, :2] = np.nan
    out[missing, 2] = 0.0
    return out


def frame_files(folder: Path, what: str, max_frames: int | None = None) -> tuple[list[Path], np.ndarray]:
    """A folder's per-frame JSON files in frame order and their frame numbers.

    Frame numbers come from the file names (the last number in each), else the
    files' order.  Raises InputError naming the folder when it holds no JSON
    file (``what`` says what was expected) or two files claim one frame number.
    """
    files = _json_files(folder)
    if not files:
        raise InputError(str(folder), what, "none")
    if max_frames is not None:
        files = files[:max_frames]
    numbers = [_frame_number(f.name) for f in files]
    if not all(n is not None for n in numbers):
        return files, np.arange(len(files))
    dup = sorted({n for n in numbers if numbers.count(n) > 1})
    if dup:
        raise InputError(str(folder), "one JSON file per frame number", f"duplicated frame numbers {dup[:5]}")
    return files, np.array(numbers, int)


def _json_files(folder: Path) -> list[Path]:
    if not folder.is_dir():
        raise InputError(str(folder), "a folder of OpenPose JSON files", "no such folder")
    files = [f for f in folder.iterdir() if f.suffix.lower() == ".json" and f.is_file()]
    numbers = [_frame_number(f.name) for f in files]
    if files and all(n is not None for n in numbers):
        return [f for _, f in sorted(zip(numbers, files), key=lambda x: (x[0], x[1].name))]
    return sorted(files, key=lambda f: f.name)


def read_openpose_folder(folder: str | os.PathLike, n_keypoints: int, person: str = "most_confident",
                         max_frames: int | None = None) -> OpenPoseFolder:
    """Keypoints of every JSON file of one camera's folder.

    Parameters
    ----------
    folder : path-like
    n_keypoints : int
        Keypoints per person of the format.
    person : str
        See :func:`read_openpose_json`.
    max_frames : int, optional
        Read only the first frames.

    Returns
    -------
    OpenPoseFolder

    Raises
    ------
    InputError
        A missing folder, a folder without JSON files, duplicated frame numbers, or a bad
        file (named).
    """
    d = Path(folder)
    files, frames = frame_files(d, "OpenPose JSON files (*.json)", max_frames)
    kps = np.stack([read_openpose_json(f, n_keypoints, person) for f in files])
    return OpenPoseFolder(folder=d, files=tuple(f.name for f in files), frames=frames, keypoints=kps)


def camera_folders(root: str | os.PathLike) -> list[Path]:
    """Sub-folders of ``root`` (one per camera), in sorted order; hidden folders are skipped."""
    r = Path(root)
    if not r.is_dir():
        raise InputError(str(r), "a folder with one sub-folder of OpenPose JSON files per camera", "no such folder")
    subs = sorted((p for p in r.iterdir() if p.is_dir() and not p.name.startswith(".")), key=lambda p: p.name)
    if not subs:
        raise InputError(str(r), "one sub-folder of OpenPose JSON files per camera", "no sub-folders")
    return subs


def read_openpose_cameras(root: str | os.PathLike, n_keypoints: int, person: str = "most_confident",
                          max_frames: int | None = None) -> tuple[list[OpenPoseFolder], np.ndarray, np.ndarray]:
    """Keypoints of every camera, aligned on frame numbers.

    Parameters
    ----------
    root : path-like
        Folder with one sub-folder per camera (sorted by name).
    n_keypoints : int
    person : str
    max_frames : int, optional
        Keep only the first ``max_frames`` frame numbers of the union.

    Returns
    -------
    folders : list of OpenPoseFolder
        One per camera, sorted by folder name.
    frames : ndarray of shape (T,) of int
        The union of frame numbers, sorted.
    keypoints : ndarray of shape (n_cams, T, K, 3)
        NaN / confidence 0 where a camera has no file for a frame (a shorter video).
    """
    folders = [read_openpose_folder(d, n_keypoints, person, max_frames) for d in camera_folders(root)]
    frames = np.unique(np.concatenate([f.frames for f in folders]))
    if max_frames is not None:
        frames = frames[:max_frames]
    kp = np.full((len(folders), len(frames), n_keypoints, 3), np.nan)
    kp[..., 2] = 0.0
    pos = {n: i for i, n in enumerate(frames.tolist())}
    for c, f in enumerate(folders):
        for t, n in enumerate(f.frames.tolist()):
            if n in pos:
                kp[c, pos[n]] = f.keypoints[t]
    return folders, frames, kp


def write_openpose_json(path: str | os.PathLike, people) -> Path:
    """Write one frame's people as an OpenPose JSON file (atomically).

    Parameters
    ----------
    path : path-like
        The file, e.g. ``keypoints/<camera>/<camera>_000012_keypoints.json``.
    people : sequence of ndarray of shape (K, 3)
        Per person ``(x, y, confidence)`` in pixels; NaN coordinates (missing) are written
        as OpenPose does, ``0, 0, 0``.

    Returns
    -------
    Path
    """
    from toolkit.io.atomic import atomic_write_text

    out = []
    for p in people:
        k = np.array(p, float).reshape(-1, 3)
        bad = ~np.isfinite(k).all(-1)
        k[bad] = 0.0
        out.append({"person_id": [-1], "pose_keypoints_2d": [float(v) for v in k.ravel()]})
    return atomic_write_text(path, json.dumps({"version": 1.3, "people": out}))
