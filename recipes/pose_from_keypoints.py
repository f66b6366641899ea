#!/usr/bin/env python3
"""Triangulate 2D keypoints of any detector with per-view offset correction.

Usage::

    python recipes/pose_from_keypoints.py --calibration Calib.toml --keypoints pose-associated \\
        --out out/keypoints [--format auto] [--max-frames N] [--videos videos]
    python recipes/pose_from_keypoints.py --keypoints Session/Participant/Trial --out out/trial \\
        [--filter-cutoff 6] [--config options.toml]

``--keypoints`` holds per camera a sub-folder of JSON files (one per frame:
OpenPose, or MMPose per image) or one JSON file (MMPose video predictions, COCO
results or annotations); see docs/keypoint_formats.md.  A Pose2Sim trial folder
is read as it is: its ``pose-associated/`` (else ``pose/``) keypoints, the
session's ``Calib*.toml`` (unless ``--calibration``), ``pose_model`` and
``frame_rate`` from its ``Config.toml`` files.  Cameras are matched to the
calibration's by name (``cam01_json`` is ``cam_01``), else by the numbers in the
names, else by sorted order; the keypoint format is found from the files
(``--format auto``) or checked against the one given.  Frames missing in a camera
are marked missing, files without people are empty frames; bad files raise an
error naming them.  Keypoints are mapped to the 14-joint skeleton, joints
below ``--min-confidence`` are dropped, and the sequence is triangulated by
``toolkit.multiview.keypoint_sequence`` (docs/stage1_multiview.md, "Keypoints"):
the detector's left/right labels are kept unless flipping a view's joints
explains the rays decisively better (never every view: that is the mirror of
the labels); one 2D offset per camera is estimated over the whole sequence and
kept only when offsets fitted on half of the joints lower the reprojection
error of the other half (a calibration error does, a detector's bias does not);
per-frame offsets with ``--offsets frame``.  Every frame is checked against the
anthropometric constraints (reported, not enforced).

Writes into ``--out``:

* ``poses3d.npz``: ``joints`` (T, 14, 3) metres in the calibration's world frame
  (NaN = no estimate), ``names`` (14,), ``frames`` (T,) frame numbers,
  ``success`` (T,), ``cost`` (T,) mean ray distance in metres,
  ``violations`` (T,) number of broken anthropometric constraints, ``frame_rate``
  (Hz); with ``--filter-cutoff`` also ``joints_filtered`` (T, 14, 3) and ``filter``;
* ``offsets.npz``: ``offsets`` (T, n_cams, 2) pixels, ``camera_names``, ``mode``
  (the offsets used: sequence, frame or none), ``sequence_offsets`` (n_cams, 2)
  (estimated, also when rejected) and ``reason`` (why they were kept or rejected);
* ``flips.npz``: ``flips`` (T, n_cams) the left/right flip applied per frame and
  camera ("" = the detector's labels), ``camera_names``, ``frames``;
* ``poses2d.npz``: per camera ``<camera>`` (T, 14, 2) offset-corrected joints
  and ``<camera>_raw`` (T, 14, 2) as detected (flips applied);
* ``poses3d.trc``, ``poses3d.c3d``, ``poses3d.csv`` (``--export``): the joints under
  Pose2Sim's marker names (TRC: Y up, metres, Pose2Sim's header; C3D: millimetres,
  the TRC's axes; CSV: metres, world frame), see toolkit/io/trajectories.py; with
  ``--filter-cutoff`` also ``poses3d_filt_butterworth.*``, low-pass filtered
  (zero-phase Butterworth, the cut-off in the C3D / CSV metadata);
* ``poses3d.json``: frame rate (and where it came from), keypoint format (and why),
  camera matching, filter, files;
* ``anthropometry.txt``: the broken constraints of every frame;
* ``recording.rrd``: rerun recording of the rig, images (with ``--videos``),
  keypoints, rays, closest points, 3D joints, offsets and costs.

Without ``--multi-person`` the person triangulated is the one most cameras agree on
(toolkit.multiview.tracking.main_person: a bystander more confidently detected in one view is
not it).  With ``--multi-person`` every person found (detections grouped across views by
ray distance, tracked over time; a bystander seen by one camera only, or outside the
capture volume, is not a person; docs/multi_person.md) gets ``OUT/person_<k>/`` with the
files above, ``OUT/people.json`` lists them, and ``OUT/recording.rrd`` holds them all, each
under ``person_<k>/`` in its own colour.

``OUT/run.json`` records the inputs (by content) and options of the run: a folder of
another run is refused (``--replace-stale`` moves it aside); the same run again
replaces its results.  Results are written at the end, also after an error or
Ctrl-C (frames not processed are NaN), but never over the results of a complete run.  Options may also come from a TOML file (--config; the keys of
toolkit.pipeline.pose_from_keypoints.PoseFromKeypointsConfig, e.g. ``export = ["csv"]``,
``flips = []``; flags given on the command line win).  ``poses3d.json`` records them
under ``run``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from toolkit.errors import InputError
from toolkit.multiview import FLIP_MODES, MAX_OFFSET_PX, MIN_JOINT_CONFIDENCE, MIN_VIEW_CONFIDENCE
from toolkit.multiview.keypoint_sequence import OFFSET_MODES
from toolkit.pipeline.pose_from_keypoints import (ASSUMED_FPS, FORMATS, PoseFromKeypointsConfig, run,
                                                  summary_lines)
from toolkit.pipeline.run import load_config


def parser() -> argparse.ArgumentParser:
    """The recipe's command line (defaults of valued options: None, so a --config file's values stand)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--calibration", type=Path, default=None,
                    help="calibration file (.toml or .yaml); default: a Pose2Sim session's Calib*.toml")
    ap.add_argument("--keypoints", type=Path, required=True,
                    help="folder with one sub-folder of JSON files (or one JSON file) per camera, "
                         "or a Pose2Sim trial folder")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--config", type=Path, default=None, help="options from a TOML file (flags given here win)")
    ap.add_argument("--format", choices=sorted(FORMATS), default=None,
                    help="keypoint format (default auto: from the files, or a Pose2Sim Config.toml's pose_model)")
    ap.add_argument("--fps", type=float, default=None,
                    help="frame rate of the keypoints (default: Pose2Sim Config.toml, else the videos, "
                         f"else {ASSUMED_FPS:g}, said so in poses3d.json)")
    ap.add_argument("--export", default=None,
                    help="trajectory files besides poses3d.npz, comma-separated among trc,c3d,csv, or 'none' "
                         "(default trc,c3d,csv)")
    ap.add_argument("--filter-cutoff", type=float, default=None,
                    help="also write low-pass filtered trajectories (zero-phase Butterworth) with this cut-off, Hz")
    ap.add_argument("--filter-order", type=int, default=None,
                    help="order of the zero-phase Butterworth filter, even (default 4, as Pose2Sim)")
    ap.add_argument("--max-frames", type=int, default=None, help="process only the first N frames")
    ap.add_argument("--videos", type=Path, default=None,
                    help="folder of one video per camera (sorted like the cameras): frames go into the recording")
    ap.add_argument("--min-confidence", type=float, default=None,
                    help=f"drop joints below this confidence (default {MIN_JOINT_CONFIDENCE})")
    ap.add_argument("--min-view-confidence", type=float, default=None,
                    help=f"drop a view whose mean confidence is below this (default {MIN_VIEW_CONFIDENCE})")
    ap.add_argument("--flips", default=None,
                    help=f"left/right flips tested per view and frame, comma-separated among {','.join(FLIP_MODES)}, "
                         "or 'none'; a flip is applied only when it explains the rays decisively better than the "
                         f"detector's labels, and never to every view (default {','.join(FLIP_MODES)})")
    ap.add_argument("--offsets", choices=OFFSET_MODES, default=None,
                    help="per-camera 2D offsets: one per camera over the sequence, kept only when they generalise "
                         "across joints (default); per frame (the silhouette stage's); or none")
    ap.add_argument("--no-offsets", action="store_true", help="same as --offsets none")
    ap.add_argument("--max-offset-px", type=float, default=None,
                    help=f"bound on each offset component in pixels (default {MAX_OFFSET_PX:g})")
    ap.add_argument("--no-robust", action="store_true", help="keep views and rays whose rays disagree")
    ap.add_argument("--no-ground-check", action="store_true",
                    help="skip the ground rule of the anthropometric check (world frame not z-up at ground 0)")
    ap.add_argument("--multi-person", action="store_true",
                    help="every person found (detections associated across views by ray distance and tracked "
                         "over time; a bystander seen by one camera only is not a person) goes to "
                         "OUT/person_<k>/ with the files below; OUT/people.json lists them and OUT/recording.rrd "
                         "shows each in its own colour (default: the person most cameras agree on)")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--replace-stale", action="store_true",
                    help="move an --out folder of another run (other inputs or options) aside instead of refusing it")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    return ap


def _names(text: str | None) -> tuple | None:
    """A comma-separated list flag as a tuple ('none': empty; not given: None)."""
    if text is None:
        return None
    return () if text.strip() == "none" else tuple(e.strip() for e in text.split(",") if e.strip())


def config_from_args(args: argparse.Namespace) -> PoseFromKeypointsConfig:
    """The run's config: the --config file (or the defaults), then the flags given."""
    config = load_config(PoseFromKeypointsConfig, args.config, calibration=args.calibration, format=args.format,
                         fps=args.fps, export=_names(args.export), filter_cutoff=args.filter_cutoff,
                         filter_order=args.filter_order, max_frames=args.max_frames, videos=args.videos,
                         min_confidence=args.min_confidence, min_view_confidence=args.min_view_confidence,
                         flips=_names(args.flips), offsets="none" if args.no_offsets else args.offsets,
                         max_offset_px=args.max_offset_px)
    return replace(config, robust=config.robust and not args.no_robust,
                   check_ground=config.check_ground and not args.no_ground_check,
                   multi_person=config.multi_person or args.multi_person,
                   recording=config.recording and not args.no_recording, replace_stale=config.replace_stale
                   or args.replace_stale, progress=config.progress and not args.quiet)


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    try:
        result = run(config_from_args(args), dataset=args.keypoints, out=args.out)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print("\n".join(summary_lines(result)))
    return 130 if result.stopped else 0


if __name__ == "__main__":
    sys.exit(main())
