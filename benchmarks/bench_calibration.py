#!/usr/bin/env python3
"""Calibration-from-scratch benchmark (issue 21): the Pose2Sim demo against the lab's calibration, and
synthetic rigs with ground truth for the three extrinsics methods.

Usage::

    python benchmarks/bench_calibration.py                 # real data (if present) + synthetic, 3 seeds
    python benchmarks/bench_calibration.py --quick         # synthetic with 1 seed
    python benchmarks/bench_calibration.py --no-real       # synthetic only

Real data (``../shared/realdata/pose2sim_demo``; skipped when absent):

* intrinsics from ``S00_Calibration/intrinsics`` (checkerboard 4x7 inner corners, 60 mm, per
  Pose2Sim's Config.toml) against ``Calib_qualisys.toml``: fx, fy, cx, cy and their differences,
  views used / rejected, RMS and coverage;
* extrinsics from the people on the balancing trial (``pose-associated`` OpenPose BODY_25B, 100
  frames, stature 1.72 m from the Config.toml's ``participant_height``), once with the lab's
  intrinsics and once with the intrinsics above: camera centres (cm) and orientations (deg) after a
  similarity alignment to ``Calib_qualisys.toml``, the scale found (1 = metric), the up direction's
  angle to the lab's z axis, reprojection errors; and the adjusted keypoints (after the same
  alignment) against Pose2Sim's ``pose-3d`` TRC (its triangulation with the lab's calibration), per
  marker name both share: median distance (cm); the lab calibration's own DLT of the same keypoints
  against the TRC for comparison.

Synthetic (4 cameras on a 4 m circle, 800 x 600, f = 700 px, mild distortion; seeds 0..2): people
(60 frames of a 1.75 m person walking a circle, arms waving; keypoints with 0 / 1 / 2 px noise),
scene points (12 points in a 4 x 4 x 1.5 m volume, same noise) and a ChArUco board (10 poses,
0.5 px corner noise): worst camera-centre error (mm) and orientation error (deg) after a similarity
alignment, and the scale.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")


import numpy as np  # noqa: E402

from toolkit.calibration.boards import Board, BoardDetection, board_frames, detect_in_frames  # noqa: E402
from toolkit.calibration.extrinsics import (  # noqa: E402
    extrinsics_from_boards,
    extrinsics_from_people,
    extrinsics_from_scene_points,
    similarity_align,
)
from toolkit.calibration.intrinsics import calibrate_intrinsics  # noqa: E402
from toolkit.cameras import Camera, Rig  # noqa: E402
from toolkit.cameras.triangulation import triangulate_linear  # noqa: E402
from toolkit.io.calibration import read_calibration  # noqa: E402
from toolkit.skeleton import JOINTS_14  # noqa: E402
from toolkit.synthetic.boards import board_corners, board_pose, people_sequence  # noqa: E402

REALDATA = Path(os.environ.get("TOOLKIT_REALDATA", Path(__file__).resolve().parents[2] / "shared" / "realdata"))


def pose_errors(est, ref):
    """Centre distances (m), orientation angles (deg), scale and rotation of the similarity est -> ref."""
    ec, rc = np.array([c.center for c in est]), np.array([c.center for c in ref])
    s, R, t = similarity_align(ec, rc)
    dc = np.linalg.norm(s * ec @ R.T + t - rc, axis=1)
    ang = []
    for ce, ct in zip(est, ref):
        Rd = ct.R @ (ce.R @ R.T).T
        ang.append(np.degrees(np.arccos(np.clip((np.trace(Rd) - 1) / 2, -1, 1))))
    return dc, np.array(ang), s, R, t


def real(root: Path):
    from toolkit.io.keypoint_files import camera_sources
    from toolkit.io.keypoint_formats import read_keypoints
    from toolkit.io.trajectories import read_trc
    from toolkit.skeleton.mappings import KEYPOINTS

    calib = root / "S00_Calibration"
    ref = read_calibration(calib / "Calib_qualisys.toml")
    board = Board("checkerboard", 4, 7, 0.060)
    print("## Intrinsics, Pose2Sim demo (checkerboard 4x7, 60 mm) vs Calib_qualisys.toml\n")
    print("| camera | views used / rejected | RMS px | coverage | fx (lab) | fy (lab) | cx (lab) | cy (lab) "
          "| fx diff | fy diff |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    ours = []
    for folder, rc in zip(sorted(p for p in (calib / "intrinsics").iterdir() if p.is_dir()), ref):
        t0 = time.time()
        dets, missed = detect_in_frames(board_frames(folder), board, str(folder))
        r = calibrate_intrinsics(dets, board, rc.name, missed=missed)
        K, L = r.camera.K, rc.K
        ours.append(r.camera)
        print(f"| {rc.name} | {len(r.view_rms_px)} / {len(r.rejected)} | {r.rms_px:.2f} | {r.coverage:.0%} | "
              f"{K[0, 0]:.1f} ({L[0, 0]:.1f}) | {K[1, 1]:.1f} ({L[1, 1]:.1f}) | {K[0, 2]:.1f} ({L[0, 2]:.1f}) | "
              f"{K[1, 2]:.1f} ({L[1, 2]:.1f}) | {100 * (K[0, 0] / L[0, 0] - 1):+.2f} % | "
              f"{100 * (K[1, 1] / L[1, 1] - 1):+.2f} % |   <!-- {time.time() - t0:.1f} s -->")
        for v, why in r.rejected:
            print(f"<!-- {rc.name} rejected {v}: {why} -->")
    trial = root / "S00_P00_SingleParticipant" / "S00_P00_T01_BalancingTrial"
    data = read_keypoints(camera_sources(trial / "pose-associated"), "body_25b")
    names = KEYPOINTS["body_25b"]
    trc = read_trc(sorted((trial / "pose-3d").glob("*_0-100.trc"))[0])
    print("\n## Extrinsics from the people, balancing trial (100 frames, BODY_25B, stature 1.72 m)\n")
    print("| intrinsics | centre error cm (per camera) | orientation error deg | scale | up vs lab z deg "
          "| reprojection median / RMS px | keypoints vs Pose2Sim TRC median cm | time s |")
    print("|---|---|---|---|---|---|---|---|")
    shared = [n for n in names if n in trc.names]
    kp_frames = data.frames
    trc_idx = [int(np.flatnonzero(trc.frames == f)[0]) if np.any(trc.frames == f) else -1 for f in kp_frames]
    for label, intr in (("lab (Calib_qualisys)", [c.replace(cam_from_world=np.eye(4)) for c in ref]),
                        ("ours (board above)", [c.replace(name=rc.name) for c, rc in zip(ours, ref)])):
        t0 = time.time()
        r = extrinsics_from_people(intr, data.keypoints, names, "body_25b", height_m=1.72,
                                   rng=np.random.default_rng(0))
        dt = time.time() - t0
        dc, ang, s, R, t = pose_errors(r.rig, ref)
        up = np.degrees(np.arccos(np.clip((R @ [0, 0, 1.0])[2], -1, 1)))
        X = r.details["keypoints3d"] * s @ R.T + t  # in the lab's frame
        d = []
        for n in shared:
            i, j = names.index(n), trc.names.index(n)
            for k, ti in enumerate(trc_idx):
                if ti >= 0 and np.all(np.isfinite(X[k, i])) and np.all(np.isfinite(trc.positions[ti, j])):
                    d.append(np.linalg.norm(X[k, i] - trc.positions[ti, j]))
        med = np.median([v["median_px"] for v in r.reprojection.values()])
        rms = np.sqrt(np.mean([v["rms_px"] ** 2 for v in r.reprojection.values()]))
        print(f"| {label} | {' '.join(f'{100 * v:.1f}' for v in dc)} | {' '.join(f'{v:.2f}' for v in ang)} | "
              f"{1 / s:.3f} | {up:.1f} | {med:.2f} / {rms:.2f} | {100 * np.median(d):.1f} | {dt:.0f} |")
        for w in r.warnings:
            print(f"<!-- warning: {w} -->")
        print(f"<!-- {label}: floor {r.details['floor_from']}; bone scales {r.details['bone_scales']} -->")
    # the lab calibration's own triangulation of the same keypoints vs the TRC
    uv = data.keypoints[..., :2].copy()
    uv[data.keypoints[..., 2] < 0.3] = np.nan
    Xl = triangulate_linear(list(ref), uv)
    d = []
    for n in shared:
        i, j = names.index(n), trc.names.index(n)
        for k, ti in enumerate(trc_idx):
            if ti >= 0 and np.all(np.isfinite(Xl[k, i])) and np.all(np.isfinite(trc.positions[ti, j])):
                d.append(np.linalg.norm(Xl[k, i] - trc.positions[ti, j]))
    print(f"\nThe lab calibration's own DLT of the same keypoints vs the TRC: median {100 * np.median(d):.1f} cm "
          f"({len(shared)} shared marker names).")


def synthetic_rig(n=4):
    return [Camera.look_at(f"cam_{i + 1:02d}", [4 * np.cos(2 * np.pi * i / n + 0.3), 4 * np.sin(2 * np.pi * i / n + 0.3),
                                                 2.0 + 0.3 * i], [0, 0, 1.0], size=(800, 600), focal_px=700.0,
                           dist=[-0.05, 0.01, 0, 0, 0]) for i in range(n)]


def synthetic(seeds):
    cams = synthetic_rig()
    intr = [c.replace(cam_from_world=np.eye(4)) for c in cams]
    print("\n## Synthetic rigs (4 cameras, 4 m circle), worst camera over seeds " + ", ".join(map(str, seeds)) + "\n")
    print("| method | noise px | centre error mm (worst) | orientation error deg (worst) | scale error % (worst) |")
    print("|---|---|---|---|---|")
    for noise in (0.0, 1.0, 2.0):
        rows = []
        for seed in seeds:
            rng = np.random.default_rng(seed)
            P = people_sequence(60, rng, height=1.75)[0]
            kp = np.zeros((4, 60, 14, 3))
            for c, cam in enumerate(cams):
                kp[c, ..., :2] = cam.project(P) + rng.normal(0, noise, (60, 14, 2))
                kp[c, ..., 2] = 1.0
            r = extrinsics_from_people(intr, kp, JOINTS_14, "skeleton14", height_m=1.75, rng=rng)
            dc, ang, s, _, _ = pose_errors(r.rig, cams)
            rows.append((dc.max(), ang.max(), abs(s - 1)))
        a = np.max(rows, axis=0)
        print(f"| people | {noise:g} | {1000 * a[0]:.1f} | {a[1]:.3f} | {100 * a[2]:.2f} |")
    for noise in (0.0, 1.0, 2.0):
        rows = []
        for seed in seeds:
            rng = np.random.default_rng(seed)
            X = rng.uniform([-2, -2, 0], [2, 2, 1.5], (12, 3))
            px = np.stack([c.project(X) for c in cams]) + rng.normal(0, noise, (4, 12, 2))
            r = extrinsics_from_scene_points(intr, X, px)
            dc = np.linalg.norm(r.rig.centers - Rig(tuple(cams)).centers, axis=1)
            _, ang, s, _, _ = pose_errors(r.rig, cams)
            rows.append((dc.max(), ang.max(), abs(s - 1)))
        a = np.max(rows, axis=0)
        print(f"| scene points (no alignment) | {noise:g} | {1000 * a[0]:.1f} | {a[1]:.3f} | {100 * a[2]:.2f} |")
    board = Board("charuco", 5, 7, 0.08, 0.06)
    for noise in (0.0, 0.5):
        rows = []
        for seed in seeds:
            rng = np.random.default_rng(seed)
            dets = [{} for _ in cams]
            for v in range(10):
                Tb = board_pose(rng.uniform([-0.5, -0.5, 0.0], [0.5, 0.5, 0.8]), rng.uniform(-30, 30, 2),
                                rng.uniform(-180, 180), facing=(0, 0, -1))
                for c, cam in enumerate(cams):
                    uv = board_corners(cam, board, Tb)
                    if np.all(cam.in_image(uv)) and Tb[:3, 2] @ (cam.center - Tb[:3, 3]) < 0:
                        dets[c][f"v{v}"] = BoardDetection("v", cam.size, np.arange(board.n_corners),
                                                          uv + rng.normal(0, noise, uv.shape))
            r = extrinsics_from_boards(intr, dets, board)
            dc, ang, s, _, _ = pose_errors(r.rig, cams)
            rows.append((dc.max(), ang.max(), abs(s - 1)))
        a = np.max(rows, axis=0)
        print(f"| board (ChArUco 5x7, 80 mm) | {noise:g} | {1000 * a[0]:.1f} | {a[1]:.3f} | {100 * a[2]:.2f} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="synthetic with one seed")
    ap.add_argument("--no-real", action="store_true", help="skip the Pose2Sim demo")
    args = ap.parse_args(argv)
    root = REALDATA / "pose2sim_demo"
    if not args.no_real:
        if root.is_dir():
            real(root)
        else:
            print(f"(real data not found at {root}: skipped)")
    synthetic([0] if args.quick else [0, 1, 2])
    return 0


if __name__ == "__main__":
    sys.exit(main())
