"""Everything a keypoint triangulation needs, from a keypoints folder or a Pose2Sim trial.

It reads the files through :mod:`toolkit.io` and picks one person per frame with the
multi-view association of :mod:`toolkit.multiview.tracking`, so it lives in the layer
between the stages, not in ``io`` (which runs no algorithm).

:func:`open_keypoint_session` resolves, in one place, what ``recipes/pose_from_keypoints.py``
is given: a folder of per-camera keypoints or a Pose2Sim trial (toolkit.io.pose2sim), the
calibration (given, or the session's), the cameras matched to the keypoint sources
(toolkit.io.keypoint_files), the keypoint format (given, the Pose2Sim ``pose_model``, or
found from the files) and the frame rate (given, or the Pose2Sim ``frame_rate``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.io.calibration import read_calibration
from toolkit.io.keypoint_files import camera_sources, match_cameras
from toolkit.io.keypoint_formats import KeypointInput, read_keypoints
from toolkit.io.pose2sim import Pose2SimTrial, is_pose2sim_trial, read_pose2sim_trial
from toolkit.multiview.tracking import DEFAULT_FPS, TrackingConfig, frame_detections, main_person

__all__ = ["KeypointSession", "open_keypoint_session"]


@dataclass(frozen=True, eq=False)
class KeypointSession:
    """Cameras and keypoints ready to triangulate.

    Attributes
    ----------
    rig : Rig
        The calibration's cameras sorted by name; camera ``c`` sees ``keypoints.keypoints[c]``.
    sources : tuple of Path
        Per camera its keypoint folder or file.
    matching : str
        How sources were matched to cameras (``by name``, ``by number``, ``by order``).
    calibration : Path
    keypoints_root : Path
        The folder holding the sources.
    trial : Pose2SimTrial or None
        The Pose2Sim trial read, if any.
    keypoints : KeypointInput
        Keypoints (n_cams, T, K, 3), frames, format and why, missing and empty frames.
    fps : float or None
        The frame rate given or from the Pose2Sim settings (``None`` when neither says).
    fps_from : str or None
        Where ``fps`` comes from.
    """

    rig: Rig
    sources: tuple[Path, ...]
    matching: str
    calibration: Path
    keypoints_root: Path
    trial: Pose2SimTrial | None
    keypoints: KeypointInput
    fps: float | None
    fps_from: str | None


def frame_offsets(root: Path, sources) -> list[int] | None:
    """Per source, the frames it started late according to ``root/sync.json`` (None without one).

    Raises
    ------
    InputError
        A ``sync.json`` that names none of the sources.
    """
    from toolkit.pipeline.detect_keypoints import SYNC_FILE, read_sync

    offsets = read_sync(root)
    if offsets is None:
        return None
    names = [Path(s).stem if Path(s).is_file() else Path(s).name for s in sources]
    if not set(offsets) & set(names):
        raise InputError(str(Path(root) / SYNC_FILE), f"offsets for the cameras {names}", f"{sorted(offsets)}")
    return [int(offsets.get(n, 0)) for n in names]


def _videos_without_keypoints(root: Path) -> bool:
    from toolkit.io.video import VIDEO_SUFFIXES

    return (root.is_dir() and not _camera_sources_or_none(root)
            and any(p.suffix.lower() in VIDEO_SUFFIXES for p in root.iterdir()))


def _camera_sources_or_none(root: Path) -> list:
    """The keypoint sources of ``root``, or an empty list when it holds none."""
    try:
        return camera_sources(root)
    except InputError:
        return []


def open_keypoint_session(keypoints: str | os.PathLike, calibration: str | os.PathLike | None = None,
                          fmt: str | None = None, fps: float | None = None, person: str = "consensus",
                          max_frames: int | None = None, detect_into: str | os.PathLike | None = None,
                          detect_config=None, log=None) -> KeypointSession:
    """Read the keypoints and calibration of a folder or a Pose2Sim trial.

    Parameters
    ----------
    keypoints : path-like
        A folder with one sub-folder (or one JSON file) of keypoints per camera, or a
        Pose2Sim trial folder (or its ``pose/`` / ``pose-associated/`` folder).
    calibration : path-like, optional
        The calibration file; default: the Pose2Sim session's ``Calib*.toml``.
    fmt : str, optional
        The keypoint format; default: the Pose2Sim ``pose_model``, else found from the files.
    fps : float, optional
        The frame rate; default: the Pose2Sim ``frame_rate``.
    person : str
        How to pick one person per frame: ``"consensus"`` (default), the person most cameras
        agree on (``toolkit.multiview.tracking.main_person``: detections grouped across views
        by ray distance and linked over time; the detections as given when no view holds
        more than one), or a per-view policy of toolkit.io.keypoint_formats.select_person.
    max_frames : int, optional
        Keep only the first frames.
    detect_into : path-like, optional
        Where to detect keypoints when ``keypoints`` is a trial with videos and no keypoints (or a
        folder of videos): toolkit.pipeline.detect_keypoints runs there (kept, reused when complete).
    detect_config : DetectConfig, optional
        The detection's options (default: the built-in detector's).
    log : callable, optional
        Receives a line when detection runs.

    Returns
    -------
    KeypointSession

    Raises
    ------
    InputError
        No calibration, cameras and sources that do not match, or bad keypoint files
        (each error names the file or argument).
    """
    trial = read_pose2sim_trial(keypoints) if is_pose2sim_trial(keypoints) else None
    root = trial.keypoints if trial is not None else Path(keypoints)
    videos = trial.videos if trial is not None and root is None else (
        Path(keypoints) if root is not None and _videos_without_keypoints(Path(keypoints)) else None)
    if videos is not None:
        if detect_into is None:
            raise InputError(str(keypoints), "keypoint files (or an output folder to detect them into)",
                             f"videos only ({videos})")
        from toolkit.pipeline.detect_keypoints import DetectConfig, ensure_keypoints

        config = detect_config or DetectConfig()
        if max_frames is not None and config.max_frames is None:
            config = replace(config, max_frames=max_frames)
        root = ensure_keypoints(videos, detect_into, config, log=log or print)
    calib = Path(calibration) if calibration is not None else (trial.calibration if trial is not None else None)
    if calib is None:
        raise InputError("--calibration", "a calibration file (or a Pose2Sim trial whose session has one)",
                         f"none given and none found for {keypoints}")
    cams = sorted(read_calibration(calib), key=lambda c: c.name)
    sources = camera_sources(root)
    order, matching = match_cameras([c.name for c in cams], sources, f"{root}: camera sources")
    sources = tuple(sources[i] for i in order)
    declared_by = "--format"
    if fmt is None and trial is not None and trial.pose_model is not None:
        fmt, declared_by = trial.pose_model, "[pose] pose_model of the Pose2Sim Config.toml"
    data = read_keypoints(list(sources), fmt, declared_by, person="most_confident" if person == "consensus" else person,
                          max_frames=max_frames, frame_offsets=frame_offsets(root, sources))
    fps_from = "--fps" if fps is not None else None
    if fps is None and trial is not None and trial.frame_rate is not None:
        fps, fps_from = trial.frame_rate, "Pose2Sim Config.toml"
    if fps is None:
        from toolkit.pipeline.detect_keypoints import DETECTION_FILE, detected_frame_rate

        fps = detected_frame_rate(root)
        fps_from = f"the videos ({Path(root) / DETECTION_FILE})" if fps is not None else None
    if person == "consensus":
        dets = frame_detections(data.cameras, data.frames, data.keypoints.shape[2])
        data = replace(data, keypoints=main_person(dets, Rig(tuple(cams)),
                                                   TrackingConfig(fps=fps if fps is not None else DEFAULT_FPS)))
    return KeypointSession(rig=Rig(tuple(cams)), sources=sources, matching=matching, calibration=calib,
                           keypoints_root=root, trial=trial, keypoints=data, fps=fps, fps_from=fps_from)
