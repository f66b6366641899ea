"""Triangulating a detector's 2D keypoints as a run: one person, or every person found.

:func:`run` is what ``recipes/pose_from_keypoints.py`` calls (its docstring
lists the outputs).  The keypoints and calibration are read by
:func:`~toolkit.pipeline.keypoint_session.open_keypoint_session` (a keypoints
folder or a Pose2Sim trial is the run's ``dataset``), mapped to the 14-joint
skeleton and triangulated as one sequence by
:func:`~toolkit.multiview.keypoint_sequence.triangulate_keypoint_sequence`
(flips, sequence offsets, anthropometric checks).  With
``multi_person`` every person tracked across the views gets a run of its own
in ``OUT/person_<k>/``.

The sequence offsets tie every frame to the others, so the run is not resumed
frame by frame: it always triangulates the whole sequence, and writes its
results at the end, also after an error or Ctrl-C (frames not processed are
NaN), but never over the results of a complete run.  Its identity (derived
from the config, :func:`~toolkit.pipeline.run.config_identity`) is recorded
in ``poses3d.json`` under ``run``, and with a fingerprint of every input file
in ``OUT/run.json``: a folder of another run is refused (or moved aside with
``replace_stale``).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from toolkit.cameras.validate import cameras_behind
from toolkit.errors import InputError
from toolkit.io.video import VIDEO_SUFFIXES
from toolkit.multiview import FLIP_MODES, MAX_OFFSET_PX, MIN_JOINT_CONFIDENCE, MIN_VIEW_CONFIDENCE
from toolkit.multiview.keypoint_sequence import OFFSET_MODES
from toolkit.pipeline.detect_keypoints import DetectConfig
from toolkit.pipeline.run import (STOPPED_INTERRUPTED, RunResult, close_run_recording, config_identity,
                                  merge_killed_parts, terminate_as_interrupt)

#: ``format`` names accepted, mapped to the names of toolkit.skeleton.mappings ("auto": found from the files).
FORMATS = {"auto": None, "body_25b": "body_25b", "body_25": "body_25", "coco17": "coco_17", "coco_17": "coco_17",
           "coco_18": "coco_18", "coco": "coco_18", "halpe_26": "halpe_26", "coco_133": "coco_133",
           "blazepose_33": "blazepose_33"}
#: Median ray distance (metres) above which a run warns that cameras may be paired with the wrong keypoints or
#: the calibration is off: the Pose2Sim demo's is 7.5-9.9 mm, two swapped keypoint folders of the synthetic
#: test scene give 60 mm.
RAY_DISTANCE_WARNING_M = 0.04
#: Share of the triangulated frames with joints behind a camera that sees them above which the calibration is
#: refused (a correct one has none: a camera sees nothing behind it).
MAX_SHARE_BEHIND = 0.5
#: Frame rate assumed when neither ``fps``, a Pose2Sim Config.toml nor the videos give one (said so in the outputs).
ASSUMED_FPS = 30.0
#: Trajectory files that may be written besides ``poses3d.npz``.
EXPORTS = ("trc", "c3d", "csv")
#: What ``poses3d.json`` says about the axes of each trajectory file.
TRAJECTORY_AXES = {"npz, csv": "world frame of the calibration (z up), metres",
                   "trc": "Y up: (X, Y, Z) = world (y, z, x), metres", "c3d": "the TRC's axes, millimetres"}
#: A person followed in fewer than this share of the frames is reported as transient, apart from the
#: participants (a bystander crossing the volume, someone entering or leaving, or a short-lived association).
PARTICIPANT_MIN_SHARE = 0.25
#: How ``people.json`` says people were found.
PEOPLE_RULE = ("detections grouped across views by ray distance (toolkit.multiview.association), tracked over "
               "time (toolkit.multiview.tracking); seen by two cameras or more, in the capture volume")


@dataclass(frozen=True)
class PoseFromKeypointsConfig:
    """Options of a keypoint triangulation run (the recipe's flags; a TOML file holds the same keys).

    Parameters
    ----------
    calibration : Path, optional
        Calibration file (``.toml`` or ``.yaml``); default: a Pose2Sim session's ``Calib*.toml``.
    format : str
        A key of :data:`FORMATS` (``"auto"``: from the files, or a Pose2Sim ``pose_model``).
    fps : float, optional
        Frame rate of the keypoints, Hz (default: Pose2Sim Config.toml, else the videos, else
        :data:`ASSUMED_FPS`).
    export : tuple of str
        Trajectory files besides ``poses3d.npz``, among :data:`EXPORTS`.
    filter_cutoff : float, optional
        Also write low-pass filtered trajectories (zero-phase Butterworth) with this cut-off, Hz.
    filter_order : int
        Order of that filter, even and >= 2.
    max_frames : int, optional
        Only the first N frames.
    videos : Path, optional
        Folder of one video per camera: frames go into the recording.
    min_confidence, min_view_confidence : float
        Joints, and views whose mean confidence, below these are dropped.
    flips : tuple of str
        Left/right flips tested per view and frame (subset of ``FLIP_MODES``).
    offsets : str
        Per-camera 2D offsets, one of ``OFFSET_MODES``.
    max_offset_px : float
        Bound on each offset component, pixels.
    robust : bool
        Drop views and rays whose rays disagree.
    check_ground : bool
        Apply the ground rule of the anthropometric check (world frame z-up at ground 0).
    multi_person : bool
        Every person found, each in ``OUT/person_<k>/`` (default: the person most cameras agree on).
    recording : bool
        Write ``recording.rrd``.
    replace_stale : bool
        Move an output folder of another run (other keypoints, calibration or options) aside
        instead of refusing it.
    progress : bool
        Show a progress bar (reading the videos).
    detection : DetectConfig
        The 2D detector's options, used when the input is a trial with videos and no keypoints
        (detected into ``OUT/keypoints/``; a TOML file sets them in a ``[detection]`` table).
    """

    calibration: Path | None = None
    format: str = "auto"
    fps: float | None = None
    export: tuple[str, ...] = EXPORTS
    filter_cutoff: float | None = None
    filter_order: int = 4
    max_frames: int | None = None
    videos: Path | None = None
    min_confidence: float = MIN_JOINT_CONFIDENCE
    min_view_confidence: float = MIN_VIEW_CONFIDENCE
    flips: tuple[str, ...] = FLIP_MODES
    offsets: str = "sequence"
    max_offset_px: float = MAX_OFFSET_PX
    robust: bool = True
    check_ground: bool = True
    multi_person: bool = False
    recording: bool = True
    replace_stale: bool = False
    progress: bool = True
    detection: DetectConfig = DetectConfig()

    #: Fields that do not change the results (left out of the run identity).
    RUNTIME = ("videos", "recording", "replace_stale", "progress")

    def __post_init__(self):
        checks = (("format", self.format in FORMATS, f"one of {sorted(FORMATS)}"),
                  ("fps", self.fps is None or self.fps > 0, "a frame rate > 0"),
                  ("export", all(e in EXPORTS for e in self.export), f"names among {EXPORTS} (or none)"),
                  ("filter_order", self.filter_order >= 2 and self.filter_order % 2 == 0, "an even order >= 2"),
                  ("max_frames", self.max_frames is None or self.max_frames >= 1, "a number of frames >= 1"),
                  ("flips", all(f in FLIP_MODES for f in self.flips), f"names among {FLIP_MODES} (or none)"),
                  ("offsets", self.offsets in OFFSET_MODES, f"one of {OFFSET_MODES}"),
                  ("filter_cutoff", self.filter_cutoff is None or self.filter_cutoff > 0, "a cut-off > 0 Hz"))
        for name, ok, expected in checks:
            if not ok:
                raise InputError(f"PoseFromKeypointsConfig.{name} (--{name.replace('_', '-')})", expected,
                                 repr(getattr(self, name)))


def keypoint_config(config: PoseFromKeypointsConfig):
    """The triangulation's options (:class:`~toolkit.multiview.keypoint_sequence.KeypointConfig`) of a run."""
    from toolkit.anthropometry import AnthropometricConstraints
    from toolkit.multiview import MultiViewConfig
    from toolkit.multiview.keypoint_sequence import KeypointConfig

    constraints = AnthropometricConstraints(check_ground=config.check_ground)
    return KeypointConfig(flips=config.flips, offsets=config.offsets,
                          multiview=MultiViewConfig(flips=(), robust=config.robust,
                                                    max_offset_px=config.max_offset_px, constraints=constraints))


def _videos(folder: Path | None, rig) -> list:
    """Open the videos of ``folder`` in the order of the rig's cameras (by name, number or order)."""
    from toolkit.io import VideoReader
    from toolkit.io.keypoint_files import match_cameras

    if folder is None:
        return []
    if not Path(folder).is_dir():
        raise InputError(str(folder), "a folder of videos", "no such folder")
    files = sorted(p for p in Path(folder).iterdir() if p.suffix.lower() in VIDEO_SUFFIXES)
    order, _ = match_cameras(rig.names, files, f"{folder}: video files")
    return [VideoReader(files[i]) for i in order]


def _frame_rate(session, videos: list) -> tuple[float, str]:
    """The frame rate and where it comes from: given or Pose2Sim, else the videos, else assumed."""
    if session.fps is not None:
        return session.fps, session.fps_from
    if videos:
        return float(videos[0].fps), f"video {videos[0].path.name}"
    return ASSUMED_FPS, "assumed (give --fps)"


def _lowpass(config: PoseFromKeypointsConfig, fps: float, fps_from: str):
    """The Butterworth filter of the run (None without a cut-off), checked against the frame rate."""
    from toolkit.filtering import ButterworthFilter

    if config.filter_cutoff is None:
        return None
    lowpass = ButterworthFilter(config.filter_cutoff, config.filter_order)
    if not config.filter_cutoff < fps / 2:
        raise InputError("filter_cutoff (--filter-cutoff)",
                         f"a cut-off below half the frame rate ({fps / 2:g} Hz, {fps_from})", f"{config.filter_cutoff:g}")
    return lowpass


def _recording(path: Path, rig):
    """A rerun observer writing ``path``, with the rig and the skeleton."""
    from toolkit.skeleton import SKELETON_14
    from toolkit.viz import RerunObserver

    merge_killed_parts(path.parent)
    # in parts: a run killed outright leaves its finished parts complete; a dropped one leaves the file as it was
    observer = RerunObserver(application_id="pose_from_keypoints", path=path, camera_names=rig.names, parts=True)
    observer.report("rig", rig=rig, static=True)
    observer.report("skeleton", skeleton=SKELETON_14)
    return observer


def _describe_inputs(session, fps: float, fps_from: str) -> list:
    """What was read: cameras matched, frames, frame rate, format, frames missing."""
    rig, kin = session.rig, session.keypoints
    n_cams, n_frames = kin.keypoints.shape[:2]
    lines = [f"{n_cams} cameras matched {session.matching} ("
             + ", ".join(f"{c.name} <- {f.name}" for c, f in zip(rig, session.sources))
             + f"), {n_frames} frames at {fps:g} fps ({fps_from}), format {kin.format.fmt} ({kin.format.reason})"]
    if session.matching == "by order":
        lines.append("  warning: no keypoint folder names a calibration camera, so they were paired in sorted order; "
                     "name the folders after the cameras if that order is not the calibration's")
    firsts = [(cam.name, int(np.min(cd.frames))) for cam, cd in zip(rig, kin.cameras) if np.size(cd.frames)]
    if len({f for _, f in firsts}) > 1:
        lines.append("  warning: the cameras' frame numbers start at different values ("
                     + ", ".join(f"{name} {f}" for name, f in firsts)
                     + "): frames are matched by number, so a frame is seen only by the cameras whose files share "
                     "its number; if the cameras started together, renumber the files (or give sync.json)")
    for c, cam in enumerate(rig):
        if kin.missing[c].any() or kin.empty[c].any():
            lines.append(f"  {cam.name}: {int(kin.missing[c].sum())} frames without a file, "
                         f"{int(kin.empty[c].sum())} with nobody (marked missing)")
    return lines


def _triangulate(config: PoseFromKeypointsConfig, session, observer):
    """The sequence's triangulation (:class:`~toolkit.multiview.keypoint_sequence.KeypointSequence`)."""
    from toolkit.multiview import keypoints_to_candidates
    from toolkit.multiview.keypoint_sequence import triangulate_keypoint_sequence
    from toolkit.skeleton.mappings import to_skeleton14

    kin = session.keypoints
    # keypoints below the threshold are missing, so the mapping falls back to the next alternative
    kp14 = to_skeleton14(kin.keypoints, kin.format.fmt, confidence=True,
                         min_confidence=config.min_confidence)  # (n_cams, T, 14, 3)
    cand = [keypoints_to_candidates(kp14[:, t], config.min_confidence, config.min_view_confidence)
            for t in range(kp14.shape[1])]
    pts = np.stack([c[0][:, 0] for c in cand], axis=1)  # (n_cams, T, 14, 2)
    wts = np.stack([c[1][:, 0] for c in cand], axis=1)
    seq = triangulate_keypoint_sequence(pts, session.rig, keypoint_config(config), weights=wts, observer=observer)
    _check_in_front(seq, session)
    if observer is not None:
        for t, v in enumerate(seq.violations):
            observer.report("scalar", name="anthropometry/violations", value=len(v), frame=t)
    return seq


def _check_in_front(seq, session) -> None:
    """Refuse a triangulation whose joints lie behind the cameras that see them (a pose in the wrong convention).

    A calibration written as ``world_from_cam`` where ``cam_from_world`` is meant can pass every check of
    the calibration alone (:mod:`toolkit.cameras.validate`) and still give rays that meet, metres away,
    behind the cameras; no camera sees a point behind it, so most frames so placed mean a wrong calibration.
    """
    ok = np.asarray(seq.success, bool)
    if not ok.any():
        return
    joints = np.asarray(seq.joints3d)[ok]                              # (n_ok, 14, 3)
    seen = np.isfinite(np.asarray(seq.poses2d)[:, ok]).all(axis=-1)    # (n_cams, n_ok, 14)
    per_frame = [cameras_behind(session.rig, joints[i], seen[:, i]) for i in range(joints.shape[0])]
    behind = np.array([bool(c) for c in per_frame])
    cams_behind = {name for c in per_frame for name in c}
    if behind.mean() > MAX_SHARE_BEHIND:
        raise InputError(f"{session.calibration}: rotation/translation",
                         "camera poses (cam_from_world, world to camera) that put the joints each camera sees in "
                         "front of it", f"the joints behind {sorted(cams_behind)} in {int(behind.sum())} of "
                         f"{behind.size} frames (a world_from_cam pose, or a translation of the other sign?)")


def _log_videos(videos: list, session, observer, progress: bool) -> None:
    """The video frames of the keypoints' frames into the recording."""
    from tqdm import tqdm

    frames = session.keypoints.frames
    for t in tqdm(range(len(frames)), desc="video frames", unit="frame", disable=not progress):
        for cam, vid in zip(session.rig, videos):
            if int(frames[t]) < len(vid):
                observer.report("image", camera=cam.name, image=vid.read(int(frames[t])), frame=t)


@dataclass(frozen=True)
class _Written:
    """What :func:`_write_outputs` needs besides the sequence."""

    out: Path
    config: PoseFromKeypointsConfig
    session: object
    fps: float
    fps_from: str
    lowpass: object
    identity: dict


def _arrays(seq, n_cams: int, n_frames: int) -> dict:
    """The sequence's arrays; without a sequence (stopped or failed before it), NaN / empty ones."""
    if seq is not None:
        return {"joints": seq.joints3d, "success": seq.success, "cost": seq.cost, "offsets": seq.offsets,
                "poses2d": seq.poses2d, "poses2d_raw": seq.poses2d_raw, "flips": seq.flips}
    nan = np.full((n_cams, n_frames, 14, 2), np.nan)
    return {"joints": np.full((n_frames, 14, 3), np.nan), "success": np.zeros(n_frames, bool),
            "cost": np.full(n_frames, np.nan), "offsets": np.zeros((n_frames, n_cams, 2)), "poses2d": nan,
            "poses2d_raw": nan, "flips": np.full((n_frames, n_cams), "", dtype=object)}


def _write_trajectories(w: _Written, arrays: dict, meta: dict) -> tuple[dict, list]:
    """``poses3d.npz`` and the trajectory files (filtered ones too); returns the filtered arrays and the files."""
    from toolkit.io import atomic_save_npz
    from toolkit.io.trajectories import skeleton14_trajectories, write_trajectories
    from toolkit.skeleton import SKELETON_14

    names, frames = np.array(SKELETON_14.joint_names), w.session.keypoints.frames
    extra = {}
    if w.lowpass is not None:
        extra = {"joints_filtered": w.lowpass.apply(arrays["joints"], w.fps), "filter": np.array(w.lowpass.describe())}
    atomic_save_npz(w.out / "poses3d.npz", joints=arrays["joints"], names=names, frames=frames,
                    success=arrays["success"], cost=arrays["cost"], violations=arrays["violations"],
                    frame_rate=np.array(w.fps), **extra)
    exported = write_trajectories(w.out / "poses3d", skeleton14_trajectories(
        arrays["joints"], names, frames, w.fps, {**meta, "filter": "none"}), w.config.export)
    if w.lowpass is not None:
        exported += write_trajectories(w.out / "poses3d_filt_butterworth", skeleton14_trajectories(
            extra["joints_filtered"], names, frames, w.fps, {**meta, "filter": w.lowpass.describe()}),
            w.config.export)
    return extra, exported


def _write_outputs(w: _Written, seq, status: str) -> list:
    """Every output file of one person (also after an error or Ctrl-C); returns the trajectory files."""
    from toolkit.io import atomic_save_npz, atomic_write_text
    from toolkit.skeleton import SKELETON_14

    s, kin, rig = w.session, w.session.keypoints, w.session.rig
    n_cams, n_frames = kin.keypoints.shape[:2]
    arrays = _arrays(seq, n_cams, n_frames)
    viol = seq.violations if seq is not None else [()] * n_frames
    arrays["violations"] = np.array([len(v) if seq is not None else -1 for v in viol])
    meta = {"source": "pose_from_keypoints", "keypoint_format": f"{kin.format.fmt} ({kin.format.reason})",
            "frame_rate": f"{w.fps:g} Hz ({w.fps_from})", "status": status}
    _, exported = _write_trajectories(w, arrays, meta)
    lp = w.lowpass
    atomic_write_text(w.out / "poses3d.json", json.dumps({
        **meta, "frame_rate_hz": w.fps, "keypoints": str(s.keypoints_root), "calibration": str(s.calibration),
        "cameras": {c.name: str(f) for c, f in zip(rig, s.sources)}, "camera_matching": s.matching,
        "frames_without_file": {c.name: int(m) for c, m in zip(rig, kin.missing.sum(1))},
        "frames_with_nobody": {c.name: int(m) for c, m in zip(rig, kin.empty.sum(1))},
        "filter": lp.describe() if lp is not None else "none",
        "filter_cutoff_hz": lp.cutoff_hz if lp is not None else None,
        "filter_order": lp.order if lp is not None else None, "trajectory_axes": TRAJECTORY_AXES,
        "files": [p.name for p in exported], "run": w.identity}, indent=2) + "\n")
    decision = seq.offset_decision if seq is not None else None
    atomic_save_npz(w.out / "offsets.npz", offsets=arrays["offsets"], camera_names=np.array(rig.names),
                    mode=np.array(decision.mode if decision else "none"),
                    sequence_offsets=decision.offsets if decision else np.zeros((n_cams, 2)),
                    reason=np.array(decision.reason if decision else status))
    atomic_save_npz(w.out / "flips.npz", flips=arrays["flips"].astype(str), camera_names=np.array(rig.names),
                    frames=kin.frames)
    atomic_save_npz(w.out / "poses2d.npz", names=np.array(SKELETON_14.joint_names),
                    **{c: arrays["poses2d"][i] for i, c in enumerate(rig.names)},
                    **{f"{c}_raw": arrays["poses2d_raw"][i] for i, c in enumerate(rig.names)})
    lines = [f"frame {int(kin.frames[t])}: " + ("; ".join(v) if v else "ok") for t, v in enumerate(viol)
             if seq is not None]
    atomic_write_text(w.out / "anthropometry.txt", "\n".join(lines) + "\n")
    return exported


def _worth_writing(out: Path, seq, status: str, log) -> bool:
    """Whether this run's outputs are at least as good as those ``out`` holds (never replace them by worse).

    A run that computed nothing (an error or Ctrl-C before the triangulation)
    writes NaN placeholders only where there is nothing yet; an interrupted
    or failed run never replaces the outputs of a complete one.
    """
    meta = out / "poses3d.json"
    if not (out / "poses3d.npz").is_file() or not meta.is_file():
        return True
    try:
        old = json.loads(meta.read_text(encoding="utf-8")).get("status")
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, AttributeError):
        old = None
    if seq is None or (old == "complete" and status != "complete"):
        log(f"{out}: the outputs of an earlier run ({old or 'status unknown'}) kept: this run is {status} "
            f"{'with nothing computed' if seq is None else 'before the end'}")
        return False
    return True


def _metrics(seq, status: str, rig, n_frames: int) -> dict:
    """The figures a person's summary shows (``RunResult.metrics``)."""
    arrays = _arrays(seq, len(rig), n_frames)
    ok = arrays["success"]
    done = int(np.sum(ok)) if seq is not None and seq.interrupted else (n_frames if seq is not None else 0)
    m = {"status": status, "processed": done, "with_estimate": int(ok.sum())}
    if seq is not None:
        d = seq.offset_decision
        m.update({"offsets": d.mode, "offsets_reason": d.reason,
                  "flips_per_camera": {c: int(n) for c, n in zip(rig.names, (arrays["flips"] != "").sum(axis=0))}})
    if ok.any():
        norms = np.linalg.norm(arrays["offsets"][ok], axis=-1)
        seen = np.isfinite(norms).any(axis=0)
        off = np.full(norms.shape[1], np.nan)
        off[seen] = np.nanmean(norms[:, seen], axis=0)   # a camera that never saw the person: NaN, no warning
        m.update({"mean_offset_px": {c: float(o) for c, o in zip(rig.names, off)},
                  "mean_ray_distance_m": float(np.nanmean(arrays["cost"][ok])),
                  "frames_breaking_constraints": int(sum(len(v) > 0 for v in seq.violations))})
        median = float(np.nanmedian(arrays["cost"][ok]))
        if median > RAY_DISTANCE_WARNING_M:
            m["warnings"] = [f"median ray distance {1000 * median:.0f} mm (over {1000 * RAY_DISTANCE_WARNING_M:.0f} "
                             "mm): the rays of the cameras barely meet; check that each keypoint folder is paired "
                             "with its camera and that the calibration is of this capture"]
    return m


def run_person(config: PoseFromKeypointsConfig, session, out, *, observer=None, log=print,
               identity: dict | None = None) -> RunResult:
    """Triangulate one person of an opened keypoint session into ``out``.

    Parameters
    ----------
    config : PoseFromKeypointsConfig
    session : KeypointSession
        From :func:`~toolkit.pipeline.keypoint_session.open_keypoint_session` (or one person's keypoints of it).
    out : path
    observer : Observer, optional
        A shared recording; default: ``out/recording.rrd`` (``config.recording``).
    log : callable or None
    identity : dict, optional
        The run identity written into ``poses3d.json`` (default: this config's).

    Returns
    -------
    RunResult
        ``extra`` holds ``files`` (name -> path of every output) and ``exported`` (the trajectory files).

    Raises
    ------
    InputError
        Bad videos folder, or a filter cut-off at or above half the frame rate.
    """
    log = log or (lambda *_: None)
    out = Path(out)
    videos = _videos(config.videos, session.rig)
    fps, fps_from = _frame_rate(session, videos)
    w = _Written(out, config, session, fps, fps_from, _lowpass(config, fps, fps_from),
                 identity if identity is not None else run_identity(config))
    out.mkdir(parents=True, exist_ok=True)
    own = observer is None and config.recording
    observer = _recording(out / "recording.rrd", session.rig) if own else observer
    for line in _describe_inputs(session, fps, fps_from):
        log(line)
    status, seq, t0 = "complete", None, time.perf_counter()
    try:
        with terminate_as_interrupt():
            if videos and observer is not None:
                _log_videos(videos, session, observer, config.progress)
            seq = _triangulate(config, session, observer)
        status = "interrupted" if seq.interrupted else status
    except KeyboardInterrupt:
        status = "interrupted"
    except BaseException:
        status = "failed"
        raise
    finally:
        exported, recording = [], None
        worth = _worth_writing(out, seq, status, log)
        if worth:
            exported = _write_outputs(w, seq, status)
        if own:  # the recording replaces the earlier one only together with the results it shows
            recording = close_run_recording(observer, out, keep=worth)
        for v in videos:
            v.close()
    n_frames = session.keypoints.keypoints.shape[1]
    metrics = _metrics(seq, status, session.rig, n_frames)
    files = {k: out / f for k, f in (("3D joints", "poses3d.npz"), ("offsets", "offsets.npz"),
                                     ("flips", "flips.npz"), ("2D joints", "poses2d.npz"),
                                     ("anthropometry", "anthropometry.txt"))}
    return RunResult(out, n_frames, metrics["processed"], metrics["processed"], 0,
                     STOPPED_INTERRUPTED if status == "interrupted" else "", time.perf_counter() - t0, metrics,
                     recording, {"files": files, "exported": list(exported)})


def run_identity(config: PoseFromKeypointsConfig) -> dict:
    """What the run's results depend on: the system and its config less :attr:`~PoseFromKeypointsConfig.RUNTIME`."""
    return {"recipe": "pose_from_keypoints", "config": config_identity(config, exclude=config.RUNTIME)}


def _start(config: PoseFromKeypointsConfig, dataset, out: Path, log) -> bool:
    """Record (or check) which inputs and options ``out`` belongs to (``OUT/run.json``).

    The identity holds the config and a fingerprint of every input file (the
    keypoints or the trial folder, and the calibration), so a folder of another
    run is refused, or moved aside with ``replace_stale``.  The same run again
    replaces the outputs (the triangulation is not resumed).  Returns whether
    the folder was new (or emptied by ``replace_stale``).
    """
    from toolkit.io.pose2sim import is_pose2sim_trial, read_pose2sim_trial
    from toolkit.io.runs import dataset_fingerprint, start_run

    inputs = {"keypoints": dataset_fingerprint(dataset, exclude=(out,)) if Path(dataset).exists() else str(dataset)}
    files = [config.calibration] if config.calibration is not None else []
    if is_pose2sim_trial(dataset):  # the session's calibration and Config.toml files, outside the trial folder
        trial = read_pose2sim_trial(dataset)
        if config.calibration is None and trial.calibration is not None:
            files.append(trial.calibration)
        files += list(trial.config_files)
    inputs["files"] = [dataset_fingerprint(f) for f in files if Path(f).is_file()]
    return not start_run(out, {**run_identity(config), "inputs": inputs}, replace_stale=config.replace_stale,
                         log=log)


def _undo_start(out: Path) -> None:
    """Remove the ``run.json`` :func:`_start` wrote into a new folder, and the folder if it is then empty."""
    from toolkit.io.runs import RUN_FILE

    (out / RUN_FILE).unlink(missing_ok=True)
    if out.is_dir() and not any(out.iterdir()):
        out.rmdir()


def _open(config: PoseFromKeypointsConfig, dataset, out: Path, log=None):
    from toolkit.pipeline.keypoint_session import open_keypoint_session

    return open_keypoint_session(dataset, config.calibration, FORMATS[config.format], config.fps,
                                 max_frames=config.max_frames, detect_into=Path(out) / "keypoints",
                                 detect_config=config.detection, log=log)


def run(config: PoseFromKeypointsConfig, *, dataset, out, observer=None, log=print) -> RunResult:
    """Triangulate the keypoints of ``dataset`` into ``out``: one person, or every person found.

    Parameters
    ----------
    config : PoseFromKeypointsConfig
    dataset : path
        A folder of per-camera keypoints, or a Pose2Sim trial (or its ``pose/`` folder).
    out : path
        Output folder (``recipes/pose_from_keypoints.py`` lists what it holds).
    observer : Observer, optional
        Receives every intermediate; default: ``out/recording.rrd`` (``config.recording``).
    log : callable or None
        Receives what was read (cameras matched, frame rate, format, people found).

    Returns
    -------
    RunResult
        One person: see :func:`run_person`.  ``multi_person``: ``extra["people"]`` lists
        ``(name, header, RunResult)`` per person, ``metrics["people"]`` what ``people.json`` holds.

    Raises
    ------
    InputError
        Bad keypoints, calibration, videos or options.
    """
    fresh = _start(config, dataset, Path(out), log)
    try:
        session = _open(config, dataset, out, log)
    except InputError:
        if fresh:  # nothing of this run is there: leave no run.json naming it
            _undo_start(Path(out))
        raise
    if not config.multi_person:
        return run_person(config, session, out, observer=observer, log=log)
    return _run_people(config, session, Path(out), observer, log)


def _run_people(config: PoseFromKeypointsConfig, session, out: Path, observer, log) -> RunResult:
    """Every person tracked across the views, each by :func:`run_person` on its own keypoints."""
    from toolkit.io import atomic_write_text
    from toolkit.multiview.tracking import DEFAULT_FPS, TrackingConfig, frame_detections, track_people
    from toolkit.observe import PrefixedObserver
    from toolkit.viz.style import SKELETON_COLORS

    log = log or (lambda *_: None)
    kin, rig, t0 = session.keypoints, session.rig, time.perf_counter()
    detections = frame_detections(kin.cameras, kin.frames, kin.keypoints.shape[2])
    people = track_people(detections, rig, TrackingConfig(fps=config.fps or session.fps or DEFAULT_FPS))
    out.mkdir(parents=True, exist_ok=True)
    own = observer is None and config.recording
    observer = _recording(out / "recording.rrd", rig) if own else observer
    n_part = sum((people.views[k] > 0).mean() >= PARTICIPANT_MIN_SHARE for k in range(people.n_people))
    log(f"{people.n_people} people found in {len(kin.frames)} frames (seen by two cameras or more, in the "
        f"capture volume, tracked over time): {n_part} participants, {people.n_people - n_part} transient "
        f"(followed in under {PARTICIPANT_MIN_SHARE:.0%} of the frames)")
    summary, results, finished, recording = [], [], False, None
    try:
        for k in range(people.n_people):
            name, seen = f"person_{k}", people.views[k] > 0
            share = float(seen.sum()) / max(len(kin.frames), 1)
            summary.append({"person": name, "frames": int(seen.sum()), "share": round(share, 3),
                            "role": "participant" if share >= PARTICIPANT_MIN_SHARE else "transient",
                            "first_frame": int(kin.frames[seen][0]),
                            "last_frame": int(kin.frames[seen][-1]),
                            "cameras_per_frame_median": float(np.median(people.views[k][seen]))})
            one = replace(session, keypoints=replace(kin, keypoints=people.keypoints(detections, k)))
            obs = None if observer is None else PrefixedObserver(observer, name, SKELETON_COLORS[k % len(SKELETON_COLORS)])
            sub = replace(config, multi_person=False, videos=config.videos if k == 0 else None)
            results.append((name, _person_header(summary[-1]), run_person(
                sub, one, out / name, observer=obs, log=log, identity=run_identity(config))))
        finished = not any(r.stopped for _, _, r in results)
    finally:
        kept = not finished and (out / "people.json").is_file()
        if kept:  # an earlier run's complete list is kept
            log(f"{out / 'people.json'}: kept (this run stopped after {len(results)} of {people.n_people} people)")
        else:
            atomic_write_text(out / "people.json", json.dumps({
                "people": summary, "frames": len(kin.frames),
                "participants": sum(p["role"] == "participant" for p in summary),
                "participant_rule": f"followed in at least {PARTICIPANT_MIN_SHARE:.0%} of the frames (else transient)",
                "cameras": rig.names, "rule": PEOPLE_RULE}, indent=2) + "\n")
        if own:  # the recording replaces the earlier one only together with the results it shows
            recording = close_run_recording(observer, out, keep=not kept)
    stopped = STOPPED_INTERRUPTED if any(r.stopped for _, _, r in results) else ""
    return RunResult(out, len(kin.frames), len(results), len(results), 0, stopped, time.perf_counter() - t0,
                     {"people": summary}, recording, {"people": results})


def _person_header(p: dict) -> str:
    return (f"{p['person']} ({p['role']}): frames {p['first_frame']}-{p['last_frame']} ({p['frames']} frames, "
            f"{p['share']:.0%}), median {p['cameras_per_frame_median']:g} cameras")


def _person_lines(result: RunResult) -> list:
    m, files = result.metrics, result.extra["files"]
    per_frame = 1000 * result.seconds / max(result.processed, 1)
    lines = [f"{m['status']}: {result.processed}/{result.frames} frames processed in {result.seconds:.1f} s "
             f"({per_frame:.0f} ms/frame), {m['with_estimate']} with a 3D estimate"]
    if "offsets" in m:
        lines.append(f"  offsets: {m['offsets']} ({m['offsets_reason']})")
        lines.append("  left/right flips applied (frames per camera): "
                     + ", ".join(f"{c} {n}" for c, n in m["flips_per_camera"].items()))
    if "mean_offset_px" in m:
        lines.append("  mean |offset| per camera (px): "
                     + ", ".join(f"{c} {o:.1f}" for c, o in m["mean_offset_px"].items()))
        lines.append(f"  mean ray distance: {1000 * m['mean_ray_distance_m']:.1f} mm; frames breaking an "
                     f"anthropometric constraint: {m['frames_breaking_constraints']}")
    lines += [f"  warning: {w}" for w in m.get("warnings", [])]
    lines.append(f"  3D joints:     {files['3D joints']}")
    lines += [f"  trajectories:  {p}" for p in result.extra["exported"]]
    lines += [f"  {k + ':':14s} {files[k]}" for k in ("offsets", "flips", "2D joints", "anthropometry")]
    return lines


def summary_lines(result: RunResult) -> list:
    """What a keypoint triangulation run says when it ends (the recipe prints these)."""
    if "people" in result.extra:
        lines = [x for name, header, r in result.extra["people"] for x in [header, *_person_lines(r)]]
    else:
        lines = _person_lines(result)
    if result.recording is not None:
        lines.append(f"  recording:     {result.recording}   (open with: rerun {result.recording})")
    return lines
