#!/usr/bin/env python3
"""Triangulate 2D keypoints of any detector with per-view offset correction.

Usage::

    python recipes/pose_from_keypoints.py --calibration Calib.toml --keypoints pose-associated \\
        --out out/keypoints [--format auto] [--max-frames N] [--videos videos]
    python recipes/pose_from_keypoints.py --keypoints Session/Participant/Trial --out out/trial \\
        [--filter-cutoff 6]

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

Results are written at the end, also after an error or Ctrl-C (frames not
processed are NaN).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from toolkit.errors import InputError

#: --format names accepted, mapped to the names of toolkit.skeleton.mappings ("auto": found from the files).
FORMATS = {"auto": None, "body_25b": "body_25b", "body_25": "body_25", "coco17": "coco_17", "coco_17": "coco_17",
           "coco_18": "coco_18", "coco": "coco_18", "halpe_26": "halpe_26", "coco_133": "coco_133",
           "blazepose_33": "blazepose_33"}
#: Frame rate assumed when neither --fps, a Pose2Sim Config.toml nor --videos gives one (said so in the outputs).
ASSUMED_FPS = 30.0
#: Video file suffixes looked for in --videos.
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv")


def parse_args(argv=None):
    from toolkit.multiview import FLIP_MODES, MAX_OFFSET_PX, MIN_JOINT_CONFIDENCE, MIN_VIEW_CONFIDENCE
    from toolkit.multiview.keypoint_sequence import OFFSET_MODES

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--calibration", type=Path, default=None,
                    help="calibration file (.toml or .yaml); default: a Pose2Sim session's Calib*.toml")
    ap.add_argument("--keypoints", type=Path, required=True,
                    help="folder with one sub-folder of JSON files (or one JSON file) per camera, "
                         "or a Pose2Sim trial folder")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--format", choices=sorted(FORMATS), default="auto",
                    help="keypoint format (default auto: from the files, or a Pose2Sim Config.toml's pose_model)")
    ap.add_argument("--fps", type=float, default=None,
                    help="frame rate of the keypoints (default: Pose2Sim Config.toml, else the videos, "
                         f"else {ASSUMED_FPS:g}, said so in poses3d.json)")
    ap.add_argument("--export", default="trc,c3d,csv",
                    help="trajectory files besides poses3d.npz, comma-separated among trc,c3d,csv, or 'none'")
    ap.add_argument("--filter-cutoff", type=float, default=None,
                    help="also write low-pass filtered trajectories (zero-phase Butterworth) with this cut-off, Hz")
    ap.add_argument("--filter-order", type=int, default=4,
                    help="order of the zero-phase Butterworth filter, even (default 4, as Pose2Sim)")
    ap.add_argument("--max-frames", type=int, default=None, help="process only the first N frames")
    ap.add_argument("--videos", type=Path, default=None,
                    help="folder of one video per camera (sorted like the cameras): frames go into the recording")
    ap.add_argument("--min-confidence", type=float, default=MIN_JOINT_CONFIDENCE,
                    help=f"drop joints below this confidence (default {MIN_JOINT_CONFIDENCE})")
    ap.add_argument("--min-view-confidence", type=float, default=MIN_VIEW_CONFIDENCE,
                    help=f"drop a view whose mean confidence is below this (default {MIN_VIEW_CONFIDENCE})")
    ap.add_argument("--flips", default=",".join(FLIP_MODES),
                    help=f"left/right flips tested per view and frame, comma-separated among {','.join(FLIP_MODES)}, "
                         "or 'none'; a flip is applied only when it explains the rays decisively better than the "
                         f"detector's labels, and never to every view (default {','.join(FLIP_MODES)})")
    ap.add_argument("--offsets", choices=OFFSET_MODES, default="sequence",
                    help="per-camera 2D offsets: one per camera over the sequence, kept only when they generalise "
                         "across joints (default); per frame (the silhouette stage's); or none")
    ap.add_argument("--no-offsets", action="store_true", help="same as --offsets none")
    ap.add_argument("--max-offset-px", type=float, default=MAX_OFFSET_PX,
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
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)
    if args.max_frames is not None and args.max_frames < 1:
        ap.error("--max-frames must be >= 1")
    if args.fps is not None and not args.fps > 0:
        ap.error("--fps must be > 0")
    args.export = () if args.export.strip() == "none" else tuple(e.strip() for e in args.export.split(",") if e.strip())
    if any(e not in ("trc", "c3d", "csv") for e in args.export):
        ap.error(f"--export takes trc, c3d, csv or none, not {','.join(args.export)}")
    if args.filter_order < 2 or args.filter_order % 2:
        ap.error("--filter-order must be even and >= 2")
    return args


def match_videos(rig, files, what: str):
    """The video files in the order of the rig's cameras (by name, number or order)."""
    from toolkit.io.keypoint_files import match_cameras

    order, _ = match_cameras(rig.names, list(files), what)
    return [files[i] for i in order]


def run(args, session=None, observer=None) -> int:
    """Triangulate one person (``session``: given by :func:`run_people`, else read; ``observer``: a
    shared recording, else ``recording.rrd`` of its own)."""
    if args.multi_person and session is None:
        return run_people(args)
    import numpy as np
    from tqdm import tqdm

    from toolkit.anthropometry import AnthropometricConstraints
    from toolkit.io import VideoReader, atomic_save_npz, atomic_write_text
    from toolkit.pipeline.keypoint_session import open_keypoint_session
    from toolkit.io.trajectories import skeleton14_trajectories, write_trajectories
    from toolkit.filtering import ButterworthFilter
    from toolkit.multiview import MultiViewConfig, keypoints_to_candidates
    from toolkit.multiview.keypoint_sequence import KeypointConfig, triangulate_keypoint_sequence
    from toolkit.skeleton import SKELETON_14
    from toolkit.skeleton.mappings import to_skeleton14

    flips = () if args.flips.strip() == "none" else tuple(f.strip() for f in args.flips.split(",") if f.strip())
    session = session or open_keypoint_session(args.keypoints, args.calibration, FORMATS[args.format], args.fps,
                                    max_frames=args.max_frames)
    rig, sources, matched, keypoints = session.rig, session.sources, session.matching, session.keypoints
    videos = None
    if args.videos is not None:
        if not args.videos.is_dir():
            raise InputError(str(args.videos), "a folder of videos", "no such folder")
        files = sorted(p for p in args.videos.iterdir() if p.suffix.lower() in VIDEO_SUFFIXES)
        files = match_videos(rig, files, f"{args.videos}: video files")
        videos = [VideoReader(p) for p in files]
    fmt, frame_numbers, kp = keypoints.format.fmt, keypoints.frames, keypoints.keypoints
    fps, fps_from = session.fps, session.fps_from
    if fps is None and videos:
        fps, fps_from = float(videos[0].fps), f"video {videos[0].path.name}"
    if fps is None:
        fps, fps_from = ASSUMED_FPS, "assumed (give --fps)"
    lowpass = None
    if args.filter_cutoff is not None:
        lowpass = ButterworthFilter(args.filter_cutoff, args.filter_order)
        if not args.filter_cutoff < fps / 2:
            raise InputError("--filter-cutoff", f"a cut-off below half the frame rate ({fps / 2:g} Hz, {fps_from})",
                             f"{args.filter_cutoff:g}")
    # keypoints below the threshold are missing, so the mapping falls back to the next alternative
    kp14 = to_skeleton14(kp, fmt, confidence=True, min_confidence=args.min_confidence)  # (n_cams, T, 14, 3)
    n_cams, n_frames = kp14.shape[:2]
    constraints = AnthropometricConstraints(check_ground=not args.no_ground_check)
    config = KeypointConfig(flips=flips, offsets="none" if args.no_offsets else args.offsets,
                            multiview=MultiViewConfig(flips=(), robust=not args.no_robust,
                                                      max_offset_px=args.max_offset_px, constraints=constraints))
    args.out.mkdir(parents=True, exist_ok=True)
    own_observer = observer is None
    if own_observer and not args.no_recording:
        from toolkit.viz import RerunObserver
        observer = RerunObserver(application_id="pose_from_keypoints", path=args.out / "recording.rrd",
                                 camera_names=rig.names)
        observer.report("rig", rig=rig, static=True)
        observer.report("skeleton", skeleton=SKELETON_14)
    print(f"{n_cams} cameras matched {matched} ({', '.join(f'{c.name} <- {f.name}' for c, f in zip(rig, sources))}), "
          f"{n_frames} frames at {fps:g} fps ({fps_from}), format {fmt} ({keypoints.format.reason})")
    for c, cam in enumerate(rig):
        if keypoints.missing[c].any() or keypoints.empty[c].any():
            print(f"  {cam.name}: {int(keypoints.missing[c].sum())} frames without a file, "
                  f"{int(keypoints.empty[c].sum())} with nobody (marked missing)")

    status, t0 = "complete", time.perf_counter()
    nan = np.full((n_cams, n_frames, 14, 2), np.nan)
    arrays = {"joints": np.full((n_frames, 14, 3), np.nan), "success": np.zeros(n_frames, bool),
              "cost": np.full(n_frames, np.nan), "offsets": np.zeros((n_frames, n_cams, 2)), "poses2d": nan,
              "poses2d_raw": nan, "flips": np.full((n_frames, n_cams), "", dtype=object)}
    seq, viol = None, [()] * n_frames
    try:
        if videos is not None:
            for t in tqdm(range(n_frames), desc="video frames", unit="frame", disable=args.quiet):
                for cam, vid in zip(rig, videos):
                    if int(frame_numbers[t]) < len(vid):
                        observer.report("image", camera=cam.name, image=vid.read(int(frame_numbers[t])), frame=t)
        cand = [keypoints_to_candidates(kp14[:, t], args.min_confidence, args.min_view_confidence)
                for t in range(n_frames)]
        pts = np.stack([c[0][:, 0] for c in cand], axis=1)  # (n_cams, T, 14, 2)
        wts = np.stack([c[1][:, 0] for c in cand], axis=1)
        seq = triangulate_keypoint_sequence(pts, rig, config, weights=wts, observer=observer)
        arrays = {"joints": seq.joints3d, "success": seq.success, "cost": seq.cost, "offsets": seq.offsets,
                  "poses2d": seq.poses2d, "poses2d_raw": seq.poses2d_raw, "flips": seq.flips}
        viol = seq.violations
        if seq.interrupted:
            status = "interrupted"
        if observer is not None:
            for t in range(n_frames):
                observer.report("scalar", name="anthropometry/violations", value=len(viol[t]), frame=t)
    except KeyboardInterrupt:
        status = "interrupted"
    except BaseException:
        status = "failed"
        raise
    finally:
        done = int(np.sum(arrays["success"])) if seq is not None and seq.interrupted else (n_frames if seq is not None else 0)
        names = np.array(SKELETON_14.joint_names)
        violations = np.array([len(v) if seq is not None else -1 for v in viol])
        meta = {"source": "pose_from_keypoints", "keypoint_format": f"{fmt} ({keypoints.format.reason})",
                "frame_rate": f"{fps:g} Hz ({fps_from})", "status": status}
        extra = {}
        if lowpass is not None:
            extra = {"joints_filtered": lowpass.apply(arrays["joints"], fps), "filter": np.array(lowpass.describe())}
        atomic_save_npz(args.out / "poses3d.npz", joints=arrays["joints"], names=names, frames=frame_numbers,
                        success=arrays["success"], cost=arrays["cost"], violations=violations,
                        frame_rate=np.array(fps), **extra)
        exported = write_trajectories(args.out / "poses3d", skeleton14_trajectories(
            arrays["joints"], names, frame_numbers, fps, {**meta, "filter": "none"}), args.export)
        if lowpass is not None:
            exported += write_trajectories(args.out / "poses3d_filt_butterworth", skeleton14_trajectories(
                extra["joints_filtered"], names, frame_numbers, fps, {**meta, "filter": lowpass.describe()}),
                args.export)
        atomic_write_text(args.out / "poses3d.json", json.dumps({
            **meta, "frame_rate_hz": fps, "keypoints": str(session.keypoints_root),
            "calibration": str(session.calibration),
            "cameras": {c.name: str(f) for c, f in zip(rig, sources)}, "camera_matching": matched,
            "frames_without_file": {c.name: int(m) for c, m in zip(rig, keypoints.missing.sum(1))},
            "frames_with_nobody": {c.name: int(m) for c, m in zip(rig, keypoints.empty.sum(1))},
            "filter": lowpass.describe() if lowpass is not None else "none",
            "filter_cutoff_hz": lowpass.cutoff_hz if lowpass is not None else None,
            "filter_order": lowpass.order if lowpass is not None else None,
            "trajectory_axes": {"npz, csv": "world frame of the calibration (z up), metres",
                                "trc": "Y up: (X, Y, Z) = world (y, z, x), metres",
                                "c3d": "the TRC's axes, millimetres"},
            "files": [p.name for p in exported]}, indent=2) + "\n")
        decision = seq.offset_decision if seq is not None else None
        atomic_save_npz(args.out / "offsets.npz", offsets=arrays["offsets"], camera_names=np.array(rig.names),
                        mode=np.array(decision.mode if decision else "none"),
                        sequence_offsets=decision.offsets if decision else np.zeros((n_cams, 2)),
                        reason=np.array(decision.reason if decision else status))
        atomic_save_npz(args.out / "flips.npz", flips=arrays["flips"].astype(str), camera_names=np.array(rig.names),
                        frames=frame_numbers)
        atomic_save_npz(args.out / "poses2d.npz", names=names,
                        **{c: arrays["poses2d"][i] for i, c in enumerate(rig.names)},
                        **{f"{c}_raw": arrays["poses2d_raw"][i] for i, c in enumerate(rig.names)})
        lines = [f"frame {int(frame_numbers[t])}: " + ("; ".join(v) if v else "ok")
                 for t, v in enumerate(viol) if seq is not None]
        atomic_write_text(args.out / "anthropometry.txt", "\n".join(lines) + "\n")
        if observer is not None and own_observer:
            observer.close()
        for v in videos or ():
            v.close()
        dt = time.perf_counter() - t0
        ok = arrays["success"]
        print(f"{status}: {done}/{n_frames} frames processed in {dt:.1f} s ({1000 * dt / max(done, 1):.0f} ms/frame), "
              f"{int(ok.sum())} with a 3D estimate")
        if decision is not None:
            print(f"  offsets: {decision.mode} ({decision.reason})")
            flipped = (arrays["flips"] != "").sum(axis=0)
            print("  left/right flips applied (frames per camera): "
                  + ", ".join(f"{c} {int(n)}" for c, n in zip(rig.names, flipped)))
        if ok.any():
            off = np.nanmean(np.linalg.norm(arrays["offsets"][ok], axis=-1), axis=0)
            print("  mean |offset| per camera (px): " + ", ".join(f"{c} {o:.1f}" for c, o in zip(rig.names, off)))
            print(f"  mean ray distance: {1000 * np.nanmean(arrays['cost'][ok]):.1f} mm; frames breaking an "
                  f"anthropometric constraint: {int(np.sum(violations > 0))}")
        print(f"  3D joints:     {args.out / 'poses3d.npz'}")
        for p in exported:
            print(f"  trajectories:  {p}")
        print(f"  offsets:       {args.out / 'offsets.npz'}")
        print(f"  flips:         {args.out / 'flips.npz'}")
        print(f"  2D joints:     {args.out / 'poses2d.npz'}")
        print(f"  anthropometry: {args.out / 'anthropometry.txt'}")
        if observer is not None and own_observer:
            print(f"  recording:     {args.out / 'recording.rrd'}   (open with: rerun {args.out / 'recording.rrd'})")
    return 130 if status == "interrupted" else 0


def run_people(args) -> int:
    """``--multi-person``: every person found, each triangulated by :func:`run` on its own keypoints."""
    from dataclasses import replace

    import numpy as np

    from toolkit.io import atomic_write_text
    from toolkit.pipeline.keypoint_session import open_keypoint_session
    from toolkit.multiview.tracking import DEFAULT_FPS, TrackingConfig, frame_detections, track_people
    from toolkit.observe import PrefixedObserver
    from toolkit.skeleton import SKELETON_14

    session = open_keypoint_session(args.keypoints, args.calibration, FORMATS[args.format], args.fps,
                                    max_frames=args.max_frames)
    kin, rig = session.keypoints, session.rig
    detections = frame_detections(kin.cameras, kin.frames, kin.keypoints.shape[2])
    people = track_people(detections, rig, TrackingConfig(fps=args.fps or session.fps or DEFAULT_FPS))
    args.out.mkdir(parents=True, exist_ok=True)
    observer = None
    if not args.no_recording:
        from toolkit.viz import RerunObserver
        from toolkit.viz.style import SKELETON_COLORS
        observer = RerunObserver(application_id="pose_from_keypoints", path=args.out / "recording.rrd",
                                 camera_names=rig.names)
        observer.report("rig", rig=rig, static=True)
        observer.report("skeleton", skeleton=SKELETON_14)
    views = people.views
    print(f"{people.n_people} people found in {len(kin.frames)} frames (seen by two cameras or more, in the "
          "capture volume, tracked over time)")
    summary, code = [], 0
    try:
        for k in range(people.n_people):
            name = f"person_{k}"
            seen = views[k] > 0
            print(f"{name}: frames {int(kin.frames[seen][0])}-{int(kin.frames[seen][-1])} ({int(seen.sum())} frames), "
                  f"median {float(np.median(views[k][seen])):g} cameras")
            summary.append({"person": name, "frames": int(seen.sum()), "first_frame": int(kin.frames[seen][0]),
                            "last_frame": int(kin.frames[seen][-1]),
                            "cameras_per_frame_median": float(np.median(views[k][seen]))})
            one = replace(session, keypoints=replace(kin, keypoints=people.keypoints(detections, k)))
            sub = argparse.Namespace(**{**vars(args), "out": args.out / name, "multi_person": False,
                                        "videos": args.videos if k == 0 else None})
            obs = None if observer is None else PrefixedObserver(
                observer, name, SKELETON_COLORS[k % len(SKELETON_COLORS)])
            code = run(sub, session=one, observer=obs) or code
    finally:
        atomic_write_text(args.out / "people.json", json.dumps({
            "people": summary, "frames": len(kin.frames), "cameras": rig.names,
            "rule": "detections grouped across views by ray distance (toolkit.multiview.association), tracked "
                    "over time (toolkit.multiview.tracking); seen by two cameras or more, in the capture volume"},
            indent=2) + "\n")
        if observer is not None:
            observer.close()
            print(f"  recording:     {args.out / 'recording.rrd'}   (open with: rerun {args.out / 'recording.rrd'})")
    return code


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        return run(args)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
