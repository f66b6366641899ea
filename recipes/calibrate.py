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

Options may also come from a TOML file (``--config``; the keys of
toolkit.pipeline.calibrate.IntrinsicsRunConfig or ExtrinsicsRunConfig, the board in a
``[board]`` table: ``kind``, ``corners = [4, 7]``, ``square_mm``, ``marker_mm``,
``dictionary``, ``every_s``, ``max_frames``; unknown keys are refused; flags given on the
command line win).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from toolkit.errors import InputError
from toolkit.pipeline.calibrate import (BOARD_KINDS, ExtrinsicsRunConfig, IntrinsicsRunConfig, parse_corners,
                                        run_extrinsics, run_intrinsics)
from toolkit.pipeline.run import load_config


def _board_args(ap, required: bool) -> None:
    ap.add_argument("--board", choices=BOARD_KINDS, default=None,
                    help="board kind" + (" (required unless --board-toml)" if required else ""))
    ap.add_argument("--corners", default=None, help="inner corners ROWS,COLS (squares minus one), e.g. 4,7")
    ap.add_argument("--square-mm", type=float, default=None, help="side of a square, millimetres")
    ap.add_argument("--marker-mm", type=float, default=None, help="ChArUco: side of a marker, millimetres")
    ap.add_argument("--dictionary", default=None, help="ChArUco: ArUco dictionary (default DICT_4X4_50)")
    ap.add_argument("--board-toml", type=Path, default=None, help="board geometry from a TOML file instead")
    ap.add_argument("--every-s", type=float, default=None, help="videos: seconds between frames used (default 1)")
    ap.add_argument("--max-frames", type=int, default=None, help="at most this many frames per camera (default 200)")
    ap.add_argument("--config", type=Path, default=None, help="options from a TOML file (flags given here win)")
    ap.add_argument("--no-recording", action="store_true", help="do not write <out>.rrd")


def parser() -> argparse.ArgumentParser:
    """The recipe's command line (defaults of valued options: None, so a --config file's values stand)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    sub = ap.add_subparsers(dest="command", required=True)
    a = sub.add_parser("intrinsics", help="intrinsics from images or videos of a board",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    a.add_argument("images", type=Path, help="folder: a sub-folder (or a video) per camera, or one camera's images")
    _board_args(a, True)
    a.add_argument("--out", type=Path, required=True, help="intrinsics TOML (Pose2Sim / anipose layout)")
    e = sub.add_parser("extrinsics", help="camera poses from a board, scene points or people")
    e.add_argument("--intrinsics", type=Path, required=True, help="intrinsics TOML (from the intrinsics command)")
    src = e.add_mutually_exclusive_group(required=True)
    src.add_argument("--board-images", type=Path, help="a sub-folder of synchronised board images per camera")
    src.add_argument("--scene-points", type=Path, help="TOML or CSV of 3D points and their pixels per camera")
    src.add_argument("--keypoints", type=Path, help="keypoints folder (a sub-folder or JSON per camera) or a "
                                                    "Pose2Sim trial")
    _board_args(e, False)
    e.add_argument("--format", default=None, help="keypoint format (default auto: found from the files)")
    e.add_argument("--height-m", type=float, default=None,
                   help="the person's stature, metres (the scale); default: a Pose2Sim trial's participant_height, "
                        "else a median adult with a warning")
    e.add_argument("--min-confidence", type=float, default=None, help="keypoints below this are not used (default 0.3)")
    e.add_argument("--seed", type=int, default=None, help="RANSAC seed (default 0)")
    e.add_argument("--out", type=Path, required=True, help="calibration TOML (Pose2Sim / anipose layout)")
    return ap


def config_from_args(args: argparse.Namespace) -> IntrinsicsRunConfig | ExtrinsicsRunConfig:
    """The command's config: the --config file (or the defaults), then the flags given."""
    if args.command == "intrinsics":
        config = load_config(IntrinsicsRunConfig, args.config)
    else:
        config = load_config(ExtrinsicsRunConfig, args.config, format=args.format, height_m=args.height_m,
                             min_confidence=args.min_confidence, seed=args.seed)
    board = {"kind": args.board, "corners": parse_corners(args.corners), "square_mm": args.square_mm,
             "marker_mm": args.marker_mm, "dictionary": args.dictionary, "toml": args.board_toml,
             "every_s": args.every_s, "max_frames": args.max_frames}
    board = replace(config.board, **{k: v for k, v in board.items() if v is not None})
    return replace(config, board=board, recording=config.recording and not args.no_recording)


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    try:
        config = config_from_args(args)
        if args.command == "intrinsics":
            run_intrinsics(config, images=args.images, out=args.out)
        else:
            run_extrinsics(config, intrinsics=args.intrinsics, out=args.out, board_images=args.board_images,
                           scene_points=args.scene_points, keypoints=args.keypoints)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
