"""A Pose2Sim session folder read as it is.

Pose2Sim lays a session out as::

    Session/                      Config.toml, the session's settings
      S00_Calibration/            Calib*.toml (cameras [cam_01] ... as Pose2Sim writes them)
      Participant/                Config.toml (optional, overrides the session's)
        Trial/                    Config.toml (optional, overrides the participant's)
          pose/                   raw 2D detections, one folder per camera (cam01_json/ ...)
          pose-associated/        the same with the main person picked (Pose2Sim's personAssociation)
          pose-3d/                Pose2Sim's own triangulation (.trc)

or without the participant level (``Session/Trial/``), or, as Pose2Sim's current demos are laid
out, a trial holding its own ``calibration/`` (``Calib.qca.txt`` from Qualisys, or a ``.toml``)
and ``videos/`` but no keypoints yet (its own detector makes them): ``keypoints`` is then ``None``
and ``videos`` the folder to detect people in (toolkit.pipeline.detect_keypoints).  :func:`read_pose2sim_trial`
takes a trial folder and finds the keypoints (``pose-associated`` when there, else
``pose``; or the one of the two it is given), the calibration file, the keypoint format (``[pose] pose_model``) and the
frame rate (``[project] frame_rate``) with Pose2Sim's own precedence (trial, then
participant, then session settings).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from toolkit.errors import InputError
from toolkit.io.text import load_toml
from toolkit.io.video import VIDEO_SUFFIXES

__all__ = ["POSE_MODELS", "Pose2SimTrial", "is_pose2sim_trial", "participant_height", "read_pose2sim_trial"]

#: Pose2Sim ``pose_model`` names (upper case) -> keypoint formats of toolkit.skeleton.mappings.
POSE_MODELS = {"BODY_25B": "body_25b", "BODY_25": "body_25", "COCO": "coco_18", "COCO_18": "coco_18",
               "COCO_17": "coco_17", "BODY": "coco_17", "HALPE_26": "halpe_26", "BODY_WITH_FEET": "halpe_26",
               "COCO_133": "coco_133", "WHOLE_BODY": "coco_133", "COCO_133_WRIST": "coco_133",
               "BLAZEPOSE": "blazepose_33"}
#: Keypoint folders of a trial, in order of preference.
POSE_FOLDERS = ("pose-associated", "pose")


@dataclass(frozen=True)
class Pose2SimTrial:
    """What a Pose2Sim trial folder holds.

    Attributes
    ----------
    trial : Path
    keypoints : Path or None
        ``pose-associated`` (or ``pose``): one sub-folder of JSON files per camera; ``None`` for a
        trial with videos and no keypoints.
    calibration : Path or None
        The session's (or the trial's own) ``Calib*.toml``, else its ``*.qca.txt``.
    pose_model : str or None
        The keypoint format (:data:`POSE_MODELS`) of the settings, ``None`` when not set.
    frame_rate : float or None
        ``[project] frame_rate`` when a number (``None`` for ``'auto'`` or not set).
    config_files : tuple of Path
        The ``Config.toml`` files read, session first.
    reference_trc : tuple of Path
        Pose2Sim's own results (``pose-3d/*.trc``).
    """

    trial: Path
    keypoints: Path
    calibration: Path | None
    pose_model: str | None
    frame_rate: float | None
    config_files: tuple[Path, ...]
    reference_trc: tuple[Path, ...]
    videos: Path | None = None


#: Video folders of a trial (Pose2Sim: ``videos/``).
VIDEO_FOLDERS = ("videos", "video")


def _videos_of(p: Path) -> Path | None:
    """The trial's folder of videos, if it has one holding videos."""
    for f in VIDEO_FOLDERS:
        folder = p / f
        if folder.is_dir() and any(v.suffix.lower() in VIDEO_SUFFIXES for v in folder.iterdir()):
            return folder
    return None


def _holds_videos_and_calibration(p: Path) -> bool:
    """A trial of today's layout: videos, and a calibration folder in it or above it."""
    return (p.is_dir() and _videos_of(p) is not None
            and any(_calibration_dir(up) is not None for up in (p, p.parent, p.parent.parent)))


def _holds_pose(p: Path) -> bool:
    return p.is_dir() and any((p / f).is_dir() for f in POSE_FOLDERS)


def _pose_folder_of_trial(p: Path) -> bool:
    """``p`` is a trial's ``pose/`` (or ``pose-associated/``) with Pose2Sim settings or calibration around."""
    trial = p.parent
    return (p.is_dir() and p.name in POSE_FOLDERS and not _holds_pose(p)
            and ((trial / "Config.toml").is_file() or any(_calibration_dir(up) is not None
                                                          for up in (trial.parent, trial.parent.parent))))


def is_pose2sim_trial(path: str | os.PathLike) -> bool:
    """Whether ``path`` is read as a Pose2Sim trial: a folder holding ``pose-associated/`` or ``pose/``,
    or one of those folders inside a trial (to read, say, the raw ``pose/`` rather than ``pose-associated/``)."""
    p = Path(path)
    return _holds_pose(p) or _pose_folder_of_trial(p) or _holds_videos_and_calibration(p)


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def _calibration_dir(folder: Path) -> Path | None:
    subs = [p for p in folder.iterdir() if p.is_dir() and "calib" in p.name.lower()] if folder.is_dir() else []
    return sorted(subs)[0] if subs else None


def read_pose2sim_trial(path: str | os.PathLike) -> Pose2SimTrial:
    """The keypoints, calibration and settings of a Pose2Sim trial folder.

    Parameters
    ----------
    path : path-like
        The trial folder (holding ``pose-associated/`` or ``pose/``), or one of those two
        folders inside it (that one is read).

    Returns
    -------
    Pose2SimTrial

    Raises
    ------
    InputError
        Not a trial folder, an unreadable ``Config.toml``, a ``pose_model`` the toolkit has no
        mapping for, a bad ``frame_rate``, or several calibration files (each names the file).
    """
    trial = Path(path)
    if _pose_folder_of_trial(trial):
        trial, keypoints = trial.parent, trial
    elif _holds_pose(trial):
        keypoints = next(trial / f for f in POSE_FOLDERS if (trial / f).is_dir())
    elif _holds_videos_and_calibration(trial):
        keypoints = None
    else:
        raise InputError(str(trial), f"a Pose2Sim trial folder holding one of {list(POSE_FOLDERS)}, or videos/ "
                         "and a calibration folder", "none of them")
    # the session is the first folder (the trial itself, or one above it) that holds a calibration folder
    session, calib_dir = None, None
    for up in (trial, trial.parent, trial.parent.parent):
        calib_dir = _calibration_dir(up)
        if calib_dir is not None:
            session = up
            break
    levels = [trial]
    if session is not None and session != trial:
        p = trial.parent
        while p != session and session in p.parents:
            levels.append(p)
            p = p.parent
        levels.append(session)
    config, files = {}, []
    for folder in reversed(levels):  # session first, trial last (the trial's settings win)
        f = folder / "Config.toml"
        if f.is_file():
            config = _merge(config, load_toml(f, "a readable Pose2Sim Config.toml"))
            files.append(f)
    where = str(files[-1]) if files else str(trial)
    model = config.get("pose", {}).get("pose_model") if isinstance(config.get("pose"), dict) else None
    fmt = None
    if model is not None and keypoints is not None:   # without keypoints, the pose_model is another detector's
        fmt = POSE_MODELS.get(str(model).upper())
        if fmt is None:
            raise InputError(f"{where}: [pose] pose_model", f"one of {sorted(POSE_MODELS)}", repr(model))
    rate = config.get("project", {}).get("frame_rate") if isinstance(config.get("project"), dict) else None
    if rate is not None and not (isinstance(rate, str) and rate.lower() == "auto"):
        if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not rate > 0:
            raise InputError(f"{where}: [project] frame_rate", "a positive number or 'auto'", repr(rate))
        rate = float(rate)
    else:
        rate = None
    calibration = None
    if calib_dir is not None:
        found = (sorted(calib_dir.glob("Calib*.toml")) or sorted(calib_dir.glob("*.toml"))
                 or sorted(calib_dir.glob("*.qca.txt")))
        if len(found) > 1:
            raise InputError(str(calib_dir), "one calibration .toml or .qca.txt (else give --calibration)",
                             f"{[t.name for t in found]}")
        calibration = found[0] if found else None
    trc = tuple(sorted((trial / "pose-3d").glob("*.trc"))) if (trial / "pose-3d").is_dir() else ()
    return Pose2SimTrial(trial=trial, keypoints=keypoints, calibration=calibration, pose_model=fmt,
                         frame_rate=rate, config_files=tuple(files), reference_trc=trc, videos=_videos_of(trial))


#: Statures (metres) accepted from a Pose2Sim ``participant_height``; others are ignored.
PARTICIPANT_HEIGHT_RANGE_M = (1.0, 2.5)


def participant_height(config_files) -> tuple[float | None, str | None]:
    """``[markerAugmentation] participant_height`` of the Pose2Sim settings.

    Parameters
    ----------
    config_files : iterable of path
        The ``Config.toml`` files in Pose2Sim's precedence (session, participant, trial).

    Returns
    -------
    height_m : float or None
        The last file's that sets a single number within :data:`PARTICIPANT_HEIGHT_RANGE_M`
        (unreadable files and lists of heights are skipped).
    source : str or None
        ``participant_height of FILE``; ``(None, None)`` when no file sets one.
    """
    lo, hi = PARTICIPANT_HEIGHT_RANGE_M
    found = (None, None)
    for f in config_files:
        try:
            doc = load_toml(f, "a Pose2Sim Config.toml")
        except InputError:
            continue
        h = doc.get("markerAugmentation", {}).get("participant_height")
        if isinstance(h, (int, float)) and lo <= h <= hi:
            found = (float(h), f"participant_height of {f}")
    return found
