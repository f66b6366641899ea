#!/usr/bin/env python3
"""Turn a Pose2Sim trial into the project's dataset layout, detecting its keypoints when it has none.

Usage::

    python recipes/import_pose2sim.py TRIAL --out DATASET [--calibration FILE] \\
        [--pose pose|pose-associated] [--copy] [--overwrite]
    python recipes/import_pose2sim.py VIDEOS_ONLY_TRIAL --out DATASET [--sync] [--max-frames N] \\
        [--detector mediapipe|rtmlib] [--num-poses 6] [--workers N]

``TRIAL`` is a Pose2Sim trial folder (``videos/``, ``pose/`` and/or
``pose-associated/``); the calibration is the session's
``S00_Calibration/Calib*.toml`` (or the trial's ``calibration/`` folder: a
``.toml`` or Qualisys ``.qca.txt``) unless ``--calibration`` names one.  Writes
``DATASET/calibration.toml``, ``DATASET/videos/<camera>.mp4``,
``DATASET/keypoints/<camera>/`` (the per-frame OpenPose JSON files as they are)
and ``DATASET/import.json`` (what was found and done), linking to the trial's
files unless ``--copy``.  Cameras keep the calibration's names; videos and
keypoint folders are matched to them by name (``cam01.mp4``, ``cam01_json`` are
``cam_01``), else by number, else by order.  Size, frame-count and frame-rate
mismatches are handled as toolkit/io/pose2sim_import.py says and printed;
see docs/dataset_layout.md, "Importing a Pose2Sim trial".

A trial with ``videos/`` and a calibration but no keypoints (Pose2Sim's current
demos) has its people detected first by the built-in detector
(docs/detection.md) into ``DATASET/detection/`` (kept: a rerun with
``--overwrite`` does only the frames missing), and ``keypoints/<camera>/``
links to those files; ``import.json`` says so under ``detection``.  With
``--sync`` the cameras' late starts are found (by where their rays meet) and
the dataset lined up: each camera that started early loses its first frames
(video re-encoded, keypoint files renumbered) so that every camera's frame 0
shows the same instant; the shifts are printed and kept in ``import.json``
(``frame_offsets``, and per camera ``frames_dropped_at_start``).
``--max-frames N`` detects only the first N frames (the dataset then holds N).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from toolkit.errors import InputError
from toolkit.io.pose2sim import POSE_FOLDERS
from toolkit.pipeline.detect_keypoints import DetectConfig
from toolkit.pipeline.run import load_config
from toolkit.pipeline.trial_input import import_lines, import_trial


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("trial", type=Path, help="Pose2Sim trial folder")
    p.add_argument("--out", type=Path, required=True, help="dataset folder to write")
    p.add_argument("--calibration", type=Path, help="calibration file (default: the session's Calib*.toml)")
    p.add_argument("--pose", choices=POSE_FOLDERS, help="keypoint folder (default: pose-associated, else pose)")
    p.add_argument("--copy", action="store_true", help="copy the videos and keypoints instead of linking")
    p.add_argument("--overwrite", action="store_true", help="write into a non-empty --out")
    g = p.add_argument_group("detection (a trial with videos and no keypoints)")
    g.add_argument("--detector", default=None, help="backend: mediapipe (default) or rtmlib")
    g.add_argument("--num-poses", type=int, default=None, help="most people per image (default 6)")
    g.add_argument("--max-frames", type=int, default=None, help="only the first N frames of each video")
    g.add_argument("--workers", type=int, default=None, help="processes, one camera each (default: one per camera)")
    g.add_argument("--sync", action="store_true",
                   help="find each camera's late start and line the cameras up in the dataset")
    g.add_argument("--quiet", action="store_true", help="no progress lines")
    return p.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        detect = load_config(DetectConfig, None, detector=args.detector, num_poses=args.num_poses,
                             max_frames=args.max_frames, workers=args.workers, sync=args.sync or None,
                             progress=False if args.quiet else None)
        result = import_trial(args.trial, args.out, calibration=args.calibration, pose=args.pose, copy=args.copy,
                              overwrite=args.overwrite, detect_config=detect)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print("\n".join(import_lines(result)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
