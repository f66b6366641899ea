"""Calibrating a rig from scratch as runs: intrinsics from a board, extrinsics from a board, scene points or people.

:func:`run_intrinsics` and :func:`run_extrinsics` are what ``recipes/calibrate.py``
calls (its docstring lists the inputs and outputs).  They find each camera's
input (a sub-folder or video per camera, matched to the intrinsics' cameras by
name, number or order), run :mod:`toolkit.calibration` and write the
calibration TOML, a JSON report beside it (``<out>.json``) and, unless told
not to, a rerun recording (``<out>.rrd``).  These are not frame-by-frame runs:
each reads all its views, solves once and writes once.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.errors import InputError

#: Board kinds.
BOARD_KINDS = ("checkerboard", "charuco")
#: Statures (metres) accepted for the people's scale.
HEIGHT_RANGE_M = (1.0, 2.5)


@dataclass(frozen=True)
class BoardOptions:
    """The calibration board and how its views are read (a ``[board]`` table in TOML).

    Parameters
    ----------
    kind : str, optional
        One of :data:`BOARD_KINDS` (required unless ``toml``).
    corners : tuple of int, optional
        Inner corners (rows, cols): squares minus one.
    square_mm : float, optional
        Side of a square, millimetres.
    marker_mm : float, optional
        ChArUco: side of a marker, millimetres.
    dictionary : str
        ChArUco: ArUco dictionary.
    toml : Path, optional
        The board geometry from a TOML file instead (``kind``, ``corners``, ``square_mm``, ...).
    every_s : float
        Videos: seconds between the frames used.
    max_frames : int
        At most this many frames per camera.
    """

    kind: str | None = None
    corners: tuple[int, int] | None = None
    square_mm: float | None = None
    marker_mm: float | None = None
    dictionary: str = "DICT_4X4_50"
    toml: Path | None = None
    every_s: float = 1.0
    max_frames: int = 200

    def __post_init__(self):
        if self.kind is not None and self.kind not in BOARD_KINDS:
            raise InputError("board.kind (--board)", f"one of {BOARD_KINDS}", repr(self.kind))
        if self.corners is not None and (len(self.corners) != 2 or min(self.corners) < 1):
            raise InputError("board.corners (--corners)", "inner corners as ROWS,COLS, e.g. 4,7", repr(self.corners))
        if not self.every_s > 0 or self.max_frames < 1:
            raise InputError("board.every_s / board.max_frames (--every-s / --max-frames)",
                             "seconds > 0 and at least one frame", f"{self.every_s}, {self.max_frames}")

    def board(self, required: bool = True):
        """The :class:`~toolkit.calibration.boards.Board` (None when not ``required`` and none is given).

        Raises
        ------
        InputError
            A missing option, named by its flag.
        """
        from toolkit.calibration.boards import Board, read_board_toml

        if self.toml is not None:
            return read_board_toml(self.toml)
        if self.kind is None:
            if not required:
                return None
            raise InputError("--board", "checkerboard or charuco (or --board-toml)", "nothing")
        if self.corners is None:
            raise InputError("--corners", "inner corners as ROWS,COLS, e.g. 4,7", "nothing")
        if self.square_mm is None or not self.square_mm > 0:
            raise InputError("--square-mm", "the side of a square in millimetres (> 0)", repr(self.square_mm))
        if self.kind == "charuco" and self.marker_mm is None:
            raise InputError("--marker-mm", "the side of a ChArUco marker in millimetres", "nothing")
        return Board(self.kind, int(self.corners[0]), int(self.corners[1]), self.square_mm / 1000.0,
                     None if self.marker_mm is None else self.marker_mm / 1000.0, self.dictionary)


def parse_corners(text: str | None) -> tuple[int, int] | None:
    """``"4,7"`` (or ``4x7``) as ``(4, 7)``; None stays None.

    Raises
    ------
    InputError
        Not two integers.
    """
    if text is None:
        return None
    m = re.fullmatch(r"\s*(\d+)\s*[,xX]\s*(\d+)\s*", text)
    if not m:
        raise InputError("--corners", "inner corners as ROWS,COLS, e.g. 4,7", repr(text))
    return int(m.group(1)), int(m.group(2))


@dataclass(frozen=True)
class IntrinsicsRunConfig:
    """Options of the intrinsics run (the recipe's flags; a TOML file holds the same keys).

    Parameters
    ----------
    board : BoardOptions
    recording : bool
        Write ``<out>.rrd``.
    """

    board: BoardOptions = field(default_factory=BoardOptions)
    recording: bool = True


@dataclass(frozen=True)
class ExtrinsicsRunConfig:
    """Options of the extrinsics run (the recipe's flags; a TOML file holds the same keys).

    Parameters
    ----------
    board : BoardOptions
        With board images.
    format : str
        Keypoint format (``"auto"``: found from the files, or a Pose2Sim ``pose_model``).
    height_m : float, optional
        The person's stature, metres (the scale); default: a Pose2Sim trial's
        ``participant_height``, else a median adult with a warning.
    min_confidence : float
        Keypoints below this are not used.
    seed : int
        RANSAC seed.
    recording : bool
        Write ``<out>.rrd``.
    """

    board: BoardOptions = field(default_factory=BoardOptions)
    format: str = "auto"
    height_m: float | None = None
    min_confidence: float = 0.3
    seed: int = 0
    recording: bool = True

    def __post_init__(self):
        lo, hi = HEIGHT_RANGE_M
        if self.height_m is not None and not lo <= self.height_m <= hi:
            raise InputError("--height-m", f"a stature between {lo} and {hi} metres", repr(self.height_m))


def camera_name(folder: str) -> str:
    """``cam_01`` for Pose2Sim-style names (``int_cam01_img``, ``cam01.mp4``), else the name itself."""
    m = re.search(r"cam(?:era)?[_-]?(\d+)", folder, re.IGNORECASE)
    return f"cam_{int(m.group(1)):02d}" if m else folder


def camera_inputs(root: Path) -> list[tuple[str, Path]]:
    """(camera name, images folder or video) per camera of an intrinsics folder.

    Raises
    ------
    InputError
        ``root`` is no folder, or holds neither a sub-folder or video per camera nor images.
    """
    from toolkit.calibration.boards import IMAGE_SUFFIXES, VIDEO_SUFFIXES

    root = Path(root)
    if not root.is_dir():
        raise InputError(str(root), "a folder of board images or videos", "no such folder")
    subs = sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))
    if subs:
        return [(camera_name(p.name), p) for p in subs]
    vids = sorted(p for p in root.iterdir() if p.suffix.lower() in VIDEO_SUFFIXES)
    if vids:
        return [(camera_name(p.stem), p) for p in vids]
    if any(p.suffix.lower() in IMAGE_SUFFIXES for p in root.iterdir()):
        return [(camera_name(root.name), root)]
    raise InputError(str(root), "a sub-folder or a video per camera, or images", "none of them")


def report_paths(out: Path) -> tuple[Path, Path]:
    """The JSON report and the recording beside a calibration file ``out``."""
    return Path(out).with_suffix(".json"), Path(out).with_suffix(".rrd")


def _observer(recording: bool, out: Path, app: str):
    if not recording:
        return None
    from toolkit.viz import RerunObserver

    return RerunObserver(application_id=app, path=report_paths(out)[1])


def _intrinsics_of(name: str, src: Path, board, options: BoardOptions, obs, log) -> tuple:
    """One camera's intrinsics from its board views; its report entry."""
    from toolkit.calibration.boards import board_frames, detect_in_frames
    from toolkit.calibration.intrinsics import calibrate_intrinsics

    dets, missed = detect_in_frames(board_frames(src, options.every_s, options.max_frames), board, str(src))
    r = calibrate_intrinsics(dets, board, name, missed=missed, observer=obs)
    K = r.camera.K
    log(f"{name}: {len(r.view_rms_px)} views, RMS {r.rms_px:.2f} px, fx {K[0, 0]:.1f} fy {K[1, 1]:.1f} "
        f"cx {K[0, 2]:.1f} cy {K[1, 2]:.1f}, coverage {r.coverage:.0%}")
    for view, why in r.rejected:
        log(f"  rejected {view}: {why}")
    for w in r.warnings:
        log(f"  warning: {w}")
    if obs is not None:
        for view, T in r.board_poses.items():
            P = board.object_points() @ T[:3, :3].T + T[:3, 3]
            obs.report("points3d", points=P, name=f"calibration/intrinsics/{name}/board/{view}")
    return r.camera, {"source": str(src), "rms_px": r.rms_px, "view_rms_px": r.view_rms_px,
                      "rejected": [list(x) for x in r.rejected], "coverage": r.coverage, "warnings": r.warnings,
                      "K": K.tolist(), "dist": r.camera.dist.tolist(), "size": list(r.camera.size)}


def run_intrinsics(config: IntrinsicsRunConfig, *, images, out, observer=None, log=print) -> dict:
    """Every camera's intrinsics from images or videos of a board, written to ``out``.

    Parameters
    ----------
    config : IntrinsicsRunConfig
    images : path
        A sub-folder (or a video) per camera, or one camera's images.
    out : path
        Intrinsics TOML (Pose2Sim / anipose layout); the report goes to ``<out>.json``,
        the recording to ``<out>.rrd``.
    observer : Observer, optional
        Default: ``<out>.rrd`` (``config.recording``).
    log : callable or None
        Receives each camera's result, rejected views and warnings.

    Returns
    -------
    dict
        The report (``board``, ``cameras``: per camera RMS, views, coverage, K, ...).

    Raises
    ------
    InputError
        Bad board options, inputs, or a board size no image shows.
    """
    from toolkit.cameras import Rig
    from toolkit.io.atomic import atomic_write_text
    from toolkit.io.calibration import write_calibration

    log = log or (lambda *_: None)
    board = config.board.board()
    inputs = camera_inputs(Path(images))
    own = observer is None
    obs = _observer(config.recording, Path(out), "calibrate_intrinsics") if own else observer
    cams, report = [], {"board": board.describe(), "cameras": {}}
    try:
        for name, src in inputs:
            cam, report["cameras"][name] = _intrinsics_of(name, src, board, config.board, obs, log)
            cams.append(cam)
        write_calibration(out, Rig(tuple(cams)), metadata={
            "kind": "intrinsics", "board": board.describe(),
            "error": float(np.mean([c["rms_px"] for c in report["cameras"].values()]))})
        atomic_write_text(report_paths(Path(out))[0], json.dumps(report, indent=1))
    finally:
        if own and obs is not None:
            obs.close()
    return report


def board_detections(root: Path, cams: list, board, options: BoardOptions) -> list:
    """Per camera (in ``cams``' order) ``{view: detection}`` of a folder of synchronised board images.

    Raises
    ------
    InputError
        No such folder, camera folders that do not match the cameras, or images of another size.
    """
    from toolkit.calibration.boards import board_frames, detect_board
    from toolkit.io.keypoint_files import match_cameras

    root = Path(root)
    if not root.is_dir():
        raise InputError(str(root), "a folder with a sub-folder of board images per camera", "no such folder")
    subs = sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))
    order, _ = match_cameras([c.name for c in cams], subs, f"{root}: camera folders")
    out = []
    for c, i in enumerate(order):
        dets = {}
        for name, im in board_frames(subs[i], options.every_s, options.max_frames):
            if im.shape[1::-1] != tuple(cams[c].size):
                raise InputError(f"{subs[i] / name}", f"images of {cams[c].size} as in the intrinsics",
                                 f"{im.shape[1::-1]}")
            d = detect_board(im, board, name)
            if d is not None:
                dets[Path(name).stem.split(":")[-1] if ":" in name else Path(name).stem] = d
        out.append(dets)
    return out


def keypoint_input(root: Path, cams: list, config: ExtrinsicsRunConfig) -> tuple:
    """The keypoints of a folder or a Pose2Sim trial matched to ``cams``, how, and the stature.

    Returns
    -------
    data : KeypointInput
    matching : str
    height : tuple of (float or None, str or None)
        The stature in metres and where it comes from (``--height-m``, a Pose2Sim
        ``participant_height``, or ``(None, None)``).
    """
    from toolkit.io.keypoint_files import camera_sources, match_cameras
    from toolkit.io.keypoint_formats import read_keypoints
    from toolkit.io.pose2sim import is_pose2sim_trial, participant_height, read_pose2sim_trial

    fmt, declared = None if config.format == "auto" else config.format, "--format"
    height = (config.height_m, "--height-m") if config.height_m is not None else (None, None)
    if is_pose2sim_trial(root):
        trial = read_pose2sim_trial(root)
        root = trial.keypoints
        if fmt is None and trial.pose_model is not None:
            fmt, declared = trial.pose_model, "[pose] pose_model of the Pose2Sim Config.toml"
        if height[0] is None:
            height = participant_height(trial.config_files)
    sources = camera_sources(root)
    order, how = match_cameras([c.name for c in cams], sources, f"{root}: camera sources")
    return read_keypoints([sources[i] for i in order], fmt, declared), how, height


def _from_boards(cams, root, config: ExtrinsicsRunConfig, obs, report: dict):
    from toolkit.calibration import extrinsics as ex

    board = config.board.board()
    dets = board_detections(root, cams, board, config.board)
    r = ex.extrinsics_from_boards(cams, dets, board, observer=obs)
    report["views"] = {c.name: sorted(d) for c, d in zip(cams, dets)}
    if obs is not None:
        O = board.object_points()
        for v, T in zip(r.details["views"], r.details["board_poses"]):
            outline = O[[0, board.cols - 1, board.n_corners - 1, board.n_corners - board.cols, 0]]
            obs.report("lines3d", strips=[outline @ T[:3, :3].T + T[:3, 3]], name=f"calibration/board/poses/{v}")
    return r


def _from_people(cams, root, config: ExtrinsicsRunConfig, obs, report: dict, log):
    from toolkit.calibration import extrinsics as ex
    from toolkit.skeleton.mappings import KEYPOINTS

    data, how, (height, height_from) = keypoint_input(Path(root), cams, config)
    if height is not None:
        log(f"stature {height:g} m ({height_from})")
    fmt = data.format.fmt
    r = ex.extrinsics_from_people(cams, data.keypoints, KEYPOINTS[fmt], fmt, height_m=height,
                                  config=ex.PeopleConfig(min_confidence=config.min_confidence),
                                  rng=np.random.default_rng(config.seed), observer=obs)
    report["keypoints"] = {"format": fmt, "why": data.format.reason, "matching": how,
                           "frames": int(len(data.frames)), "height_m": height, "height_from": height_from}
    if obs is not None:
        pts = r.points[:: max(1, len(r.points) // 200)]
        for cam in r.rig:
            obs.report("rays", origins=np.broadcast_to(cam.center, pts.shape).copy(), ends=pts,
                       name=f"calibration/people/rays/{cam.name}")
    return r


def _write_extrinsics(r, out: Path, report: dict, log) -> None:
    from toolkit.io.atomic import atomic_write_text
    from toolkit.io.calibration import write_calibration

    write_calibration(out, r.rig, metadata={"kind": f"extrinsics from {r.method}", "error": float(
        np.mean([v["rms_px"] for v in r.reprojection.values()])), "warnings": len(r.warnings)})
    report.update({"method": r.method, "reprojection": r.reprojection, "warnings": r.warnings,
                   "details": {k: v for k, v in r.details.items() if k not in ("board_poses", "keypoints3d")},
                   "centres_m": {c.name: c.center.tolist() for c in r.rig}})
    atomic_write_text(report_paths(out)[0], json.dumps(report, indent=1, default=str))
    for name, v in r.reprojection.items():
        c = r.rig[name].center
        log(f"{name}: {v['n']} observations, median {v['median_px']:.2f} px, RMS {v['rms_px']:.2f} px, "
            f"centre ({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f}) m")
    for w in r.warnings:
        log(f"warning: {w}")


def run_extrinsics(config: ExtrinsicsRunConfig, *, intrinsics, out, board_images=None, scene_points=None,
                   keypoints=None, observer=None, log=print) -> dict:
    """The cameras' poses from one source (board images, scene points or people), written to ``out``.

    Parameters
    ----------
    config : ExtrinsicsRunConfig
    intrinsics : path
        Intrinsics TOML (from :func:`run_intrinsics`).
    out : path
        Calibration TOML (Pose2Sim / anipose layout); the report goes to ``<out>.json``,
        the recording to ``<out>.rrd``.
    board_images, scene_points, keypoints : path, exactly one
        A sub-folder of synchronised board images per camera; a TOML or CSV of 3D
        points and their pixels per camera; a keypoints folder or a Pose2Sim trial.
    observer : Observer, optional
        Default: ``<out>.rrd`` (``config.recording``).
    log : callable or None
        Receives each camera's reprojection and centre, and the warnings.

    Returns
    -------
    dict
        The report (method, reprojection per camera, warnings, details, centres).

    Raises
    ------
    InputError
        Not exactly one source, bad inputs, cameras that do not match.
    """
    from toolkit.calibration import extrinsics as ex
    from toolkit.calibration.scene_points import read_scene_points
    from toolkit.io.calibration import read_calibration

    given = [s for s in (board_images, scene_points, keypoints) if s is not None]
    if len(given) != 1:
        raise InputError("run_extrinsics", "exactly one of board_images, scene_points, keypoints", f"{len(given)}")
    log = log or (lambda *_: None)
    cams = list(read_calibration(intrinsics))
    own = observer is None
    obs = _observer(config.recording, Path(out), "calibrate_extrinsics") if own else observer
    report: dict = {"intrinsics": str(intrinsics)}
    try:
        if board_images is not None:
            r = _from_boards(cams, board_images, config, obs, report)
        elif scene_points is not None:
            names, X, px = read_scene_points(scene_points, [c.name for c in cams])
            r = ex.extrinsics_from_scene_points(cams, X, px, names, observer=obs)
        else:
            r = _from_people(cams, keypoints, config, obs, report, log)
        _write_extrinsics(r, Path(out), report, log)
    finally:
        if own and obs is not None:
            obs.close()
    return report
