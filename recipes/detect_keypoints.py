#!/usr/bin/env python3
"""Detect people's 2D keypoints in a rig's videos, offline, and optionally synchronise the cameras.

Usage::

    python recipes/detect_keypoints.py VIDEOS_OR_TRIAL --out KP_DIR [--sync] [--max-frames N]
        [--detector mediapipe|rtmlib] [--num-poses 6] [--workers N] [--config options.toml]

``VIDEOS_OR_TRIAL`` is a folder of videos, a trial folder holding ``videos/`` (Pose2Sim's layout), or
one video.  Each camera is named after its video's stem (``cam01.mp4`` is camera ``cam01``).

Writes into ``KP_DIR``:

* ``<camera>/<camera>_<frame:012d>_keypoints.json``: OpenPose JSON, every person found in the frame,
  frames numbered from 0, in the detector's keypoint layout (default ``blazepose_33``: BlazePose's
  33 keypoints, docs/detection.md lists them); every keypoint reader of the toolkit takes the folder
  as it is (``pose_from_keypoints.py --keypoints KP_DIR``);
* ``detection.json``: layout and keypoint names, model, options, per camera its video, frame rate,
  size, frames and people per frame, warnings (cameras at different frame rates, nobody found);
* ``sync.json`` (``--sync``): ``{"offsets": {camera: frames started late}, "peaks": ..., "curves": ...}``
  from where the cameras' rays meet (with ``--calibration``) or else from the correlation of the
  people's motion between cameras; ``pose_from_keypoints.py`` applies it.

The detector runs offline from the model files of the installed ``mediapipe`` wheel (BlazePose full,
several people per image); ``--detector rtmlib --det-model X.onnx --pose-model Y.onnx`` runs RTMPose
from model files you have.  Frames are written as they are done: a rerun with the same options does
only what is missing; a rerun with other options into the same folder is refused.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from toolkit.errors import InputError
from toolkit.pipeline.detect_keypoints import DetectConfig, detect_videos, summary_lines
from toolkit.pipeline.run import load_config


def parser() -> argparse.ArgumentParser:
    """The recipe's command line (valued options default to None so a --config file's values stand)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("source", type=Path, help="a folder of videos, a trial folder with videos/, or a video")
    ap.add_argument("--out", type=Path, required=True, help="keypoint folder to write")
    ap.add_argument("--config", type=Path, default=None, help="options from a TOML file (flags given here win)")
    ap.add_argument("--detector", default=None, help="backend: mediapipe (default) or rtmlib")
    ap.add_argument("--num-poses", type=int, default=None, help="most people per image (default 6)")
    ap.add_argument("--min-detection-confidence", type=float, default=None,
                    help="person detector threshold in [0, 1] (default 0.5)")
    ap.add_argument("--det-model", type=Path, default=None, help="rtmlib: the person detector's ONNX file")
    ap.add_argument("--pose-model", type=Path, default=None, help="rtmlib: the pose model's ONNX file")
    ap.add_argument("--layout", default=None, help="rtmlib: the pose model's keypoints (halpe_26, coco_17, coco_133)")
    ap.add_argument("--max-frames", type=int, default=None, help="only the first N frames of each video")
    ap.add_argument("--workers", type=int, default=None,
                    help="processes, one camera each (default: one per camera up to the machine's cores)")
    ap.add_argument("--sync", action="store_true", help="find each camera's frame offset (sync.json)")
    ap.add_argument("--calibration", type=Path, default=None,
                    help="the rig's calibration (.toml, .yaml, .qca.txt): --sync by where the rays meet (sharper) "
                         "instead of by the correlation of motion")
    ap.add_argument("--max-sync-offset", type=int, default=None, help="largest offset searched, frames (default 60)")
    ap.add_argument("--quiet", action="store_true", help="no progress lines")
    return ap


def config_from_args(args: argparse.Namespace) -> DetectConfig:
    """The run's config: the --config file (or the defaults), then the flags given."""
    config = load_config(DetectConfig, args.config, detector=args.detector, num_poses=args.num_poses,
                         min_detection_confidence=args.min_detection_confidence, det_model=args.det_model,
                         pose_model=args.pose_model, layout=args.layout, max_frames=args.max_frames,
                         workers=args.workers, max_sync_offset=args.max_sync_offset,
                         calibration=args.calibration)
    from dataclasses import replace

    return replace(config, sync=config.sync or args.sync, progress=config.progress and not args.quiet)


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    try:
        result = detect_videos(args.source, args.out, config_from_args(args))
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"interrupted: the frames done are kept in {args.out}; run again to finish", file=sys.stderr)
        return 130
    print("\n".join(summary_lines(result)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
