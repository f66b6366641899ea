"""Detecting 2D keypoints in a rig's videos, as a resumable run, and synchronising the cameras.

:func:`detect_videos` is what ``recipes/detect_keypoints.py`` calls, and what the keypoint consumers
(``pose_from_keypoints``, ``import_pose2sim``, ``free_viewpoint``) call when a trial has videos but
no keypoints (:func:`ensure_keypoints`).  It writes, per camera (named after its video's stem)::

    KP_DIR/<camera>/<camera>_<frame:012d>_keypoints.json    OpenPose JSON: every person found
    KP_DIR/detection.json                                   layout, model, options, per-camera summary
    KP_DIR/sync.json                                        with ``sync``: offsets and their evidence

The JSON files are OpenPose's (``{"version": 1.3, "people": [{"pose_keypoints_2d": [x, y, c, ...]}]}``)
in the detector's keypoint layout (``blazepose_33`` by default: the 33 names of
``toolkit.skeleton.mappings.BLAZEPOSE_33``, in that order), frames numbered from 0, so every reader
of keypoints takes them as they are.  Each file is written atomically as its frame is done: an
interrupted run keeps its frames and a rerun with the same options does only the missing ones (a
rerun with other options into the same folder is refused).  Cameras run in parallel processes
(``workers``; default: one per camera up to the machine's cores).
"""

from __future__ import annotations

import json
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.io.video import VIDEO_SUFFIXES
from toolkit.pipeline.parallel import available_cores

__all__ = ["DetectConfig", "DetectResult", "VIDEO_SUFFIXES", "find_videos", "detect_videos", "synchronise",
           "read_sync", "ensure_keypoints", "detected_frame_rate", "summary_lines", "DETECTION_FILE", "SYNC_FILE"]

#: Summary file of a detection run, and the synchronisation's.
DETECTION_FILE = "detection.json"
SYNC_FILE = "sync.json"
#: Video folders of a trial, in order of preference (Pose2Sim's layout: ``videos/``).
VIDEO_FOLDERS = ("videos", "video", "raw_videos")
#: Frame rates closer than this (relative) are the same.
FPS_TOLERANCE = 0.01


@dataclass(frozen=True)
class DetectConfig:
    """Options of a detection run (the recipe's flags; a TOML file holds the same keys).

    Parameters
    ----------
    detector : str
        Backend name (``toolkit.detection.BACKENDS``).
    num_poses : int
        Most people found per image (``mediapipe``).
    tiles : bool
        Also detect in square tiles along the image's long side and merge (``mediapipe``; finds people
        the whole image misses, at about four times the cost on a portrait or wide image).
    min_detection_confidence, min_presence_confidence : float
        Detector thresholds (``mediapipe``).
    det_model, pose_model : Path, optional
        ONNX files (``rtmlib``).
    layout : str
        Keypoint layout of the pose model (``rtmlib``).
    max_frames : int, optional
        Only the first N frames of each video.
    workers : int, optional
        Processes (one camera each); default: as many as cameras, up to the machine's cores.
    sync : bool
        Also find each camera's frame offset (``sync.json``).
    max_sync_offset : int
        Largest offset searched, frames.
    calibration : Path, optional
        The rig's calibration, for the synchronisation by ray geometry (else by motion).
    progress : bool
        Print a line per finished camera.
    """

    detector: str = "mediapipe"
    num_poses: int = 6
    tiles: bool = True
    min_detection_confidence: float = 0.5
    min_presence_confidence: float = 0.5
    det_model: Path | None = None
    pose_model: Path | None = None
    layout: str = "halpe_26"
    max_frames: int | None = None
    workers: int | None = None
    sync: bool = False
    max_sync_offset: int = 60
    calibration: Path | None = None
    progress: bool = True

    #: Fields that do not change the detections (left out of the run identity).
    RUNTIME = ("workers", "sync", "max_sync_offset", "calibration", "progress", "max_frames")

    def __post_init__(self):
        from toolkit.detection import BACKENDS

        checks = (("detector", self.detector in BACKENDS, f"one of {sorted(BACKENDS)}"),
                  ("num_poses", isinstance(self.num_poses, int) and self.num_poses >= 1, "a whole number >= 1"),
                  ("max_frames", self.max_frames is None or self.max_frames >= 1, "a number of frames >= 1"),
                  ("workers", self.workers is None or self.workers >= 1, "a number of processes >= 1"),
                  ("max_sync_offset", isinstance(self.max_sync_offset, int) and self.max_sync_offset >= 0,
                   "a whole number of frames >= 0"),
                  ("min_detection_confidence", 0 <= self.min_detection_confidence <= 1, "a value in [0, 1]"),
                  ("min_presence_confidence", 0 <= self.min_presence_confidence <= 1, "a value in [0, 1]"))
        for name, ok, expected in checks:
            if not ok:
                raise InputError(f"DetectConfig.{name} (--{name.replace('_', '-')})", expected,
                                 repr(getattr(self, name)))

    def backend_options(self) -> dict:
        """The options handed to :func:`toolkit.detection.make_detector`."""
        if self.detector == "mediapipe":
            return {"num_poses": self.num_poses, "tiles": self.tiles, "min_detection_confidence": self.min_detection_confidence,
                    "min_presence_confidence": self.min_presence_confidence}
        return {"det_model": self.det_model, "pose_model": self.pose_model, "layout": self.layout}

    def identity(self) -> dict:
        """What makes two runs' detections the same."""
        d = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(self).items() if k not in self.RUNTIME}
        return d


@dataclass
class DetectResult:
    """What a detection run did.

    Attributes
    ----------
    out : Path
    cameras : dict of str to dict
        Per camera: video, fps, size, frames, frames detected now and before, people per frame
        (a histogram), seconds.
    layout : str
    model : str
    warnings : list of str
    sync : SyncResult or None
    seconds : float
    """

    out: Path
    cameras: dict
    layout: str
    model: str
    warnings: list = field(default_factory=list)
    sync: object = None
    seconds: float = 0.0

    @property
    def frames_detected(self) -> int:
        """Frames run through the detector by this run (all cameras)."""
        return int(sum(c["frames_detected_now"] for c in self.cameras.values()))

    @property
    def detector_fps(self) -> float:
        """Images detected per second of the whole run (start-up, decoding and all processes included)."""
        busy = self.seconds
        return self.frames_detected / busy if busy > 0 else float("nan")


# --------------------------------------------------------------------------- inputs

def find_videos(source) -> list[Path]:
    """The videos of a rig: a folder of videos, a trial folder with ``videos/``, or a list of files.

    Parameters
    ----------
    source : path-like or sequence of path-like

    Returns
    -------
    list of Path
        Sorted by name; each camera is named after its video's stem.

    Raises
    ------
    InputError
        Nothing found, a file that is not a video, two videos with the same stem.
    """
    if isinstance(source, (list, tuple)):
        files = [Path(p) for p in source]
        where = "videos"
    else:
        root = Path(source)
        where = str(root)
        if root.is_file():
            files = [root]
        elif root.is_dir():
            folder = next((root / f for f in VIDEO_FOLDERS if (root / f).is_dir()), root)
            where = str(folder)
            files = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES)
        else:
            raise InputError(str(root), "a video, a folder of videos or a trial folder with videos/",
                             "no such file or folder")
    for f in files:
        if not f.is_file():
            raise InputError(str(f), "a video file", "no such file")
        if f.suffix.lower() not in VIDEO_SUFFIXES:
            raise InputError(str(f), f"a video ending in {VIDEO_SUFFIXES}", f"suffix {f.suffix!r}")
    if not files:
        raise InputError(where, f"video files ({', '.join(VIDEO_SUFFIXES)}) or a videos/ folder", "none")
    stems = [f.stem for f in files]
    dup = sorted({s for s in stems if stems.count(s) > 1})
    if dup:
        raise InputError(where, "one video per camera (cameras are named after the video's stem)",
                         f"several videos named {dup}")
    return sorted(files, key=lambda p: p.stem)


def _frame_file(out: Path, camera: str, frame: int) -> Path:
    return out / camera / f"{camera}_{frame:012d}_keypoints.json"


# --------------------------------------------------------------------------- one camera (a worker process)

def _detect_camera(video: str, out: str, backend: str, options: dict, max_frames: int | None) -> dict:
    """Run the detector over one video, writing a JSON file per frame not yet done; returns its summary."""
    from toolkit.detection import make_detector
    from toolkit.io import VideoReader
    from toolkit.io.openpose import write_openpose_json

    video, out = Path(video), Path(out)
    camera = video.stem
    t0 = time.perf_counter()
    reader = VideoReader(video)
    n = len(reader) if max_frames is None else min(len(reader), max_frames)
    todo = {f for f in range(n) if not _frame_file(out, camera, f).is_file()}
    counts: dict[int, int] = {}
    detector = None
    try:
        if todo:
            detector = make_detector(backend, **options)
            last = max(todo)
            for f, image in enumerate(reader):
                if f > last:
                    break
                if f not in todo:
                    continue
                people = detector.detect(image)
                write_openpose_json(_frame_file(out, camera, f), [p.keypoints for p in people])
                counts[len(people)] = counts.get(len(people), 0) + 1
    finally:
        if detector is not None:
            detector.close()
        reader.close()
    return {"camera": camera, "video": str(video), "fps": float(reader.fps), "size": list(reader.size),
            "n_frames": int(n), "frames_detected_now": len(todo), "frames_before": n - len(todo),
            "people_per_frame_now": {str(k): v for k, v in sorted(counts.items())},
            "seconds": round(time.perf_counter() - t0, 3)}


def _people_histogram(out: Path, camera: str, n: int) -> dict:
    hist: dict[int, int] = {}
    for f in range(n):
        p = _frame_file(out, camera, f)
        if p.is_file():
            k = len(json.loads(p.read_text()).get("people", []))
            hist[k] = hist.get(k, 0) + 1
    return {str(k): v for k, v in sorted(hist.items())}


# --------------------------------------------------------------------------- the run

def _check_identity(out: Path, config: DetectConfig, model: str) -> None:
    path = out / DETECTION_FILE
    if not path.is_file():
        return
    try:
        old = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return
    if old.get("options") != config.identity():
        raise InputError(str(path), "a detection run with the same options (or another --out)",
                         f"options {old.get('options')} (this run: {config.identity()})")


def _probe(videos: list[Path]) -> tuple[dict, list[str]]:
    """Each video's frame rate, size and frames, and warnings for rates or counts that differ."""
    from toolkit.io.video import probe_video

    infos = {v.stem: probe_video(v) for v in videos}
    warnings = []
    rates = {k: i.fps for k, i in infos.items()}
    ref = float(np.median(list(rates.values())))
    odd = {k: r for k, r in rates.items() if not (abs(r - ref) <= FPS_TOLERANCE * max(ref, 1e-9))}
    if odd:
        warnings.append(f"cameras with different frame rates: {rates} (frames are paired by number; resample "
                        "the videos to one rate first, or the 3D result mixes instants)")
    counts = {k: i.n_frames for k, i in infos.items()}
    if len(set(counts.values())) > 1:
        warnings.append(f"videos with different frame counts: {counts} (a camera started late or stopped "
                        "early: use --sync)")
    return infos, warnings


def detect_videos(source, out, config: DetectConfig = DetectConfig(), log=print) -> DetectResult:
    """Detect the people in every frame of every camera's video and write OpenPose JSON files.

    Parameters
    ----------
    source : path-like or sequence of path-like
        Videos (see :func:`find_videos`).
    out : path-like
        The keypoint folder (created).
    config : DetectConfig
    log : callable
        Receives progress and warning lines.

    Returns
    -------
    DetectResult
        Also written as ``out/detection.json``.

    Raises
    ------
    InputError
        No videos, a video that does not open (naming it), a backend that cannot run, or a folder
        holding a run made with other options.
    """
    from toolkit.detection import make_detector
    from toolkit.io.atomic import atomic_write_text
    from toolkit.skeleton.mappings import KEYPOINTS

    t0 = time.perf_counter()
    videos = find_videos(source)
    out = Path(out)
    infos, warnings = _probe(videos)
    for w in warnings:
        log(f"warning: {w}")
    probe = make_detector(config.detector, **config.backend_options())   # fails early with a clear error
    layout, model = probe.layout, probe.model
    probe.close()
    _check_identity(out, config, model)
    out.mkdir(parents=True, exist_ok=True)
    workers = config.workers or max(1, min(len(videos), available_cores()))
    jobs = [(str(v), str(out), config.detector, config.backend_options(), config.max_frames) for v in videos]
    summaries = {}
    if workers == 1:
        for job in jobs:
            s = _detect_camera(*job)
            summaries[s["camera"]] = s
            if config.progress:
                log(f"{s['camera']}: {s['frames_detected_now']} frames in {s['seconds']:.1f} s")
    else:
        with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
            futures = [pool.submit(_detect_camera, *job) for job in jobs]
            for fut in futures:
                s = fut.result()
                summaries[s["camera"]] = s
                if config.progress:
                    log(f"{s['camera']}: {s['frames_detected_now']} frames in {s['seconds']:.1f} s")
    for cam, s in summaries.items():
        s["people_per_frame"] = _people_histogram(out, cam, s["n_frames"])
        if set(s["people_per_frame"]) <= {"0"}:
            warnings.append(f"{cam}: nobody found in any of its {s['n_frames']} frames")
    if all(set(s["people_per_frame"]) <= {"0"} for s in summaries.values()):
        warnings.append("nobody found in any camera: check the videos (people far smaller than a tenth of the "
                        "image are missed) or lower --min-detection-confidence")
    result = DetectResult(out=out, cameras=summaries, layout=layout, model=model, warnings=warnings,
                          seconds=time.perf_counter() - t0)
    doc = {"layout": layout, "keypoint_names": list(KEYPOINTS[layout]), "detector": config.detector,
           "model": model, "options": config.identity(), "frames_from": 0,
           "file_pattern": "<camera>/<camera>_<frame:012d>_keypoints.json (OpenPose JSON)",
           "cameras": summaries, "warnings": warnings, "seconds": round(result.seconds, 2),
           "detector_fps": round(result.detector_fps, 2) if np.isfinite(result.detector_fps) else None}
    atomic_write_text(out / DETECTION_FILE, json.dumps(doc, indent=1))
    if config.sync:
        calibration = config.calibration if config.calibration is not None else _trial_calibration(source)
        if calibration is not None and config.calibration is None:
            log(f"sync: by the rays of the trial's calibration {calibration}")
        result.sync = synchronise(out, config.max_sync_offset, calibration)
        log("sync: " + ", ".join(f"{k} {v:+d}" for k, v in result.sync.offsets.items()))
    return result


def _trial_calibration(source):
    """The calibration file of a Pose2Sim trial given as the videos' source (None otherwise): ``--sync``
    then solves by ray geometry, which finds offsets the motion correlation misses."""
    from toolkit.io.pose2sim import is_pose2sim_trial, read_pose2sim_trial

    if isinstance(source, (list, tuple)) or not Path(source).is_dir():
        return None
    try:
        return read_pose2sim_trial(source).calibration if is_pose2sim_trial(source) else None
    except InputError:
        return None


# --------------------------------------------------------------------------- synchronisation

def synchronise(kp_dir, max_offset: int = 60, calibration=None):
    """Find each camera's frame offset from the keypoints of ``kp_dir`` and write ``kp_dir/sync.json``.

    Parameters
    ----------
    kp_dir : path-like
        A keypoint folder (one sub-folder or file per camera, any format the toolkit reads).
    max_offset : int
        Largest offset searched, frames.
    calibration : path-like, optional
        The rig's calibration: all offsets solved at once from where the rays of every pair of
        cameras meet (:func:`toolkit.detection.sync.find_offsets_geometric`, sharp); without it, from
        the correlation of the people's motion (:func:`toolkit.detection.sync.find_offsets`).

    Returns
    -------
    SyncResult
        Also written to ``sync.json``: the offsets, then the evidence (per camera its cost or
        correlation curve over lags and its confidence; with a calibration, every pair's cost curve),
        and the calibration file used.

    Raises
    ------
    InputError
        A camera of ``kp_dir`` that the calibration lacks, or fewer than two cameras.
    """
    from toolkit.detection.sync import find_offsets, find_offsets_geometric, motion_signal
    from toolkit.io.atomic import atomic_write_text
    from toolkit.io.keypoint_files import camera_sources, read_camera_detections

    kp_dir = Path(kp_dir)
    per_camera = {}
    for src in camera_sources(kp_dir):
        cam = read_camera_detections(src)
        frames = np.asarray(cam.frames)
        T = int(frames.max()) + 1 if len(frames) else 0
        per_frame: list[list[np.ndarray]] = [[] for _ in range(T)]
        for f, people in zip(frames, cam.people):
            per_frame[int(f)] = [np.asarray(p, float) for p in people]
        per_camera[src.name] = per_frame
    if calibration is not None:
        from toolkit.io.calibration import read_calibration
        from toolkit.io.keypoint_files import normalise_name

        rig = read_calibration(calibration)
        by_norm = {normalise_name(c.name): c for c in rig.cameras}
        cameras = {n: by_norm[normalise_name(n)] for n in per_camera if normalise_name(n) in by_norm}
        result = find_offsets_geometric(per_camera, cameras, max_offset=max_offset)
    else:
        result = find_offsets({n: motion_signal(p) for n, p in per_camera.items()}, max_offset=max_offset)
    doc = result.to_json()
    doc["calibration"] = None if calibration is None else str(calibration)
    atomic_write_text(kp_dir / SYNC_FILE, json.dumps(doc, indent=1))
    return result


def read_sync(kp_dir) -> dict[str, int] | None:
    """The offsets of ``kp_dir/sync.json`` (camera folder name -> frames started late), or None.

    Raises
    ------
    InputError
        A ``sync.json`` that is not a JSON object with integer ``offsets``.
    """
    path = Path(kp_dir) / SYNC_FILE
    if not path.is_file():
        return None
    try:
        offsets = json.loads(path.read_text())["offsets"]
        return {str(k): int(v) for k, v in offsets.items() if float(v) == int(v)}
    except (OSError, json.JSONDecodeError, KeyError, TypeError, ValueError) as e:
        raise InputError(str(path), "a JSON object with 'offsets': {camera: whole frames}",
                         f"{type(e).__name__}: {e}") from None


def detected_frame_rate(kp_dir) -> float | None:
    """The videos' frame rate recorded in ``kp_dir/detection.json`` (the median over cameras), or None."""
    path = Path(kp_dir) / DETECTION_FILE
    try:
        rates = [float(c["fps"]) for c in json.loads(path.read_text())["cameras"].values()]
    except (OSError, json.JSONDecodeError, KeyError, TypeError, ValueError):
        return None
    rates = [r for r in rates if r > 0]
    return float(np.median(rates)) if rates else None


def ensure_keypoints(videos_source, kp_dir, config: DetectConfig = DetectConfig(), log=print) -> Path:
    """The keypoints of a rig's videos in ``kp_dir``, detected now unless a complete run is there.

    Used by the keypoint consumers when a trial has videos and no keypoints.

    Returns
    -------
    Path
        ``kp_dir``.
    """
    kp_dir = Path(kp_dir)
    done = kp_dir / DETECTION_FILE
    if done.is_file():
        try:
            doc = json.loads(done.read_text())
            complete = doc.get("options") == config.identity() and all(
                _frame_file(kp_dir, cam, f).is_file() for cam, c in doc["cameras"].items()
                for f in range(int(c["n_frames"])))
        except (OSError, json.JSONDecodeError, KeyError, TypeError):
            complete = False
        if complete:
            return kp_dir
    log(f"no keypoints: detecting people in the videos of {videos_source} into {kp_dir}")
    detect_videos(videos_source, kp_dir, config, log=log)
    return kp_dir


def summary_lines(result: DetectResult) -> list[str]:
    """What the recipe prints at the end."""
    lines = [f"detector: {result.model}, layout {result.layout}",
             f"{result.frames_detected} images detected in {result.seconds:.1f} s "
             f"({result.detector_fps:.2f} images/s)"]
    for cam, s in result.cameras.items():
        lines.append(f"  {cam}: {s['n_frames']} frames ({s['frames_before']} from an earlier run), "
                     f"people per frame {s['people_per_frame']}")
    for w in result.warnings:
        lines.append(f"warning: {w}")
    if result.sync is not None:
        s = result.sync
        lines.append("sync offsets (frames started late): " + ", ".join(
            f"{k} {v}" + ("" if s.trusted[k] else " (untrusted: " + (
                "other offsets fit the rays almost as well)" if s.method == "rays" else "weak correlation)"))
            for k, v in s.offsets.items()))
    return lines
