#!/usr/bin/env python3
"""Turn a Pose2Sim trial into the project's dataset layout.

Usage::

    python recipes/import_pose2sim.py TRIAL --out DATASET [--calibration TOML] \\
        [--pose pose|pose-associated] [--copy] [--overwrite]

``TRIAL`` is a Pose2Sim trial folder (``videos/``, ``pose/`` and/or
``pose-associated/``); the calibration is the session's
``S00_Calibration/Calib*.toml`` unless ``--calibration`` names one.  Writes
``DATASET/calibration.toml``, ``DATASET/videos/<camera>.mp4``,
``DATASET/keypoints/<camera>/`` (the per-frame OpenPose JSON files as they are)
and ``DATASET/import.json`` (what was found and done), linking to the trial's
files unless ``--copy``.  Cameras keep the calibration's names; videos and
keypoint folders are matched to them by name (``cam01.mp4``, ``cam01_json`` are
``cam_01``), else by number, else by order.  Size, frame-count and frame-rate
mismatches are handled as toolkit/io/pose2sim_import.py says and printed;
see docs/dataset_layout.md, "Importing a Pose2Sim trial".
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from toolkit.errors import InputError
from toolkit.io.pose2sim import POSE_FOLDERS
from toolkit.io.pose2sim_import import IMPORT_JSON, import_pose2sim_trial


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("trial", type=Path, help="Pose2Sim trial folder")
    p.add_argument("--out", type=Path, required=True, help="dataset folder to write")
    p.add_argument("--calibration", type=Path, help="calibration file (default: the session's Calib*.toml)")
    p.add_argument("--pose", choices=POSE_FOLDERS, help="keypoint folder (default: pose-associated, else pose)")
    p.add_argument("--copy", action="store_true", help="copy the videos and keypoints instead of linking")
    p.add_argument("--overwrite", action="store_true", help="write into a non-empty --out")
    return p.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        result = import_pose2sim_trial(args.trial, args.out, calibration=args.calibration, pose=args.pose,
                                       copy=args.copy, overwrite=args.overwrite)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    for line in result.messages:
        print(line)
    rep = result.report
    print(f"{len(result.rig)} cameras {result.rig.names}, {result.n_frames} frames at {rep['fps']:g} fps, "
          f"keypoints from {rep['keypoints']} ({rep['pose_model'] or 'format not stated'}), files {rep['files']}")
    print(f"wrote {result.out} (report: {result.out / IMPORT_JSON})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
