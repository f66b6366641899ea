#!/usr/bin/env python3
"""Compare our keypoint triangulation with Pose2Sim's on its demo.

Usage::

    python benchmarks/bench_pose2sim.py [--realdata DIR] [--max-frames N] [--out OUT]

Runs ``recipes/pose_from_keypoints.py`` on the Pose2Sim demo's associated
OpenPose keypoints (``pose-associated/``, BODY_25B) with and without per-view
offsets, then prints:

* per joint, the distance (mm) between our 3D joints and Pose2Sim's own
  triangulation (``pose-3d/*.trc``, the unfiltered one; 21 markers in
  metres, Y-up, world = (trc Z, trc X, trc Y), checked here by projecting);
* the reprojection error (px) against the OpenPose keypoints of our joints and
  of Pose2Sim's, on the joints both have, and of ours against the
  offset-corrected keypoints;
* the offsets per camera and the time per frame.

The demo lives in ``../shared/realdata/pose2sim_demo`` (or ``$TOOLKIT_REALDATA``);
without it the benchmark prints a message and exits 0.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

from toolkit.cameras import Rig  # noqa: E402
from toolkit.io import read_calibration  # noqa: E402
from toolkit.io.openpose import read_openpose_cameras  # noqa: E402
from toolkit.skeleton import JOINTS_14  # noqa: E402
from toolkit.skeleton.mappings import BODY_25B, to_skeleton14  # noqa: E402

TRIALS = (Path("pose2sim_demo/S00_P00_SingleParticipant/S00_P00_T00_StaticTrial"),
          Path("pose2sim_demo/S00_P00_SingleParticipant/S00_P00_T01_BalancingTrial"))
CALIB = Path("pose2sim_demo/S00_Calibration/Calib_qualisys.toml")
#: Our joints and the .trc markers that name the same point.
PAIRS = [(f"{s.lower()}_{n}", f"{s}{n.capitalize()}") for s in "LR"
         for n in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")]
#: Confidence below which a keypoint is not used in the reprojection comparison (as Pose2Sim).
MIN_CONFIDENCE = 0.3


def read_trc(path: Path):
    """Marker names and positions (T, M, 3) of a .trc file, in its own axes and units."""
    lines = path.read_text().splitlines()
    names = [n for n in lines[3].split("\t")[2:] if n.strip()]
    data = np.loadtxt(path, skiprows=5)
    return names, data[:, 2:].reshape(len(data), len(names), 3)


def run_recipe(calib: Path, keypoints: Path, out: Path, max_frames: int | None, extra: list[str]) -> float:
    cmd = [sys.executable, str(REPO / "recipes" / "pose_from_keypoints.py"), "--calibration", str(calib),
           "--keypoints", str(keypoints), "--out", str(out), "--quiet", "--no-recording", *extra]
    if max_frames:
        cmd += ["--max-frames", str(max_frames)]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--realdata", type=Path,
                    default=Path(os.environ.get("TOOLKIT_REALDATA", REPO.parent / "shared" / "realdata")))
    ap.add_argument("--max-frames", type=int, default=None)
    ap.add_argument("--out", type=Path, default=None, help="keep the recipe outputs here")
    args = ap.parse_args(argv)
    calib = args.realdata / CALIB
    if not all((args.realdata / t).is_dir() for t in TRIALS) or not calib.is_file():
        print(f"Pose2Sim demo not found under {args.realdata}; skipping (set TOOLKIT_REALDATA).")
        return 0
    for t in TRIALS:
        print(f"\n======== {t.name} ========")
        bench_trial(args.realdata / t, calib, args)
    return 0


def bench_trial(trial: Path, calib: Path, args) -> None:

    rig = read_calibration(calib)
    rig = Rig(tuple(sorted(rig, key=lambda c: c.name)))
    _, frames, kp = read_openpose_cameras(trial / "pose-associated", len(BODY_25B), max_frames=args.max_frames)
    kp14 = to_skeleton14(kp, "body_25b", confidence=True, min_confidence=MIN_CONFIDENCE)
    names, trc = read_trc(next(p for p in sorted((trial / "pose-3d").glob("*.trc")) if "filt" not in p.name))
    trc = trc[: len(frames)][..., [2, 0, 1]]  # Y-up trc -> our z-up world: (Z, X, Y)
    trc_kp = {n: i for i, n in enumerate(names)}

    # check the axis convention by projecting: the .trc must land on the keypoints
    raw25 = np.where(kp[..., 2:] >= MIN_CONFIDENCE, kp[..., :2], np.nan)
    def trc_reprojection(points):
        proj = rig.project(points)                                    # (C, T, M, 2)
        obs = np.stack([raw25[:, :, BODY_25B.index(n)] if n in BODY_25B else np.full(raw25.shape[:2] + (2,), np.nan)
                        for n in names], axis=2)
        return np.linalg.norm(proj - obs, axis=-1)
    e_ok = np.nanmedian(trc_reprojection(trc))
    e_swapped = np.nanmedian(trc_reprojection(trc[..., [1, 0, 2]]))
    print(f"axis check: Pose2Sim .trc as (Z, X, Y) reprojects at {e_ok:.1f} px median, "
          f"as (X, Z, Y) at {e_swapped:.1f} px")

    with tempfile.TemporaryDirectory() as tmp:
        base = args.out or Path(tmp)
        runs = {}
        for label, extra in (("ours (defaults)", []), ("ours (per-frame offsets)", ["--offsets", "frame"]),
                             ("ours (no offsets)", ["--no-offsets"])):
            out = base / label.replace(" ", "_").replace("(", "").replace(")", "")
            dt = run_recipe(calib, trial / "pose-associated", out, args.max_frames, extra)
            p3 = np.load(out / "poses3d.npz")
            off = np.load(out / "offsets.npz")
            flips = np.load(out / "flips.npz")["flips"]
            runs[label] = dict(joints=p3["joints"], offsets=off["offsets"], seconds=dt, cost=p3["cost"],
                               mode=str(off["mode"]), reason=str(off["reason"]), flips=int((flips != "").sum()))

    T = len(frames)
    print(f"\nPose2Sim demo, {T} frames, {len(rig)} cameras ({', '.join(rig.names)})")
    print("\nPer-joint distance to Pose2Sim's triangulation (mm): median / 90th percentile")
    header = f"{'joint':<12}" + "".join(f"{k:>22}" for k in runs)
    print(header)
    per_joint = {k: [] for k in runs}
    for ours, theirs in PAIRS:
        row = f"{ours:<12}"
        for k, r in runs.items():
            d = 1000 * np.linalg.norm(r["joints"][:, JOINTS_14.index(ours)] - trc[:, trc_kp[theirs]], axis=-1)
            per_joint[k].append(d)
            row += f"{np.nanmedian(d):>14.0f} / {np.nanpercentile(d, 90):<5.0f}"
        print(row)
    row = f"{'all':<12}"
    for k in runs:
        d = np.concatenate(per_joint[k])
        row += f"{np.nanmedian(d):>14.0f} / {np.nanpercentile(d, 90):<5.0f}"
    print(row)

    # reprojection error against the OpenPose keypoints, on the 12 limb joints both have
    idx = [JOINTS_14.index(a) for a, _ in PAIRS]
    obs = kp14[..., :2][:, :, idx]                                      # (C, T, 12, 2)
    print("\nReprojection error against the OpenPose keypoints (px, 12 limb joints): median / 90th percentile")
    theirs = np.linalg.norm(rig.project(trc[:, [trc_kp[b] for _, b in PAIRS]]) - obs, axis=-1)
    print(f"{'Pose2Sim .trc':<32}{np.nanmedian(theirs):>8.1f} / {np.nanpercentile(theirs, 90):.1f}")
    for k, r in runs.items():
        e = np.linalg.norm(rig.project(r["joints"][:, idx]) - obs, axis=-1)
        print(f"{k + ', raw keypoints':<32}{np.nanmedian(e):>8.1f} / {np.nanpercentile(e, 90):.1f}")
        if "no offsets" not in k:
            corr = obs + np.transpose(np.nan_to_num(r["offsets"]), (1, 0, 2))[:, :, None, :]
            e = np.linalg.norm(rig.project(r["joints"][:, idx]) - corr, axis=-1)
            print(f"{k + ', corrected keypoints':<32}{np.nanmedian(e):>8.1f} / {np.nanpercentile(e, 90):.1f}")
    for k, r in runs.items():
        off = np.nanmedian(r["offsets"], axis=0)
        print(f"\n{k}: offsets {r['mode']} (median per camera, px: " + ", ".join(
            f"{c} ({o[0]:+.1f}, {o[1]:+.1f})" for c, o in zip(rig.names, off)) + f"); {r['flips']} view-frames flipped")
        print(f"  why: {r['reason']}")
        print(f"  mean ray distance {1000 * np.nanmean(r['cost']):.1f} mm, "
              f"{1000 * r['seconds'] / T:.0f} ms per frame (whole recipe run incl. start-up)")


if __name__ == "__main__":
    sys.exit(main())
