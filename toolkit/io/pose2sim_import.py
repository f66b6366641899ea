"""A Pose2Sim trial turned into the project's dataset layout.

:func:`import_pose2sim_trial` reads a trial (its ``videos/``, its ``pose/`` or
``pose-associated/`` keypoints and the session's calibration, found by
:func:`toolkit.io.pose2sim.read_pose2sim_trial`) and writes::

    OUT/
      calibration.toml          the calibration's cameras, sizes set to the videos' (see below)
      videos/<camera>.mp4       links to the trial's videos (or copies; re-encoded only to trim them)
      keypoints/<camera>/       links to (or copies of) the per-frame OpenPose JSON files, names kept
                                (renumbered ``<camera>_<frame:012d>_keypoints.json`` when shifted)
      import.json               what was found and what was done (written last)

A trial with videos and no keypoints is imported from a keypoints folder given (``keypoints``: one
sub-folder per camera, e.g. what ``toolkit.pipeline.detect_keypoints`` wrote;
``toolkit.pipeline.trial_input.import_trial`` detects and then calls this function).

Cameras keep the calibration's names; the videos and keypoint folders are matched
to them with :func:`toolkit.io.keypoint_files.match_cameras` (by name:
``cam01.mp4`` and ``cam01_json`` are ``cam_01``; else by the numbers in the names;
else by sorted order, which is reported).  Mismatches are handled and reported,
never ignored:

* **Counts.** Fewer (or more) videos or keypoint folders than cameras, or keypoint
  folders that name no camera (nor video), are errors.
* **Frame sizes.** A video whose size differs from its camera's calibrated size by
  at most :data:`PAD_TOLERANCE_PX` pixels in each direction is taken as the same
  image cropped or padded at the right and bottom (what codecs do to reach a
  multiple of 8 or 16 pixels): the intrinsics are kept (so the principal point
  stays where the calibration measured it) and the size is set to the video's.  A
  video that is the calibrated image resized (same aspect ratio) gets the camera
  scaled (:meth:`toolkit.cameras.Camera.scaled`).  Anything else is an error.  The
  Pose2Sim demo states 1088x1920 for its four cameras where the videos of
  ``cam01`` and ``cam02`` are 1080x1920: their size becomes 1080x1920, K is kept.
* **Frame counts.** Videos and keypoint folders are trimmed to their common length
  (the shortest video, and the last keypoint frame + 1 of the shortest keypoint
  folder); a video longer than that is re-encoded (``mp4v``) to its first frames,
  keypoint files beyond it are left out.
* **Frame rates.** Videos with different rates are an error; a ``frame_rate`` of
  the Pose2Sim settings unlike the videos' is reported (the videos' is kept).
* **Late starts** (``frame_offsets``: camera ``c`` started ``k_c`` frames late, the meaning of
  ``sync.json``, toolkit.detection.sync).  Every camera's frame 0 is made to show the same instant,
  the start of the camera that started last: camera ``c`` loses its first ``max(k) - k_c`` frames
  (its video re-encoded, its keypoint files renumbered by as much, those before dropped), then all
  are trimmed to the common length.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path


from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.io.video import VIDEO_SUFFIXES
from toolkit.io.atomic import atomic_path, atomic_write_text, temp_path
from toolkit.io.calibration import read_calibration, write_calibration_toml
from toolkit.io.keypoint_files import camera_sources, match_cameras
from toolkit.io.layout import FPS_RELATIVE_TOLERANCE, DatasetLayout
from toolkit.io.openpose import frame_files
from toolkit.io.pose2sim import POSE_FOLDERS, read_pose2sim_trial
from toolkit.io.video import VideoReader, VideoWriter, probe_video

__all__ = ["IMPORT_JSON", "PAD_TOLERANCE_PX", "VIDEO_SUFFIXES", "ImportResult", "fit_camera_to_video",
           "import_pose2sim_trial"]

#: Largest size difference (pixels, per direction) read as codec padding or cropping at the
#: right / bottom edge: encoders pad frames to multiples of 8 or 16 pixels.
PAD_TOLERANCE_PX = 16
#: Relative aspect-ratio difference below which a video of another size is the calibrated image resized.
ASPECT_TOLERANCE = 2e-3
#: The import's report, written last into the dataset folder.
IMPORT_JSON = "import.json"


@dataclass(frozen=True)
class ImportResult:
    """What :func:`import_pose2sim_trial` did.

    Attributes
    ----------
    out : Path
        The dataset folder written.
    rig : Rig
        The cameras written to ``calibration.toml``.
    n_frames : int
        Frames of every video (and the keypoint frames kept: numbers below it).
    shifts : dict of str to int
        Per camera, frames dropped at its start to line the cameras up (0 without offsets).
    report : dict
        The content of ``import.json``.
    messages : list of str
        One line per mismatch found and what was done about it (also in ``report``).
    """

    out: Path
    rig: Rig
    n_frames: int
    report: dict
    messages: list[str]
    shifts: dict = field(default_factory=dict)


def fit_camera_to_video(cam: Camera, video_size: tuple[int, int], where: str) -> tuple[Camera, str | None]:
    """The camera ``cam`` for frames of ``video_size``, and what was changed (``None``: nothing).

    Parameters
    ----------
    cam : Camera
        As calibrated.
    video_size : tuple of int
        ``(width, height)`` of the video's frames, pixels.
    where : str
        The video, for messages.

    Returns
    -------
    camera : Camera
        ``cam`` itself when the sizes agree; ``cam`` with ``size = video_size`` and K unchanged when
        the sizes differ by at most :data:`PAD_TOLERANCE_PX` per direction (padding or cropping at
        the right / bottom); ``cam.scaled(f)`` when the video is the calibrated image resized by f.
    message : str or None

    Raises
    ------
    InputError
        Any other size, or a principal point outside the video's frame.
    """
    (cw, ch), (vw, vh) = cam.size, tuple(int(v) for v in video_size)
    if (cw, ch) == (vw, vh):
        return cam, None
    if abs(cw - vw) <= PAD_TOLERANCE_PX and abs(ch - vh) <= PAD_TOLERANCE_PX:
        cx, cy = cam.K[0, 2], cam.K[1, 2]
        if not (0 <= cx < vw and 0 <= cy < vh):
            raise InputError(where, f"frames holding camera {cam.name!r}'s principal point ({cx:.1f}, {cy:.1f})",
                             f"{vw}x{vh}")
        return cam.replace(size=(vw, vh)), (
            f"{cam.name}: the calibration states {cw}x{ch}, the video {where} is {vw}x{vh}: read as the same "
            f"image padded or cropped at the right/bottom (at most {PAD_TOLERANCE_PX} px); kept K (principal "
            f"point {cx:.2f}, {cy:.2f} px) and set the size to {vw}x{vh}")
    f = vw / cw
    if abs(vh / ch - f) <= ASPECT_TOLERANCE * f:
        scaled = cam.scaled(f)
        if scaled.size == (vw, vh):
            return scaled, (f"{cam.name}: the calibration states {cw}x{ch}, the video {where} is {vw}x{vh}: "
                            f"read as the image resized by {f:.6g}; scaled K by it")
    raise InputError(where, f"frames of {cw}x{ch} (camera {cam.name!r} of the calibration), the same padded or "
                            f"cropped by at most {PAD_TOLERANCE_PX} px, or resized", f"{vw}x{vh}")


def _videos(trial: Path) -> list[Path]:
    folder = trial / "videos"
    if not folder.is_dir():
        raise InputError(str(folder), "the trial's videos, one per camera", "no such folder")
    vids = sorted((p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".")
                   and p.suffix.lower() in VIDEO_SUFFIXES), key=lambda p: p.name)
    if not vids:
        raise InputError(str(folder), f"one video per camera ({', '.join(VIDEO_SUFFIXES)})", "no video")
    return vids


def _stem(p: Path) -> str:
    name = p.stem if p.is_file() else p.name
    for tail in ("_json", "-json", ".json"):
        if name.lower().endswith(tail):
            return name[: -len(tail)]
    return name


def _match(names: list[str], sources: list[Path], what: str, kind: str) -> tuple[list[Path], str]:
    if len(sources) != len(names):
        few = "fewer" if len(sources) < len(names) else "more"
        raise InputError(what, f"one {kind} per calibration camera {names} ({len(names)})",
                         f"{few} {kind}s: {len(sources)} ({[s.name for s in sources]})")
    order, how = match_cameras(names, sources, what)
    return [sources[i] for i in order], how


def _link_or_copy(src: Path, dst: Path, copy: bool, root: Path | None = None) -> None:
    """``dst`` becomes a copy of ``src`` or a symbolic link to it, atomically.

    The link is absolute, but relative when ``src`` lies inside ``root`` (the dataset folder: files
    made in it, such as detected keypoints, stay found when the folder is moved).
    """
    dst.parent.mkdir(parents=True, exist_ok=True)
    if copy:
        with atomic_path(dst) as tmp:
            shutil.copyfile(src, tmp)
        return
    target = src.resolve()
    if root is not None and root.resolve() in target.parents:
        target = Path(os.path.relpath(target, dst.parent.resolve()))
    tmp = temp_path(dst)
    tmp.unlink()
    try:
        os.symlink(target, tmp)
        os.replace(tmp, dst)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _trim_video(src: Path, dst: Path, start: int, n_frames: int, fps: float) -> None:
    """``dst``: frames ``start .. start + n_frames - 1`` of ``src``, re-encoded."""
    with VideoReader(src) as reader, VideoWriter(dst, fps) as writer:
        for t, rgb in enumerate(reader):
            if t >= start + n_frames:
                break
            if t >= start:
                writer.write(rgb)


def _offsets_per_camera(frame_offsets: dict | None, names: list[str], videos: list[Path],
                        folders: list[Path]) -> list[int]:
    """Per camera (calibration order) the frames it started late, from offsets keyed by camera, video or folder."""
    if not frame_offsets:
        return [0] * len(names)
    keys = [{n, v.stem, f.name if f.is_dir() else f.stem} for n, v, f in zip(names, videos, folders)]
    unknown = sorted(str(k) for k in frame_offsets if not any(k in ks for ks in keys))
    if unknown:
        raise InputError("frame_offsets", f"offsets of the cameras {names} (or of their videos "
                                          f"{[v.stem for v in videos]})", f"offsets for {unknown}")
    out = []
    for n, ks in zip(names, keys):
        found = [int(v) for k, v in frame_offsets.items() if k in ks]
        if len(set(found)) > 1:
            raise InputError("frame_offsets", f"one offset for camera {n}", f"{found}")
        out.append(found[0] if found else 0)
    return out


def _trial_sources(trial: Path, calibration: str | os.PathLike | None, pose: str | None,
                   keypoints: str | os.PathLike | None):
    """Find a trial's Pose2Sim settings, keypoints folder and calibration file.

    Parameters
    ----------
    trial : Path
        The trial folder.
    calibration : path-like or None
        A calibration file given instead of the session's ``Calib*.toml``.
    pose : str or None
        The trial's keypoint folder asked for (one of :data:`POSE_FOLDERS`).
    keypoints : path-like or None
        A keypoints folder given instead of the trial's.

    Returns
    -------
    info : Pose2SimTrial
        What :func:`read_pose2sim_trial` found in the trial (or its ``pose`` folder).
    kp_root : Path
        The keypoints folder to import.
    calib_path : Path
        The calibration file to read.

    Raises
    ------
    InputError
        No trial folder, ``pose`` and ``keypoints`` both given, an unknown or missing ``pose``, no
        keypoints, no calibration.
    """
    if not trial.is_dir():
        raise InputError(str(trial), "a Pose2Sim trial folder", "no such folder")
    if pose is not None:
        if keypoints is not None:
            raise InputError("pose, keypoints", "the trial's keypoint folder (pose) or a folder given (keypoints)",
                             "both")
        if pose not in POSE_FOLDERS:
            raise InputError("pose", f"one of {list(POSE_FOLDERS)}", repr(pose))
        if not (trial / pose).is_dir():
            raise InputError(str(trial / pose), "the trial's keypoint folder asked for", "no such folder")
        info = read_pose2sim_trial(trial / pose)
    else:
        info = read_pose2sim_trial(trial)
    kp_root = Path(keypoints) if keypoints is not None else info.keypoints
    if kp_root is None:
        raise InputError(str(trial), f"keypoints: one of {list(POSE_FOLDERS)} in the trial, or a keypoints folder "
                                     "given (recipes/import_pose2sim.py detects them)",
                         f"videos only ({info.videos})")
    calib_path = Path(calibration) if calibration is not None else info.calibration
    if calib_path is None:
        raise InputError(str(trial), "a calibration: S00_Calibration/Calib*.toml in the session above the trial, "
                                     "or one given (--calibration)", "none found")
    return info, kp_root, calib_path


def _match_videos_and_keypoints(names: list[str], trial: Path, kp_root: Path):
    """Match the trial's videos and the keypoint folders to the calibrated cameras.

    Parameters
    ----------
    names : list of str
        The calibrated cameras' names, in rig order.
    trial : Path
        The trial folder (its ``videos/``).
    kp_root : Path
        The keypoints folder (one sub-folder per camera).

    Returns
    -------
    videos : list of Path
        One video per camera, in rig order.
    folders : list of Path
        One keypoint folder per camera, in rig order.
    how_v, how_k : str
        How the videos and the keypoint folders were matched (by name, by order, ...).
    messages : list of str
        What the user should know (matches made by sorted order).

    Raises
    ------
    InputError
        Files instead of keypoint folders, counts that are not the cameras', keypoint folders that
        name neither a camera nor a video.
    """
    messages = []
    videos, how_v = _match(names, _videos(trial), str(trial / "videos"), "video")
    folders = camera_sources(kp_root)
    if any(not f.is_dir() for f in folders):
        raise InputError(str(kp_root), "one folder of per-frame JSON files per camera",
                         f"{[f.name for f in folders]}")
    folders, how_k = _match(names, folders, str(kp_root), "keypoint folder")
    if how_k == "by order":
        # folder names that mention no camera: they may name the videos instead (front_json, front.mp4)
        order, how_kv = match_cameras([v.stem for v in videos], folders, str(kp_root))
        if how_kv == "by order" and how_v != "by order":
            raise InputError(str(kp_root), f"keypoint folders named after the cameras {names} or their "
                                           f"videos {[v.name for v in videos]}",
                             f"folders that match none: {[f.name for f in folders]}")
        folders, how_k = [folders[i] for i in order], f"{how_kv}, through the videos' names"
    for how, what in ((how_v, "videos"), (how_k, "keypoint folders")):
        if how.startswith("by order"):
            messages.append(f"{what} matched to the cameras by sorted order (their names name no camera)")
    return videos, folders, how_v, how_k, messages


def _fit_rig_to_videos(rig_in: Rig, videos: list[Path], trial: Path, settings_frame_rate: float | None):
    """Probe the videos, check they share one frame rate and fit each camera to its video's size.

    Parameters
    ----------
    rig_in : Rig
        The calibrated cameras, in the order of ``videos``.
    videos : list of Path
        One video per camera.
    trial : Path
        The trial folder, named in errors.
    settings_frame_rate : float or None
        The Pose2Sim settings' ``frame_rate`` (frames per second), if any.

    Returns
    -------
    probes : list of VideoInfo
        What :func:`probe_video` found in each video.
    fps : float
        The videos' frame rate (frames per second), the first video's.
    rig : Rig
        The cameras fitted to their videos' sizes (:func:`fit_camera_to_video`).
    messages : list of str
        What the user should know (a settings frame rate that is not the videos', fitted cameras).

    Raises
    ------
    InputError
        Videos of different frame rates, video sizes that are not the calibrated ones.
    """
    messages = []
    probes = [probe_video(v) for v in videos]
    fps = probes[0].fps
    for v, p in zip(videos, probes):
        if abs(p.fps - fps) > FPS_RELATIVE_TOLERANCE * fps:
            raise InputError(str(trial / "videos"), "videos of one frame rate",
                             f"{videos[0].name} at {fps:g} fps, {v.name} at {p.fps:g} fps")
    if settings_frame_rate is not None and abs(settings_frame_rate - fps) > FPS_RELATIVE_TOLERANCE * fps:
        messages.append(f"the Pose2Sim settings say frame_rate = {settings_frame_rate:g}, the videos run at {fps:g} "
                        f"fps: kept the videos'")
    cams = []
    for cam, v, p in zip(rig_in, videos, probes):
        fitted, msg = fit_camera_to_video(cam, p.size, str(v))
        cams.append(fitted)
        if msg:
            messages.append(msg)
    return probes, fps, Rig(tuple(cams)), messages


def _line_up_frames(names: list[str], late: list[int], videos: list[Path], probes: list, folders: list[Path]):
    """Drop each camera's frames before the latest start and find the frames all cameras share.

    Parameters
    ----------
    names : list of str
        The cameras' names, in rig order.
    late : list of int
        Per camera, the frames it started late.
    videos, folders : list of Path
        Per camera, its video and its keypoint folder.
    probes : list of VideoInfo
        Per camera, its video's probe (``n_frames``).

    Returns
    -------
    shifts : list of int
        Per camera, the frames dropped at its start.
    kp_files : list of (list of Path, ndarray of int)
        Per camera, its keypoint files and their frame numbers (:func:`frame_files`).
    kp_lengths : list of int
        Per camera, its keypoint frames after the shift.
    n_frames : int
        The frames all cameras share after the shift.
    messages : list of str
        What the user should know (cameras lined up, frame counts trimmed).

    Raises
    ------
    InputError
        Offsets that leave no common frame.
    """
    messages = []
    shifts = [max(late) - k for k in late]     # frames dropped at each camera's start
    kp_files = [frame_files(f, "per-frame OpenPose JSON files") for f in folders]
    kp_lengths = [int(nums.max()) + 1 - s for (_, nums), s in zip(kp_files, shifts)]
    n_frames = min([p.n_frames - s for p, s in zip(probes, shifts)] + kp_lengths)
    if any(shifts):
        messages.append("cameras lined up by their late starts (frame offsets): " + ", ".join(
            f"{n} started {k} frames late, its first {s} frames dropped" for n, k, s in zip(names, late, shifts)))
    if n_frames < 1:
        raise InputError("frame_offsets", "offsets that leave the cameras frames in common",
                         f"{dict(zip(names, late))}: no common frame")
    lengths = {f"video {v.name}": p.n_frames - s for v, p, s in zip(videos, probes, shifts)}
    lengths.update({f"keypoints {f.name}": n for f, n in zip(folders, kp_lengths)})
    if len(set(lengths.values())) > 1:
        after = " after the shift" if any(shifts) else ""
        messages.append(f"frame counts differ{after} ({', '.join(f'{k}: {n}' for k, n in lengths.items())}): "
                        f"trimmed to the common length {n_frames}")
    return shifts, kp_files, kp_lengths, n_frames, messages


def _dataset_layout(out: Path, overwrite: bool, kp_root: Path) -> DatasetLayout:
    """Check the dataset folder to write and lay it out.

    Parameters
    ----------
    out : Path
        The dataset folder to write.
    overwrite : bool
        Whether a non-empty ``out`` may be written into.
    kp_root : Path
        The keypoints folder imported, which must lie outside the dataset's own.

    Returns
    -------
    DatasetLayout

    Raises
    ------
    InputError
        ``out`` a file, or not empty without ``overwrite``; ``kp_root`` inside the dataset's keypoints.
    """
    if out.exists() and not out.is_dir():
        raise InputError(str(out), "a dataset folder to write", "a file")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise InputError(str(out), "a new or empty folder (else overwrite)", "a folder with files")
    layout = DatasetLayout(out)
    if layout.keypoints_dir.resolve() in (kp_root.resolve(), *kp_root.resolve().parents):
        raise InputError(str(kp_root), f"a keypoints folder outside the dataset's {layout.keypoints_dir}",
                         "the dataset's own keypoints (the import would replace its sources)")
    return layout


def _write_camera(layout: DatasetLayout, cam: Camera, src: Camera, video: Path, probe, folder: Path,
                  kp_files: tuple, late: int, shift: int, n_frames: int, fps: float, copy: bool) -> dict:
    """Write one camera's video and keypoint files into the dataset, lined up and trimmed.

    Parameters
    ----------
    layout : DatasetLayout
        The dataset written.
    cam : Camera
        The camera fitted to its video.
    src : Camera
        The camera as calibrated.
    video : Path
        Its video.
    probe : VideoInfo
        Its video's probe (``size``, ``n_frames``).
    folder : Path
        Its keypoint folder.
    kp_files : (list of Path, ndarray of int)
        Its keypoint files and their frame numbers.
    late : int
        The frames it started late.
    shift : int
        The frames dropped at its start.
    n_frames : int
        The frames kept.
    fps : float
        The videos' frame rate (frames per second).
    copy : bool
        Copy the files instead of linking to them.

    Returns
    -------
    dict
        The camera's entry in ``import.json``.
    """
    files, nums = kp_files
    dst = layout.video(cam.name)
    if shift or probe.n_frames > n_frames:
        _trim_video(video, dst, shift, n_frames, fps)
        video_action = (f"re-encoded (mp4v) to its frames {shift}..{shift + n_frames - 1}" if shift
                        else f"re-encoded (mp4v) to its first {n_frames} frames")
    else:
        _link_or_copy(video, dst, copy, layout.root)
        video_action = "copied" if copy else "linked"
    kept = [(f, int(n) - shift) for f, n in zip(files, nums) if 0 <= n - shift < n_frames]
    kdir = layout.keypoint_dir(cam.name)
    if kdir.is_dir():   # overwriting: no file of an earlier import stays among these
        for old in kdir.glob("*.json"):
            old.unlink()
    for f, t in kept:
        name = f.name if not shift else f"{cam.name}_{t:012d}_keypoints.json"
        _link_or_copy(f, kdir / name, copy, layout.root)
    return {
        "name": cam.name, "video": str(video.resolve()), "video_action": video_action,
        "keypoints": str(folder.resolve()), "keypoint_files": len(kept),
        "keypoint_files_left_out": len(files) - len(kept),
        "calibrated_size": list(src.size), "video_size": list(probe.size), "size": list(cam.size),
        "video_frames": probe.n_frames, "keypoint_frames": int(nums.max()) + 1,
        "started_late": late, "frames_dropped_at_start": shift,
    }


def import_pose2sim_trial(trial: str | os.PathLike, out: str | os.PathLike, *,
                          calibration: str | os.PathLike | None = None, pose: str | None = None,
                          keypoints: str | os.PathLike | None = None, keypoint_format: str | None = None,
                          frame_offsets: dict[str, int] | None = None, detection: dict | None = None,
                          copy: bool = False, overwrite: bool = False) -> ImportResult:
    """Write a Pose2Sim trial as a dataset folder (module docstring).

    Parameters
    ----------
    trial : path-like
        The trial folder (``videos/``, ``pose/`` and/or ``pose-associated/``, or ``videos/`` and a
        calibration folder with ``keypoints`` given).
    out : path-like
        The dataset folder to write; it must not exist or be empty unless ``overwrite``.
    calibration : path-like, optional
        A calibration file (TOML, OpenCV YAML or ``.qca.txt``) instead of the session's ``Calib*.toml``.
    pose : {"pose", "pose-associated"}, optional
        The keypoint folder to import; by default ``pose-associated`` when there, else ``pose``.
    keypoints : path-like, optional
        A keypoints folder to import instead of the trial's (one sub-folder of per-frame OpenPose JSON
        files per camera, named after the camera or its video; other files in it are ignored).
    keypoint_format : str, optional
        The keypoints' format, recorded as ``pose_model`` (default: the Pose2Sim settings').
    frame_offsets : dict of str to int, optional
        Per camera (its calibration name, its video's stem or its keypoint folder's name), the frames
        it started late (``sync.json``'s ``offsets``); the cameras are lined up (module docstring).
        Cameras not named have offset 0.
    detection : dict, optional
        How ``keypoints`` were made, recorded as ``detection`` in ``import.json``.
    copy : bool
        Copy the videos and keypoint files instead of linking to them.
    overwrite : bool
        Write into a non-empty ``out`` (files of the import are replaced, and the JSON files of its
        ``keypoints/<camera>/`` folders removed first).

    Returns
    -------
    ImportResult

    Raises
    ------
    InputError
        Naming the file or folder at fault: no trial, no calibration (neither found nor given), no
        videos, no keypoints (a trial of videos only, none given), fewer (or more) videos or keypoint
        folders than cameras, keypoint folders that name no camera, video sizes that are not the
        calibrated ones (padded, cropped or resized), videos of different frame rates, offsets that
        name no camera or leave no common frame, an ``out`` that is not empty, an unknown ``pose``,
        ``pose`` and ``keypoints`` both given.
    """
    trial = Path(trial)
    info, kp_root, calib_path = _trial_sources(trial, calibration, pose, keypoints)
    rig_in = read_calibration(calib_path)
    names = rig_in.names
    videos, folders, how_v, how_k, messages = _match_videos_and_keypoints(names, trial, kp_root)
    probes, fps, rig, fit_messages = _fit_rig_to_videos(rig_in, videos, trial, info.frame_rate)
    messages += fit_messages

    late = _offsets_per_camera(frame_offsets, list(names), videos, folders)
    shifts, kp_files, kp_lengths, n_frames, line_up_messages = _line_up_frames(list(names), late, videos, probes,
                                                                               folders)
    messages += line_up_messages

    layout = _dataset_layout(Path(out), overwrite, kp_root)
    layout.root.mkdir(parents=True, exist_ok=True)
    (layout.root / IMPORT_JSON).unlink(missing_ok=True)  # a dataset without import.json is unfinished
    write_calibration_toml(layout.calibration, rig, metadata={"source": str(calib_path.resolve())})
    cameras = [_write_camera(layout, cam, rig_in[cam.name], v, p, folder, kp, k, shift, n_frames, fps, copy)
               for cam, v, p, folder, kp, k, shift in zip(rig, videos, probes, folders, kp_files, late, shifts)]
    report = {
        "trial": str(trial.resolve()), "calibration": str(calib_path.resolve()),
        "keypoints": str(kp_root.resolve()),
        "pose_model": keypoint_format if keypoint_format is not None else info.pose_model,
        "settings_frame_rate": info.frame_rate, "fps": fps, "n_frames": n_frames,
        "files": "copied" if copy else "linked", "videos_matched": how_v, "keypoints_matched": how_k,
        "frame_offsets": dict(zip(names, late)) if frame_offsets else None,
        "detection": detection, "cameras": cameras, "messages": messages,
    }
    atomic_write_text(layout.root / IMPORT_JSON, json.dumps(report, indent=2) + "\n")
    return ImportResult(out=layout.root, rig=rig, n_frames=n_frames, report=report, messages=messages,
                        shifts=dict(zip(names, shifts)))
