#!/usr/bin/env python3
"""Calibration-from-scratch benchmark (issue 21): the Pose2Sim demo against the lab's calibration, and
synthetic rigs with ground truth for the three extrinsics methods.

Usage::

    python benchmarks/bench_calibration.py                 # real data (if present) + synthetic, 3 seeds
    python benchmarks/bench_calibration.py --quick         # synthetic with 1 seed
    python benchmarks/bench_calibration.py --no-real       # synthetic only
    python benchmarks/bench_calibration.py --parts ours [--out OUT]   # our detections only

``--parts`` picks among ``demo`` (the demo's OpenPose keypoints and board intrinsics), ``ours`` (the
project's own detections), ``sensitivity`` (the multiperson capture under other settings, about 15
minutes; not by default) and ``synthetic`` (the others by default).

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

Our detections (``ours``, issue 32 item 5): the built-in detector (BlazePose, ``detect_videos`` with
default options, kept in ``OUT/<capture>_keypoints`` and reused) on the videos of
``pose2sim_multiperson`` (two participants and bystanders; no stature given) and of the demo's
balancing trial (one person, stature 1.72 m), with the intrinsics of the capture's Qualisys file:
camera centres (cm, per camera, median and worst) and orientations (deg) after a similarity alignment
to that file, scale, up direction, reprojection and the people-frames used (RANSAC seeds 0, 1, 2), for
two inputs: one person per camera and frame (the most confident, what ``read_keypoints`` gives and
``calibrate.py extrinsics --keypoints`` passes) and every detection (``detections_array``); and, for
comparison, the best fit of the same detections: grouped with the lab's own poses and adjusted from
them (what the detections allow near the lab's rig), and the lab rig's own reprojection of them.

Synthetic (4 cameras on a 4 m circle, 800 x 600, f = 700 px, mild distortion; seeds 0..2): people
(60 frames of a 1.75 m person walking a circle, arms waving; keypoints with 0 / 1 / 2 px noise; and
two such people with a bystander seen by one camera, every camera's detections in a random order,
seeds 100..102),
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
    PeopleConfig,
    adjust_observations,
    extrinsics_from_boards,
    extrinsics_from_people,
    extrinsics_from_scene_points,
    similarity_align,
)
from toolkit.calibration.people_matching import (  # noqa: E402
    JOIN_FACTOR,
    associate_detections,
    detections_array,
    group_observations,
    triangulate_normalised,
)
from toolkit.calibration.intrinsics import calibrate_intrinsics  # noqa: E402
from toolkit.cameras import Camera, Rig  # noqa: E402
from toolkit.cameras.triangulation import triangulate_linear  # noqa: E402
from toolkit.errors import InputError  # noqa: E402
from toolkit.io.calibration import read_calibration  # noqa: E402
from toolkit.skeleton import JOINTS_14  # noqa: E402
from toolkit.synthetic.boards import board_corners, board_pose, people_sequence  # noqa: E402

REALDATA = Path(os.environ.get("TOOLKIT_REALDATA", Path(__file__).resolve().parents[2] / "shared" / "realdata"))
REPO = Path(__file__).resolve().parents[1]
#: Our detections: capture name -> (videos, the lab's calibration, stature in metres or None).
OURS = {"pose2sim_multiperson": ("pose2sim_multiperson/videos", "pose2sim_multiperson/calibration/Calib.qca.txt",
                                 None),
        "balancing trial": ("pose2sim_demo/S00_P00_SingleParticipant/S00_P00_T01_BalancingTrial/videos",
                            "pose2sim_demo/S00_Calibration/Calib.qca.txt", 1.72)}
#: RANSAC seeds of the runs on our detections (one person per camera is a weak input: its result moves).
SEEDS = (0, 1, 2)


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


def best_fit(ref, kp: np.ndarray, cfg: PeopleConfig = PeopleConfig()) -> tuple:
    """The lab's rig adjusted to detections (n_cams, T, P, K, 3), as ``extrinsics_from_people`` adjusts its
    own start: people grouped with the poses (first within ``JOIN_FACTOR * match_px``: the lab's rig
    reprojects these detections less well), two rounds of bundle adjustment (soft L1, observations over
    ``cfg.outlier_px`` dropped after the first), grouped again within ``match_px`` and adjusted again.

    Returns the cameras, the median residual (pixels) and the cameras per group.
    """
    cams = list(ref)
    uv = kp[..., :2].copy()
    seen = (kp[..., 2] >= cfg.min_confidence) & np.isfinite(uv).all(-1)
    xy = np.stack([c.undistort_points(uv[i]) for i, c in enumerate(cams)])
    f = np.array([c.K[0, 0] for c in cams])
    C = len(cams)
    for match_px in (JOIN_FACTOR * cfg.match_px, cfg.match_px):
        groups, frames, _ = associate_detections(np.stack([c.cam_from_world for c in cams]), xy, seen, f, match_px)
        gx, gs = group_observations(groups, frames, xy, seen)
        cams, _, residuals, _ = adjust_observations(cams, gx.reshape(C, -1, 2), gs.reshape(C, -1), 0, cfg)
    return cams, float(np.median(residuals)), (groups >= 0).sum(1)


def ours(out: Path):
    """Extrinsics from the people on the project's own detections, against the captures' Qualisys files."""
    from toolkit.io.keypoint_files import camera_sources, match_cameras
    from toolkit.io.keypoint_formats import read_keypoints
    from toolkit.pipeline.detect_keypoints import DetectConfig, detect_videos
    from toolkit.skeleton.mappings import KEYPOINTS

    print("\n## Extrinsics from the people, our detections (BlazePose, every frame of the videos), "
          "against the Qualisys file\n")
    print("| capture | input | centre error cm (per camera) | median / worst cm | orientation error deg "
          "| scale | up vs lab z deg | reprojection median px | people-frames (2/3/4 cameras) | time s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, (videos, calib, height) in OURS.items():
        if not (REALDATA / videos).is_dir():
            print(f"<!-- {name}: {REALDATA / videos} not found, skipped -->")
            continue
        ref = read_calibration(REALDATA / calib)
        kp_dir = out / f"{name.replace(' ', '_')}_keypoints"
        t0 = time.time()
        detect_videos(REALDATA / videos, kp_dir, DetectConfig(progress=False), log=lambda *_: None)
        print(f"<!-- {name}: detections in {kp_dir} ({time.time() - t0:.0f} s) -->")
        sources = camera_sources(kp_dir)
        order, _ = match_cameras([c.name for c in ref], sources, str(kp_dir))
        data = read_keypoints([sources[i] for i in order])
        names = KEYPOINTS[data.format.fmt]
        every = detections_array(data.cameras, data.frames, len(names))
        intr = [c.replace(cam_from_world=np.eye(4)) for c in ref]
        for label, kp in (("one person per camera (most confident)", data.keypoints),
                          ("every detection (matched across cameras)", every)):
            for seed in SEEDS:
                t0 = time.time()
                try:
                    r = extrinsics_from_people(intr, kp, names, data.format.fmt, height_m=height,
                                               rng=np.random.default_rng(seed))
                except InputError as e:
                    print(f"| {name} | {label}, seed {seed} | failed: {e} | | | | | | | {time.time() - t0:.0f} |")
                    continue
                dc, ang, s, R, _ = pose_errors(r.rig, list(ref))
                up = np.degrees(np.arccos(np.clip((R @ [0, 0, 1.0])[2], -1, 1)))
                med = np.median([v["median_px"] for v in r.reprojection.values()])
                views = r.details["groups_by_views"]
                print(f"| {name} | {label}, seed {seed} | {' '.join(f'{100 * v:.1f}' for v in dc)} | "
                      f"{100 * np.median(dc):.1f} / {100 * dc.max():.1f} | {' '.join(f'{v:.2f}' for v in ang)} | "
                      f"{1 / s:.3f} | {up:.1f} | {med:.2f} | {' / '.join(str(views.get(k, 0)) for k in (2, 3, 4))} "
                      f"| {time.time() - t0:.0f} |")
                for w in r.warnings:
                    print(f"<!-- warning: {w} -->")
                print(f"<!-- bone scales {r.details['bone_scales']}; {r.details['detections_unmatched']} "
                      "detections in no group -->")
        t0 = time.time()
        cams, med, views = best_fit(ref, every)
        dc, ang, s, R, _ = pose_errors(cams, list(ref))
        up = np.degrees(np.arccos(np.clip((R @ [0, 0, 1.0])[2], -1, 1)))
        print(f"| {name} | best fit of every detection (adjusted from the lab's poses) | "
              f"{' '.join(f'{100 * v:.1f}' for v in dc)} | {100 * np.median(dc):.1f} / {100 * dc.max():.1f} | "
              f"{' '.join(f'{v:.2f}' for v in ang)} | {1 / s:.3f} | {up:.1f} | {med:.2f} | "
              f"{' / '.join(str(int((views == k).sum())) for k in (2, 3, 4))} | {time.time() - t0:.0f} |")
        # the lab's rig itself on the same groups: its reprojection error
        lab_err = lab_reprojection(ref, every)
        print(f"<!-- {name}: the lab's rig on the same detections, median reprojection per camera after "
              f"triangulation: {' '.join(f'{v:.1f}' for v in lab_err)} px -->")


#: Keypoints left out by the sensitivity part's keypoint-set variants (BlazePose names).
_FACE_INNER = ("left_eye_inner", "left_eye_outer", "right_eye_inner", "right_eye_outer", "mouth_left", "mouth_right")
_HANDS = ("left_pinky", "right_pinky", "left_index", "right_index", "left_thumb", "right_thumb")


def sensitivity(out: Path):
    """The multiperson capture from every detection under other settings, keypoint sets, lens distortion
    and camera shifts of one frame: camera centres after the similarity alignment (median / worst, cm)."""
    from toolkit.io.keypoint_files import camera_sources, match_cameras
    from toolkit.io.keypoint_formats import read_keypoints
    from toolkit.skeleton.mappings import KEYPOINTS

    videos, calib, height = OURS["pose2sim_multiperson"]
    kp_dir = out / "pose2sim_multiperson_keypoints"
    if not (kp_dir / "detection.json").is_file():
        print(f"(sensitivity: run --parts ours first, {kp_dir} holds no detections: skipped)")
        return
    ref = read_calibration(REALDATA / calib)
    sources = camera_sources(kp_dir)
    order, _ = match_cameras([c.name for c in ref], sources, str(kp_dir))
    data = read_keypoints([sources[i] for i in order])
    names = KEYPOINTS[data.format.fmt]
    every = detections_array(data.cameras, data.frames, len(names))
    intr = [c.replace(cam_from_world=np.eye(4)) for c in ref]

    def without(left_out):
        kp = every.copy()
        m = np.array([n in left_out for n in names])
        kp[..., m, 2] = 0.0
        return kp

    def shifted(c, d):
        kp = np.full_like(every, np.nan)
        kp[..., 2] = 0.0
        T = every.shape[1]
        kp[:, max(0, -d):T - max(0, d)] = every[:, max(0, -d):T - max(0, d)]
        kp[c, max(0, -d):T - max(0, d)] = every[c, max(0, d):T - max(0, -d)]
        return kp

    variants = [("defaults", every, intr, PeopleConfig()),
                ("confidence >= 0.8", every, intr, PeopleConfig(min_confidence=0.8)),
                ("match within 6 px", every, intr, PeopleConfig(match_px=6.0)),
                ("match within 15 px", every, intr, PeopleConfig(match_px=15.0)),
                ("cut at 6 px", every, intr, PeopleConfig(outlier_px=6.0)),
                ("robust loss from 4 px", every, intr, PeopleConfig(f_scale_px=4.0)),
                ("without inner eye points and mouth", without(_FACE_INNER), intr, PeopleConfig()),
                ("without hands", without(_HANDS), intr, PeopleConfig()),
                ("without face, hands and feet", without(_FACE_INNER + _HANDS + ("nose", "left_eye", "right_eye",
                 "left_ear", "right_ear", "left_heel", "right_heel", "left_foot_index", "right_foot_index")), intr,
                 PeopleConfig()),
                ("lens distortion of the file not divided by 64", every,
                 [c.replace(dist=c.dist * 64) for c in intr], PeopleConfig())]
    variants += [(f"{ref[c].name} shifted by {d:+d} frame", shifted(c, d), intr, PeopleConfig())
                 for c in range(len(ref)) for d in (-1, 1)]
    print("\n## Sensitivity: pose2sim_multiperson from every detection, seed 0\n")
    print("| variant | centre error cm (per camera) | median / worst cm | reprojection median px | time s |")
    print("|---|---|---|---|---|")
    for label, kp, cams, cfg in variants:
        t0 = time.time()
        try:
            r = extrinsics_from_people(cams, kp, names, data.format.fmt, height_m=height, config=cfg,
                                       rng=np.random.default_rng(0))
        except InputError as e:
            print(f"| {label} | failed: {e} | | | {time.time() - t0:.0f} |")
            continue
        dc = pose_errors(r.rig, list(ref))[0]
        med = np.median([v["median_px"] for v in r.reprojection.values()])
        print(f"| {label} | {' '.join(f'{100 * v:.1f}' for v in dc)} | {100 * np.median(dc):.1f} / "
              f"{100 * dc.max():.1f} | {med:.2f} | {time.time() - t0:.0f} |", flush=True)


def lab_reprojection(ref, kp: np.ndarray, cfg: PeopleConfig = PeopleConfig()) -> np.ndarray:
    """Per camera, the median reprojection error (px) of detections grouped and triangulated with ``ref``'s poses."""
    cams = list(ref)
    uv = kp[..., :2].copy()
    seen = (kp[..., 2] >= cfg.min_confidence) & np.isfinite(uv).all(-1)
    xy = np.stack([c.undistort_points(uv[i]) for i, c in enumerate(cams)])
    f = np.array([c.K[0, 0] for c in cams])
    poses = np.stack([c.cam_from_world for c in cams])
    groups, frames, _ = associate_detections(poses, xy, seen, f, 4 * cfg.match_px)
    gx, gs = group_observations(groups, frames, xy, seen)
    obs = np.where(gs[..., None], gx, np.nan)
    out = []
    X = triangulate_normalised(poses, obs)
    for c, cam in enumerate(cams):
        Y = X @ cam.R.T + cam.t
        e = np.linalg.norm(Y[..., :2] / Y[..., 2:] - obs[c], axis=-1) * f[c]
        out.append(float(np.nanmedian(e)))
    return np.array(out)


def synthetic_rig(n=4):
    return [Camera.look_at(f"cam_{i + 1:02d}", [4 * np.cos(2 * np.pi * i / n + 0.3), 4 * np.sin(2 * np.pi * i / n + 0.3),
                                                 2.0 + 0.3 * i], [0, 0, 1.0], size=(800, 600), focal_px=700.0,
                           dist=[-0.05, 0.01, 0, 0, 0]) for i in range(n)]


def crowd_detections(cams, people: np.ndarray, noise: float, rng: np.random.Generator) -> np.ndarray:
    """Detections (n_cams, T, P, 14, 3) of people (P, T, 14, 3): the last person (a bystander) in the first
    camera only, every camera listing its detections in its own random order per frame."""
    P, T = people.shape[:2]
    kp = np.full((len(cams), T, P, 14, 3), np.nan)
    kp[..., 2] = 0.0
    for c, cam in enumerate(cams):
        who = list(range(P)) if c == 0 else list(range(P - 1))
        for t in range(T):
            for k, slot in zip(who, rng.permutation(len(who))):
                kp[c, t, slot, :, :2] = cam.project(people[k, t]) + rng.normal(0, noise, (14, 2))
                kp[c, t, slot, :, 2] = 1.0
    return kp


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
            rng = np.random.default_rng(100 + seed)
            kp = crowd_detections(cams, people_sequence(60, rng, height=1.75, n_people=3), noise, rng)
            r = extrinsics_from_people(intr, kp, JOINTS_14, "skeleton14", height_m=1.75, rng=rng)
            dc, ang, s, _, _ = pose_errors(r.rig, cams)
            rows.append((dc.max(), ang.max(), abs(s - 1)))
        a = np.max(rows, axis=0)
        print(f"| people, two + a bystander seen by one camera, detections unordered | {noise:g} | "
              f"{1000 * a[0]:.1f} | {a[1]:.3f} | {100 * a[2]:.2f} |")
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
    ap.add_argument("--no-real", action="store_true", help="skip the real captures (demo and ours)")
    ap.add_argument("--parts", default="demo,ours,synthetic",
                    help="comma-separated: demo (OpenPose keypoints, board intrinsics), ours (our detections), "
                         "sensitivity (the multiperson capture under other settings), synthetic")
    ap.add_argument("--out", type=Path, default=REPO / "out" / "bench_calibration",
                    help="folder of our detections (made once, then reused)")
    args = ap.parse_args(argv)
    parts = {p.strip() for p in args.parts.split(",")} - ({"demo", "ours", "sensitivity"} if args.no_real else set())
    root = REALDATA / "pose2sim_demo"
    if "demo" in parts:
        if root.is_dir():
            real(root)
        else:
            print(f"(real data not found at {root}: skipped)")
    if "ours" in parts:
        ours(args.out)
    if "sensitivity" in parts:
        sensitivity(args.out)
    if "synthetic" in parts:
        synthetic([0] if args.quick else [0, 1, 2])
    return 0


if __name__ == "__main__":
    sys.exit(main())
