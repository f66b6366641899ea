#!/usr/bin/env python3
"""Triangulate 2D keypoints of any detector with per-view offset correction.

Usage::

    python recipes/pose_from_keypoints.py --calibration Calib.toml --keypoints pose-associated \\
        --out out/keypoints [--format body_25b] [--max-frames N] [--videos videos]

``--keypoints`` holds one sub-folder of OpenPose JSON files per camera (one file
per frame); the sub-folders, sorted by name, are matched to the calibration's
cameras sorted by name.  Keypoints are mapped to the 14-joint skeleton, joints
below ``--min-confidence`` are dropped, and every frame is triangulated with
the multi-view stage of source 000 §2.1 (one candidate per view plus its
left/right flips, per-view 2D offsets by Levenberg-Marquardt, the previous
frame's offsets as the starting point), then checked against the
anthropometric constraints (reported, not enforced).

Writes into ``--out``:

* ``poses3d.npz``: ``joints`` (T, 14, 3) metres in the calibration's world frame
  (NaN = no estimate), ``names`` (14,), ``frames`` (T,) frame numbers,
  ``success`` (T,), ``cost`` (T,) mean ray distance in metres,
  ``violations`` (T,) number of broken anthropometric constraints;
* ``offsets.npz``: ``offsets`` (T, n_cams, 2) pixels, ``camera_names``;
* ``poses2d.npz``: per camera ``<camera>`` (T, 14, 2) offset-corrected joints
  and ``<camera>_raw`` (T, 14, 2) as detected (flips applied);
* ``anthropometry.txt``: the broken constraints of every frame;
* ``recording.rrd``: rerun recording of the rig, images (with ``--videos``),
  keypoints, rays, closest points, 3D joints, offsets and costs.

Results are written at the end, also after an error or Ctrl-C (frames not
processed are NaN).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from toolkit.errors import InputError  # noqa: E402

#: --format names accepted, mapped to the names of toolkit.skeleton.mappings.
FORMATS = {"body_25b": "body_25b", "body_25": "body_25", "coco17": "coco_17", "coco_17": "coco_17"}
#: Video file suffixes looked for in --videos.
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv")


def parse_args(argv=None):
    from toolkit.multiview import FLIP_MODES, MAX_OFFSET_PX, MIN_JOINT_CONFIDENCE, MIN_VIEW_CONFIDENCE

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--calibration", type=Path, required=True, help="calibration file (.toml or .yaml)")
    ap.add_argument("--keypoints", type=Path, required=True,
                    help="folder with one sub-folder of OpenPose JSON files per camera")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--format", choices=sorted(FORMATS), default="body_25b", help="keypoint format (default body_25b)")
    ap.add_argument("--max-frames", type=int, default=None, help="process only the first N frames")
    ap.add_argument("--videos", type=Path, default=None,
                    help="folder of one video per camera (sorted like the cameras): frames go into the recording")
    ap.add_argument("--min-confidence", type=float, default=MIN_JOINT_CONFIDENCE,
                    help=f"drop joints below this confidence (default {MIN_JOINT_CONFIDENCE})")
    ap.add_argument("--min-view-confidence", type=float, default=MIN_VIEW_CONFIDENCE,
                    help=f"drop a view whose mean confidence is below this (default {MIN_VIEW_CONFIDENCE})")
    ap.add_argument("--flips", default="all",
                    help=f"left/right flips tried per view, comma-separated among {','.join(FLIP_MODES)}, "
                         "or 'none' (default all)")
    ap.add_argument("--no-offsets", action="store_true", help="do not optimise per-view 2D offsets")
    ap.add_argument("--max-offset-px", type=float, default=MAX_OFFSET_PX,
                    help=f"bound on each offset component in pixels (default {MAX_OFFSET_PX:g})")
    ap.add_argument("--no-robust", action="store_true", help="keep views and rays whose rays disagree")
    ap.add_argument("--no-ground-check", action="store_true",
                    help="skip the ground rule of the anthropometric check (world frame not z-up at ground 0)")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)
    if args.max_frames is not None and args.max_frames < 1:
        ap.error("--max-frames must be >= 1")
    return args


def match_cameras(rig, folders, what: str):
    """Rig sorted by camera name, matched one-to-one with sorted folders or files."""
    from toolkit.cameras import Rig

    cams = sorted(rig, key=lambda c: c.name)
    if len(cams) != len(folders):
        raise InputError(what, f"{len(cams)} entries, one per calibration camera {[c.name for c in cams]}",
                         f"{len(folders)}: {[f.name for f in folders]}")
    return Rig(tuple(cams))


def run(args) -> int:
    import numpy as np
    from tqdm import tqdm

    from toolkit.anthropometry import AnthropometricConstraints
    from toolkit.io import VideoReader, atomic_save_npz, atomic_write_text, read_calibration
    from toolkit.io.openpose import camera_folders, read_openpose_cameras
    from toolkit.multiview import MultiViewConfig, MultiViewTracker, keypoints_to_candidates, stack_selections
    from toolkit.skeleton import SKELETON_14
    from toolkit.skeleton.mappings import KEYPOINTS, to_skeleton14

    fmt = FORMATS[args.format]
    flips = () if args.flips.strip() == "none" else tuple(f.strip() for f in args.flips.split(",") if f.strip())
    rig = read_calibration(args.calibration)
    folders = camera_folders(args.keypoints)
    rig = match_cameras(rig, folders, f"{args.keypoints}: camera sub-folders")
    videos = None
    if args.videos is not None:
        if not args.videos.is_dir():
            raise InputError(str(args.videos), "a folder of videos", "no such folder")
        files = sorted(p for p in args.videos.iterdir() if p.suffix.lower() in VIDEO_SUFFIXES)
        match_cameras(rig, files, f"{args.videos}: video files")
        videos = [VideoReader(p) for p in files]
    _, frame_numbers, kp = read_openpose_cameras(args.keypoints, len(KEYPOINTS[fmt]), max_frames=args.max_frames)
    # keypoints below the threshold are missing, so the mapping falls back to the next alternative
    kp14 = to_skeleton14(kp, fmt, confidence=True, min_confidence=args.min_confidence)  # (n_cams, T, 14, 3)
    n_cams, n_frames = kp14.shape[:2]
    constraints = AnthropometricConstraints(check_ground=not args.no_ground_check)
    config = MultiViewConfig(flips=flips, optimise_offsets=not args.no_offsets, robust=not args.no_robust,
                             max_offset_px=args.max_offset_px, constraints=constraints)
    args.out.mkdir(parents=True, exist_ok=True)
    observer = None
    if not args.no_recording:
        from toolkit.viz import RerunObserver
        observer = RerunObserver(application_id="pose_from_keypoints", path=args.out / "recording.rrd",
                                 camera_names=rig.names)
        observer.report("rig", rig=rig, static=True)
        observer.report("skeleton", skeleton=SKELETON_14)
    print(f"{n_cams} cameras ({', '.join(f'{c.name} <- {f.name}' for c, f in zip(rig, folders))}), "
          f"{n_frames} frames, format {fmt}")

    tracker = MultiViewTracker(rig, config, observer)
    selections = [None] * n_frames
    status, t0 = "complete", time.perf_counter()
    try:
        for t in tqdm(range(n_frames), desc="triangulating", unit="frame", disable=args.quiet):
            if videos is not None:
                for cam, vid in zip(rig, videos):
                    if int(frame_numbers[t]) < len(vid):
                        observer.report("image", camera=cam.name, image=vid.read(int(frame_numbers[t])), frame=t)
            cand, w = keypoints_to_candidates(kp14[:, t], args.min_confidence, args.min_view_confidence)
            sel = tracker.step(cand, w, frame=t)
            selections[t] = sel
            if observer is not None:
                observer.report("scalar", name="anthropometry/violations", value=len(sel.violations), frame=t)
    except KeyboardInterrupt:
        status = "interrupted"
    except BaseException:
        status = "failed"
        raise
    finally:
        done = sum(s is not None for s in selections)
        arrays = stack_selections(selections, n_cams)
        names = np.array(SKELETON_14.joint_names)
        violations = np.array([len(s.violations) if s is not None else -1 for s in selections])
        atomic_save_npz(args.out / "poses3d.npz", joints=arrays["joints"], names=names, frames=frame_numbers,
                        success=arrays["success"], cost=arrays["cost"], violations=violations)
        atomic_save_npz(args.out / "offsets.npz", offsets=arrays["offsets"], camera_names=np.array(rig.names))
        atomic_save_npz(args.out / "poses2d.npz", names=names,
                        **{c: arrays["poses2d"][i] for i, c in enumerate(rig.names)},
                        **{f"{c}_raw": arrays["poses2d_raw"][i] for i, c in enumerate(rig.names)})
        lines = [f"frame {int(frame_numbers[t])}: " + ("; ".join(s.violations) if s.violations else "ok")
                 for t, s in enumerate(selections) if s is not None]
        atomic_write_text(args.out / "anthropometry.txt", "\n".join(lines) + "\n")
        if observer is not None:
            observer.close()
        for v in videos or ():
            v.close()
        dt = time.perf_counter() - t0
        ok = arrays["success"]
        print(f"{status}: {done}/{n_frames} frames processed in {dt:.1f} s ({1000 * dt / max(done, 1):.0f} ms/frame), "
              f"{int(ok.sum())} with a 3D estimate")
        if ok.any():
            off = np.nanmean(np.linalg.norm(arrays["offsets"][ok], axis=-1), axis=0)
            print("  mean |offset| per camera (px): " + ", ".join(f"{c} {o:.1f}" for c, o in zip(rig.names, off)))
            print(f"  mean ray distance: {1000 * np.nanmean(arrays['cost'][ok]):.1f} mm; frames breaking an "
                  f"anthropometric constraint: {int(np.sum(violations > 0))}")
        print(f"  3D joints:     {args.out / 'poses3d.npz'}")
        print(f"  offsets:       {args.out / 'offsets.npz'}")
        print(f"  2D joints:     {args.out / 'poses2d.npz'}")
        print(f"  anthropometry: {args.out / 'anthropometry.txt'}")
        if observer is not None:
            print(f"  recording:     {args.out / 'recording.rrd'}   (open with: rerun {args.out / 'recording.rrd'})")
    return 130 if status == "interrupted" else 0


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        return run(args)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
