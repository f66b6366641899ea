#!/usr/bin/env python3
"""Several people: per person MPJPE and identity switches on crowd scenes, and the Pose2Sim demo's raw detections.

Usage::

    python benchmarks/bench_multiperson.py                 # 4 seeds x 4 scenes x (0, 4) px, 30 frames
    python benchmarks/bench_multiperson.py --seeds 8 --frames 40 --no-demo

Why (issue 14 item 3): ``pose_from_keypoints --multi-person`` must find every
person of raw per-view detections (any number per view, bystanders, people
entering and leaving), keep each one's identity over time, and report no
bystander seen by one camera only.  Each seeded scene
(``toolkit.synthetic.crowd``: no rendering) puts two or three people in a ring
of three or four cameras, all but the first entering late and leaving early,
and one or two bystanders outside the volume each seen by exactly one camera (and a two-camera rig with two bystanders);
the detections get the detector noise of ``benchmarks/bench_keypoints.py``
(3 px per-joint bias, 1.5 px jitter at 200 px, 5 % missed joints, 3 % left/right
swaps) and 5 % occlusions (a person missing from a view).  People are
associated and tracked (``toolkit.multiview.tracking.track_people``) and each is
triangulated on its own keypoints (``triangulate_keypoint_sequence``, the
recipe's defaults); "oracle" triangulates the same way on the true
association (which detection shows whom), so MPJPE above it is the
association's.  Printed per scene and, per configuration, the median and
worst over seeds of: per person MPJPE (mm), identity switches, frames missed
(a person seen by two cameras with no estimate), false people (a bystander or
a ghost reported).

With the shared Pose2Sim demo (``../shared/realdata/pose2sim_demo``, skipped
when absent), the recipe runs with ``--multi-person`` on each trial's raw
``pose/`` folders (a bystander in the background of two views) and without it
on ``pose-associated/`` (Pose2Sim's own association): people found and the
median / largest distance between the two results.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
#: Scenes: (people, bystanders, cameras).
SCENES = ((2, 1, 3), (3, 2, 4), (3, 2, 3), (2, 2, 2))
ERRORS_PX = (0.0, 4.0)
TRIALS = ("S00_P00_T00_StaticTrial", "S00_P00_T01_BalancingTrial")


def run_scene(n_people: int, n_bystanders: int, n_cams: int, err: float, seed: int, frames: int) -> dict:
    from toolkit.multiview.keypoint_sequence import KeypointConfig, triangulate_keypoint_sequence
    from toolkit.multiview.tracking import TrackingConfig, person_keypoints, track_people
    from toolkit.synthetic.crowd import detect_crowd, make_crowd, score_people

    scene = make_crowd(n_people, n_bystanders, n_cams, frames, 25.0, err, rng=seed)
    det = detect_crowd(scene, rng=seed)
    t0 = time.perf_counter()
    tracks = track_people(det.detections, scene.measured_rig, TrackingConfig(fps=scene.fps))
    t_track = time.perf_counter() - t0

    def triangulate(assignments):
        est = []
        for a in assignments:
            kp = person_keypoints(det.detections, a, scene.joints.shape[2])
            w = np.where(kp[..., 2] >= 0.3, kp[..., 2], 0.0)
            xy = np.where((w > 0)[..., None], kp[..., :2], np.nan)
            est.append(triangulate_keypoint_sequence(xy, scene.measured_rig, KeypointConfig(), weights=w).joints3d)
        return np.array(est).reshape(-1, *scene.joints.shape[1:])

    s = score_people(triangulate(tracks.assignment), scene, det)
    t_total = time.perf_counter() - t0
    truth = [np.array([[int(np.flatnonzero(ids == p)[0]) if (ids == p).any() else -1 for ids in fr]
                       for fr in det.identity]) for p in scene.people]
    oracle = score_people(triangulate(truth), scene, det)
    return {"mpjpe": 1000 * s.mpjpe_m, "oracle": 1000 * oracle.mpjpe_m, "switches": s.switches, "missed": s.missed,
            "false": s.false_people, "found": tracks.n_people, "track_ms": 1000 * t_track / frames,
            "total_s": t_total, "counts": det.counts()}


def demo(root: Path, out: Path) -> None:
    from recipes import pose_from_keypoints as mod
    from toolkit.io.keypoint_files import read_camera_detections

    calib = root / "S00_Calibration" / "Calib_qualisys.toml"
    print("\nPose2Sim demo, raw pose/ folders with --multi-person against pose-associated/ without it")
    for trial_name in TRIALS:
        trial = root / "S00_P00_SingleParticipant" / trial_name
        counts = [np.bincount([len(p) for p in read_camera_detections(d).people])
                  for d in sorted((trial / "pose").iterdir()) if d.is_dir()]
        common = ["--calibration", str(calib), "--quiet", "--export", "none", "--no-recording"]
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            mod.main(["--keypoints", str(trial / "pose"), "--out", str(out / trial_name / "multi"), "--multi-person",
                      *common])
            t1 = time.perf_counter()
            mod.main(["--keypoints", str(trial / "pose-associated"), "--out", str(out / trial_name / "single"),
                      *common])
        people = sorted(p.name for p in (out / trial_name / "multi").iterdir() if p.is_dir())
        single = np.load(out / trial_name / "single" / "poses3d.npz")["joints"]
        line = (f"  {trial_name}: detections per frame and camera (count: frames) "
                + "; ".join(", ".join(f"{n}: {c}" for n, c in enumerate(cnt) if c) for cnt in counts)
                + f" -> {len(people)} people found ({t1 - t0:.0f} s)")
        if people:
            multi = np.load(out / trial_name / "multi" / people[0] / "poses3d.npz")["joints"]
            d = 1000 * np.linalg.norm(multi - single, axis=-1)
            line += (f"; person_0 vs single-person result: median {np.nanmedian(d):.2f} mm, "
                     f"largest {np.nanmax(d):.2f} mm, frames with joints "
                     f"{int(np.isfinite(multi).all(-1).any(-1).sum())}"
                     f"/{len(multi)}")
        print(line, flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--no-demo", action="store_true", help="skip the Pose2Sim demo")
    args = ap.parse_args(argv)

    rows = []
    print(f"{'scene':28s} {'err':>3s} {'seed':>4s} {'found':>5s} {'false':>5s} {'MPJPE per person (mm)':>24s} "
          f"{'oracle':>18s} {'switches':>8s} {'missed':>8s} {'ms/frame':>8s}")
    for n_people, n_by, n_cams in SCENES:
        for err in ERRORS_PX:
            for seed in range(args.seeds):
                r = run_scene(n_people, n_by, n_cams, err, 300 + seed, args.frames)
                r.update(scene=(n_people, n_by, n_cams), err=err, seed=seed)
                rows.append(r)
                print(f"{n_people} people {n_by} bystanders {n_cams} cams {err:3.0f} {seed:4d} {r['found']:5d} "
                      f"{r['false']:5d} {' '.join(f'{m:5.1f}' for m in r['mpjpe']):>24s} "
                      f"{' '.join(f'{m:5.1f}' for m in r['oracle']):>18s} {str(r['switches'].tolist()):>8s} "
                      f"{str(r['missed'].tolist()):>8s} {r['track_ms']:8.1f}", flush=True)
    print("\nper configuration, over seeds: per person MPJPE (mm) median / worst; identity switches total / worst "
          "person; missed frames total; false people total")
    for sc in SCENES:
        for err in ERRORS_PX:
            sel = [r for r in rows if r["scene"] == sc and r["err"] == err]
            mp = np.concatenate([r["mpjpe"] for r in sel])
            orc = np.concatenate([r["oracle"] for r in sel])
            sw = np.concatenate([r["switches"] for r in sel])
            print(f"  {sc[0]} people, {sc[1]} bystanders, {sc[2]} cams, {err:.0f} px: MPJPE {np.nanmedian(mp):.1f} / "
                  f"{np.nanmax(mp):.1f} (oracle {np.nanmedian(orc):.1f} / {np.nanmax(orc):.1f}); "
                  f"switches {int(sw.sum())} / {int(sw.max())}; missed "
                  f"{int(sum(r['missed'].sum() for r in sel))}; false people {sum(r['false'] for r in sel)} "
                  f"({len(sel)} scenes)")
    root = Path(os.environ.get("TOOLKIT_REALDATA", REPO_ROOT.parent / "shared" / "realdata")) / "pose2sim_demo"
    if not args.no_demo:
        if (root / "S00_P00_SingleParticipant").is_dir():
            with tempfile.TemporaryDirectory() as tmp:
                demo(root, Path(tmp))
        else:
            print(f"\nPose2Sim demo not found at {root}: skipped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
