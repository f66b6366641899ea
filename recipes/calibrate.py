#!/usr/bin/env python3
"""Calibrate a rig from scratch: intrinsics from a board, extrinsics from a board, scene points or people.

Usage::

    python recipes/calibrate.py intrinsics IMAGES_OR_VIDEOS_DIR --board checkerboard|charuco \\
        --corners ROWS,COLS --square-mm S [--marker-mm M] --out intrinsics.toml
    python recipes/calibrate.py extrinsics --intrinsics intrinsics.toml \\
        (--board-images DIR | --scene-points FILE | --keypoints DIR) --out calibration.toml

``intrinsics``: ``IMAGES_OR_VIDEOS_DIR`` holds one sub-folder per camera (images and / or
videos; Pose2Sim's ``intrinsics/int_cam01_img`` layout), or one video per camera, or the
images of a single camera.  ``--corners`` counts *inner* corners (squares minus one) as
rows,cols; a board TOML (``--board-toml``: ``kind``, ``corners``, ``square_mm``,
``marker_mm``, ``dictionary``) may replace the board options.  Views without the board and
views whose reprojection error is far above the others are rejected with the reason;
the image coverage of the corners is reported (a board seen only in the middle is a
warning).  A declared board size that no image shows is an error saying which board the
images show.

``extrinsics``: camera folders / files are matched to the intrinsics' cameras by name
(``cam01_json`` is ``cam_01``), else by the numbers in the names, else by sorted order.
``--board-images DIR``: a sub-folder per camera of synchronised images (same file names
mean the same moment); the world is the board of the first view the first camera sees,
z out of its printed side.  ``--scene-points FILE``: 3D coordinates and their pixels per
camera (TOML or CSV, docs/calibration.md).  ``--keypoints DIR``: 2D keypoints of a person
moving through the volume (any detector of docs/keypoint_formats.md, or a Pose2Sim trial
folder); the scale from ``--height-m`` (else a Pose2Sim trial's ``participant_height``,
else a median adult with a warning), the floor from the resting feet.

Both commands write the Pose2Sim / anipose TOML (``--out``), a JSON report next to it
(``<out>.json``: reprojection errors per camera, rejected views, coverage, warnings) and a
rerun recording (``<out>.rrd``: cameras, board poses or keypoint points and rays,
residuals) unless ``--no-recording``.  Exit status 2 on bad input (the message names the
file or argument), 0 otherwise; warnings are printed and kept in the report.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from toolkit.errors import InputError


def _board_args(ap, required: bool):
    ap.add_argument("--board", choices=("checkerboard", "charuco"), default=None,
                    help="board kind" + (" (required unless --board-toml)" if required else ""))
    ap.add_argument("--corners", default=None, help="inner corners ROWS,COLS (squares minus one), e.g. 4,7")
    ap.add_argument("--square-mm", type=float, default=None, help="side of a square, millimetres")
    ap.add_argument("--marker-mm", type=float, default=None, help="ChArUco: side of a marker, millimetres")
    ap.add_argument("--dictionary", default="DICT_4X4_50", help="ChArUco: ArUco dictionary (default DICT_4X4_50)")
    ap.add_argument("--board-toml", type=Path, default=None, help="board geometry from a TOML file instead")
    ap.add_argument("--every-s", type=float, default=1.0, help="videos: seconds between frames used (default 1)")
    ap.add_argument("--max-frames", type=int, default=200, help="at most this many frames per camera (default 200)")


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    sub = ap.add_subparsers(dest="command", required=True)
    a = sub.add_parser("intrinsics", help="intrinsics from images or videos of a board",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    a.add_argument("images", type=Path, help="folder: a sub-folder (or a video) per camera, or one camera's images")
    _board_args(a, True)
    a.add_argument("--out", type=Path, required=True, help="intrinsics TOML (Pose2Sim / anipose layout)")
    a.add_argument("--no-recording", action="store_true", help="do not write <out>.rrd")
    e = sub.add_parser("extrinsics", help="camera poses from a board, scene points or people")
    e.add_argument("--intrinsics", type=Path, required=True, help="intrinsics TOML (from the intrinsics command)")
    src = e.add_mutually_exclusive_group(required=True)
    src.add_argument("--board-images", type=Path, help="a sub-folder of synchronised board images per camera")
    src.add_argument("--scene-points", type=Path, help="TOML or CSV of 3D points and their pixels per camera")
    src.add_argument("--keypoints", type=Path, help="keypoints folder (a sub-folder or JSON per camera) or a "
                                                    "Pose2Sim trial")
    _board_args(e, False)
    e.add_argument("--format", default="auto", help="keypoint format (default auto: found from the files)")
    e.add_argument("--height-m", type=float, default=None,
                   help="the person's stature, metres (the scale); default: a Pose2Sim trial's participant_height, "
                        "else a median adult with a warning")
    e.add_argument("--min-confidence", type=float, default=0.3, help="keypoints below this are not used")
    e.add_argument("--seed", type=int, default=0, help="RANSAC seed (default 0)")
    e.add_argument("--out", type=Path, required=True, help="calibration TOML (Pose2Sim / anipose layout)")
    e.add_argument("--no-recording", action="store_true", help="do not write <out>.rrd")
    return ap.parse_args(argv)


def board_from_args(args, required: bool = True):
    """The Board of --board-toml or --board/--corners/--square-mm/--marker-mm (InputError naming the option)."""
    from toolkit.calibration.boards import Board, read_board_toml

    if args.board_toml is not None:
        return read_board_toml(args.board_toml)
    if args.board is None:
        if not required:
            return None
        raise InputError("--board", "checkerboard or charuco (or --board-toml)", "nothing")
    m = re.fullmatch(r"\s*(\d+)\s*[,xX]\s*(\d+)\s*", args.corners or "")
    if not m:
        raise InputError("--corners", "inner corners as ROWS,COLS, e.g. 4,7", repr(args.corners))
    if args.square_mm is None or not args.square_mm > 0:
        raise InputError("--square-mm", "the side of a square in millimetres (> 0)", repr(args.square_mm))
    if args.board == "charuco" and args.marker_mm is None:
        raise InputError("--marker-mm", "the side of a ChArUco marker in millimetres", "nothing")
    return Board(args.board, int(m.group(1)), int(m.group(2)), args.square_mm / 1000.0,
                 None if args.marker_mm is None else args.marker_mm / 1000.0, args.dictionary)


def camera_name(folder: str) -> str:
    """``cam_01`` for Pose2Sim-style names (``int_cam01_img``, ``cam01.mp4``), else the name itself."""
    m = re.search(r"cam(?:era)?[_-]?(\d+)", folder, re.IGNORECASE)
    return f"cam_{int(m.group(1)):02d}" if m else folder


def camera_inputs(root: Path) -> list[tuple[str, Path]]:
    """(camera name, images folder or video) per camera of an intrinsics folder."""
    from toolkit.calibration.boards import IMAGE_SUFFIXES, VIDEO_SUFFIXES

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


def _report_paths(out: Path) -> tuple[Path, Path]:
    return out.with_suffix(".json"), out.with_suffix(".rrd")


def _observer(args, out: Path, app: str):
    if args.no_recording:
        return None
    from toolkit.viz import RerunObserver

    return RerunObserver(application_id=app, path=_report_paths(out)[1])


def run_intrinsics(args) -> int:
    import numpy as np

    from toolkit.calibration.boards import board_frames, detect_in_frames
    from toolkit.calibration.intrinsics import calibrate_intrinsics
    from toolkit.cameras import Rig
    from toolkit.io.atomic import atomic_write_text
    from toolkit.io.calibration import write_calibration

    board = board_from_args(args)
    inputs = camera_inputs(args.images)
    obs = _observer(args, args.out, "calibrate_intrinsics")
    cams, report = [], {"board": board.describe(), "cameras": {}}
    try:
        for name, src in inputs:
            dets, missed = detect_in_frames(board_frames(src, args.every_s, args.max_frames), board, str(src))
            r = calibrate_intrinsics(dets, board, name, missed=missed, observer=obs)
            cams.append(r.camera)
            K = r.camera.K
            print(f"{name}: {len(r.view_rms_px)} views, RMS {r.rms_px:.2f} px, fx {K[0, 0]:.1f} fy {K[1, 1]:.1f} "
                  f"cx {K[0, 2]:.1f} cy {K[1, 2]:.1f}, coverage {r.coverage:.0%}")
            for view, why in r.rejected:
                print(f"  rejected {view}: {why}")
            for w in r.warnings:
                print(f"  warning: {w}")
            report["cameras"][name] = {"source": str(src), "rms_px": r.rms_px, "view_rms_px": r.view_rms_px,
                                       "rejected": [list(x) for x in r.rejected], "coverage": r.coverage,
                                       "warnings": r.warnings, "K": K.tolist(), "dist": r.camera.dist.tolist(),
                                       "size": list(r.camera.size)}
            if obs is not None:
                for view, T in r.board_poses.items():
                    P = board.object_points() @ T[:3, :3].T + T[:3, 3]
                    obs.report("points3d", points=P, name=f"calibration/intrinsics/{name}/board/{view}")
        rig = Rig(tuple(cams))
        write_calibration(args.out, rig, metadata={"kind": "intrinsics", "board": board.describe(),
                                                   "error": float(np.mean([c["rms_px"] for c in
                                                                           report["cameras"].values()]))})
        atomic_write_text(_report_paths(args.out)[0], json.dumps(report, indent=1))
        print(f"wrote {args.out}")
    finally:
        if obs is not None:
            obs.close()
    return 0


def _board_detections(args, cams, board):
    from toolkit.calibration.boards import board_frames, detect_board
    from toolkit.io.keypoint_files import match_cameras

    root = args.board_images
    if not root.is_dir():
        raise InputError(str(root), "a folder with a sub-folder of board images per camera", "no such folder")
    subs = sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))
    order, _ = match_cameras([c.name for c in cams], subs, f"{root}: camera folders")
    out = []
    for c, i in enumerate(order):
        dets = {}
        for name, im in board_frames(subs[i], args.every_s, args.max_frames):
            if im.shape[1::-1] != tuple(cams[c].size):
                raise InputError(f"{subs[i] / name}", f"images of {cams[c].size} as in the intrinsics",
                                 f"{im.shape[1::-1]}")
            d = detect_board(im, board, name)
            if d is not None:
                dets[Path(name).stem.split(":")[-1] if ":" in name else Path(name).stem] = d
        out.append(dets)
    return out


def _keypoint_input(args, cams):
    from toolkit.io.keypoint_files import camera_sources, match_cameras
    from toolkit.io.keypoint_formats import read_keypoints
    from toolkit.io.pose2sim import is_pose2sim_trial, read_pose2sim_trial

    root, fmt, declared = args.keypoints, None if args.format == "auto" else args.format, "--format"
    height = (args.height_m, "--height-m") if args.height_m is not None else (None, None)
    if is_pose2sim_trial(root):
        trial = read_pose2sim_trial(root)
        root = trial.keypoints
        if fmt is None and trial.pose_model is not None:
            fmt, declared = trial.pose_model, "[pose] pose_model of the Pose2Sim Config.toml"
        if height[0] is None:
            height = pose2sim_height(trial.config_files)
    sources = camera_sources(root)
    order, how = match_cameras([c.name for c in cams], sources, f"{root}: camera sources")
    data = read_keypoints([sources[i] for i in order], fmt, declared)
    return data, how, height


def pose2sim_height(config_files) -> tuple[float | None, str | None]:
    """``[markerAugmentation] participant_height`` of the Pose2Sim settings (the last file that sets a
    single number wins), with the file it comes from; ``(None, None)`` when none does."""
    import tomllib

    found = (None, None)
    for f in config_files:
        try:
            doc = tomllib.loads(Path(f).read_text(encoding="utf-8"))
        except (OSError, tomllib.TOMLDecodeError):
            continue
        h = doc.get("markerAugmentation", {}).get("participant_height")
        if isinstance(h, (int, float)) and 1.0 <= h <= 2.5:
            found = (float(h), f"participant_height of {f}")
    return found


def run_extrinsics(args) -> int:
    import numpy as np

    from toolkit.calibration import extrinsics as ex
    from toolkit.calibration.scene_points import read_scene_points
    from toolkit.io.atomic import atomic_write_text
    from toolkit.io.calibration import read_calibration, write_calibration
    from toolkit.skeleton.mappings import KEYPOINTS

    cams = list(read_calibration(args.intrinsics))
    obs = _observer(args, args.out, "calibrate_extrinsics")
    report: dict = {"intrinsics": str(args.intrinsics)}
    try:
        if args.board_images is not None:
            board = board_from_args(args)
            dets = _board_detections(args, cams, board)
            r = ex.extrinsics_from_boards(cams, dets, board, observer=obs)
            report["views"] = {c.name: sorted(d) for c, d in zip(cams, dets)}
            if obs is not None:
                O = board.object_points()
                for v, T in zip(r.details["views"], r.details["board_poses"]):
                    outline = O[[0, board.cols - 1, board.n_corners - 1, board.n_corners - board.cols, 0]]
                    obs.report("lines3d", strips=[outline @ T[:3, :3].T + T[:3, 3]],
                               name=f"calibration/board/poses/{v}")
        elif args.scene_points is not None:
            names, X, px = read_scene_points(args.scene_points, [c.name for c in cams])
            r = ex.extrinsics_from_scene_points(cams, X, px, names, observer=obs)
        else:
            if args.height_m is not None and not (1.0 <= args.height_m <= 2.5):
                raise InputError("--height-m", "a stature between 1.0 and 2.5 metres", repr(args.height_m))
            data, how, (height, height_from) = _keypoint_input(args, cams)
            if height is not None:
                print(f"stature {height:g} m ({height_from})")
            fmt = data.format.fmt
            r = ex.extrinsics_from_people(cams, data.keypoints, KEYPOINTS[fmt], fmt, height_m=height,
                                          config=ex.PeopleConfig(min_confidence=args.min_confidence),
                                          rng=np.random.default_rng(args.seed), observer=obs)
            report["keypoints"] = {"format": fmt, "why": data.format.reason, "matching": how,
                                   "frames": int(len(data.frames)), "height_m": height, "height_from": height_from}
            if obs is not None:
                pts = r.points[:: max(1, len(r.points) // 200)]
                for cam in r.rig:
                    obs.report("rays", origins=np.broadcast_to(cam.center, pts.shape).copy(), ends=pts,
                               name=f"calibration/people/rays/{cam.name}")
        write_calibration(args.out, r.rig, metadata={"kind": f"extrinsics from {r.method}", "error": float(
            np.mean([v["rms_px"] for v in r.reprojection.values()])), "warnings": len(r.warnings)})
        report.update({"method": r.method, "reprojection": r.reprojection, "warnings": r.warnings,
                       "details": {k: v for k, v in r.details.items() if k not in ("board_poses", "keypoints3d")},
                       "centres_m": {c.name: c.center.tolist() for c in r.rig}})
        atomic_write_text(_report_paths(args.out)[0], json.dumps(report, indent=1, default=str))
        for name, v in r.reprojection.items():
            c = r.rig[name].center
            print(f"{name}: {v['n']} observations, median {v['median_px']:.2f} px, RMS {v['rms_px']:.2f} px, "
                  f"centre ({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f}) m")
        for w in r.warnings:
            print(f"warning: {w}")
        print(f"wrote {args.out}")
    finally:
        if obs is not None:
            obs.close()
    return 0


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        return run_intrinsics(args) if args.command == "intrinsics" else run_extrinsics(args)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
