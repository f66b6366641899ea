#!/usr/bin/env python3
"""Real captures from their videos alone: the built-in detector, synchronisation and several people.

Usage::

    python benchmarks/bench_detection.py [--realdata DIR] [--out OUT] [--parts trials,sync,multi]
        [--seed 0[,1,...]]

* ``trials``: Pose2Sim's demo trials (balancing, static) from ``videos/`` and ``Calib.qca.txt`` only:
  ``detect_videos`` then ``pose_from_keypoints`` with default options; per joint (hips, knees, ankles,
  shoulders, elbows, wrists) the distance to Pose2Sim's ``.trc`` (made from OpenPose), the share of
  joints filled, and how much of the gap is the two detectors' joint definitions: the same distance
  after removing each joint's constant offset in the body's frame (lateral, forward, up), and the
  2D offset between our keypoints and the shipped OpenPose ones on frames where the two agree;
  seconds (detection, triangulation) and the detector's images per second.
* ``sync``: per seed (``--seed 0,1,2,3``), two cameras of the balancing trial re-encoded starting 4-14
  frames late; per camera the true and found offsets, the error and the confidence, whether all are
  within one frame, and the 3D result against the synchronised run's (when ``trials`` ran into the
  same ``--out``).  Then the rigs in sync as recorded (the balancing trial, ``pose2sim_multiperson``):
  the offsets found, which must all be 0.  Detections are kept under ``OUT`` and reused by a rerun.
* ``multi``: ``pose2sim_multiperson`` from videos + ``Calib.qca.txt``, ``--multi-person``: the people
  found and how long each was followed; a picture per camera (``OUT/multiperson_cameras.jpg``).

Without the real data the benchmark says so and exits 0.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_pose2sim import PAIRS, read_trc
from toolkit.io import read_calibration
from toolkit.pipeline.detect_keypoints import DetectConfig, detect_videos
from toolkit.pipeline.pose_from_keypoints import PoseFromKeypointsConfig, run
from toolkit.skeleton import JOINTS_14
from toolkit.skeleton.mappings import BLAZEPOSE_33, BODY_25B

REPO = Path(__file__).resolve().parents[1]
DEMO = Path("pose2sim_demo")
TRIALS = {"balancing": DEMO / "S00_P00_SingleParticipant/S00_P00_T01_BalancingTrial",
          "static": DEMO / "S00_P00_SingleParticipant/S00_P00_T00_StaticTrial"}
QCA = DEMO / "S00_Calibration/Calib.qca.txt"
MULTI = Path("pose2sim_multiperson")
#: OpenPose BODY_25B and BlazePose names of the 12 limb joints, for the 2D comparison.
OP_NAMES = {"shoulder": "Shoulder", "elbow": "Elbow", "wrist": "Wrist", "hip": "Hip", "knee": "Knee",
            "ankle": "Ankle"}
#: Frames where the two detectors agree: the median distance over the 12 joints is below this (px).
AGREE_PX = 15.0


def _quiet(*_):
    pass


def triangulate(kp_dir: Path, calib: Path, out: Path, multi: bool = False):
    config = PoseFromKeypointsConfig(calibration=calib, recording=multi, export=(), progress=False,
                                     multi_person=multi)
    t0 = time.perf_counter()
    result = run(config, dataset=kp_dir, out=out, log=_quiet)
    return result, time.perf_counter() - t0


def body_frame_bias(J: np.ndarray, trc: np.ndarray, ix: dict) -> dict:
    """Per joint, the median offset ours - theirs in the body's frame (lateral, forward, up), metres."""
    x = trc[:, ix["LHip"]] - trc[:, ix["RHip"]]
    x[:, 2] = 0
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross([0, 0, 1.0], x)
    out = {}
    for ours, theirs in PAIRS:
        d = J[:, JOINTS_14.index(ours)] - trc[:, ix[theirs]]
        local = np.stack([(d * x).sum(1), (d * y).sum(1), d[:, 2]], 1)
        b = np.nanmedian(local, axis=0)
        out[ours] = (b, x, y)
    return out


def compare_to_trc(J: np.ndarray, frames: np.ndarray, trial: Path) -> dict:
    names, trc = read_trc(next(p for p in sorted((trial / "pose-3d").glob("*.trc")) if "filt" not in p.name))
    trc = trc[frames][..., [2, 0, 1]]
    ix = {n: i for i, n in enumerate(names)}
    bias = body_frame_bias(J, trc, ix)
    rows, raw, unbiased = {}, [], []
    for ours, theirs in PAIRS:
        d = J[:, JOINTS_14.index(ours)] - trc[:, ix[theirs]]
        b, x, y = bias[ours]
        world_b = b[0] * x + b[1] * y + b[2] * np.array([0, 0, 1.0])
        e, e2 = 1000 * np.linalg.norm(d, axis=1), 1000 * np.linalg.norm(d - world_b, axis=1)
        rows[ours] = (np.nanmedian(e), np.nanpercentile(e, 90), np.isfinite(e).mean(), np.nanmedian(e2),
                      1000 * np.linalg.norm(b))
        raw.append(e)
        unbiased.append(e2)
    raw, unbiased = np.concatenate(raw), np.concatenate(unbiased)
    return {"rows": rows, "median": np.nanmedian(raw), "p90": np.nanpercentile(raw, 90),
            "fill": np.isfinite(raw).mean(), "median_unbiased": np.nanmedian(unbiased)}


def definition_gap_2d(kp_dir: Path, trial: Path) -> dict:
    """Per joint, the median 2D offset (px) BlazePose - OpenPose on frames where the two agree."""
    from toolkit.io.keypoint_files import camera_sources, read_camera_detections
    from toolkit.io.openpose import read_openpose_cameras

    _, op_frames, op = read_openpose_cameras(trial / "pose-associated", len(BODY_25B))
    ours = [read_camera_detections(s) for s in camera_sources(kp_dir)]
    per_joint = {f"{s}_{j}": [] for s in "lr" for j in OP_NAMES}
    agree = total = 0
    for c, cam in enumerate(ours):
        for f, people in zip(cam.frames, cam.people):
            t = np.searchsorted(op_frames, f)
            if t >= len(op_frames) or op_frames[t] != f or len(people) == 0:
                continue
            o = op[c, t]
            best = None
            for p in people:
                d = []
                for s, side in (("l", "left"), ("r", "right")):
                    for j, name in OP_NAMES.items():
                        a = p[BLAZEPOSE_33.index(f"{side}_{j}"), :2]
                        b = o[BODY_25B.index(f"{side[0].upper()}{name}")]
                        d.append(a - b[:2] if b[2] >= 0.3 else [np.nan, np.nan])
                d = np.array(d)
                med = np.nanmedian(np.linalg.norm(d, axis=1))
                if best is None or med < best[0]:
                    best = (med, d)
            total += 1
            if best is not None and best[0] < AGREE_PX:
                agree += 1
                for k, key in enumerate(per_joint):
                    per_joint[key].append(best[1][k])
    return {"agree_share": agree / max(total, 1),
            "median_offset_px": {k: np.nanmedian(np.array(v), axis=0) if v else np.array([np.nan, np.nan])
                                 for k, v in per_joint.items()}}


def bench_trials(root: Path, out: Path, log) -> None:
    calib = root / QCA
    for label, rel in TRIALS.items():
        trial = root / rel
        kp = out / f"{label}_keypoints"
        t0 = time.perf_counter()
        det = detect_videos(trial / "videos", kp, DetectConfig(progress=False), log=_quiet)
        t_det = time.perf_counter() - t0
        result, t_tri = triangulate(kp, calib, out / f"{label}_run")
        p = np.load(out / f"{label}_run" / "poses3d.npz")
        cmp = compare_to_trc(p["joints"], p["frames"], trial)
        gap = definition_gap_2d(kp, trial)
        n_img = sum(c["n_frames"] for c in det.cameras.values())
        log(f"\n== {label}: {len(p['frames'])} frames, 4 cameras, from videos/ and Calib.qca.txt ==")
        log(f"detection {t_det:.1f} s ({n_img / max(t_det, 1e-9):.1f} images/s, {det.frames_detected} run now), "
            f"triangulation {t_tri:.1f} s, total {t_det + t_tri:.1f} s")
        log(f"{'joint':<12}{'median':>8}{'p90':>8}{'filled':>8}{'bias|':>8}{'w/o bias':>10}   (mm; bias = constant "
            "offset in the body frame)")
        for j, (med, p90, fill, unb, b) in cmp["rows"].items():
            log(f"{j:<12}{med:8.1f}{p90:8.1f}{fill:8.2f}{b:8.1f}{unb:10.1f}")
        log(f"{'all 12':<12}{cmp['median']:8.1f}{cmp['p90']:8.1f}{cmp['fill']:8.3f}{'':8}{cmp['median_unbiased']:10.1f}")
        log(f"2D: the detectors agree (median over 12 joints < {AGREE_PX:g} px) on {gap['agree_share']:.0%} of the "
            "view-frames; median offset ours - OpenPose there (px, x right / y down):")
        log("  " + ", ".join(f"{k} ({v[0]:+.0f}, {v[1]:+.0f})" for k, v in gap["median_offset_px"].items()))


def _late_starts(seed: int) -> dict[str, int]:
    """Two of the four cameras starting 4-14 frames late, drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    late = {c: 0 for c in ("cam01", "cam02", "cam03", "cam04")}
    for c in rng.choice(list(late), size=2, replace=False):
        late[str(c)] = int(rng.integers(4, 15))
    return late


def bench_sync(root: Path, out: Path, seeds: list[int], log) -> None:
    """Late starts found per seed (error per camera, all within one frame?), and in-sync rigs kept at 0."""
    from toolkit.io import VideoReader
    from toolkit.io.video import write_video
    from toolkit.pipeline.detect_keypoints import synchronise

    trial = root / TRIALS["balancing"]
    rows = []
    for seed in seeds:
        late = _late_starts(seed)
        base = out / f"sync_seed{seed}"
        videos = base / "videos"
        videos.mkdir(parents=True, exist_ok=True)
        for c, k in late.items():   # every camera re-encoded alike, two of them starting late
            if not (videos / f"{c}.mp4").is_file():
                with VideoReader(trial / "videos" / f"{c}.mp4") as r:
                    fps, frames = r.fps, [f for i, f in enumerate(r) if i >= k]
                write_video(videos / f"{c}.mp4", frames, fps)
        t0 = time.perf_counter()
        det = detect_videos(videos, base / "keypoints", DetectConfig(progress=False, sync=True,
                                                                      calibration=root / QCA), log=_quiet)
        found, conf = det.sync.offsets, det.sync.confidence
        errs = {c: found[c] - late[c] for c in late}
        ok = max(abs(e) for e in errs.values()) <= 1
        rows.append((seed, late, found, errs, ok))
        log(f"\n== sync, seed {seed}: cameras started late {late} ({time.perf_counter() - t0:.0f} s, "
            "detection included unless kept from an earlier run) ==")
        log(f"{'camera':<8}{'true':>6}{'found':>7}{'error':>7}{'confidence':>12}{'trusted':>9}")
        for c in late:
            log(f"{c:<8}{late[c]:>6}{found[c]:>7}{errs[c]:>+7}{conf.get(c, float('nan')):>12.3f}"
                f"{str(det.sync.trusted[c]):>9}")
        log("all within one frame" if ok else "MISSED: an offset off by more than one frame")
        triangulate(base / "keypoints", root / QCA, base / "run")
        ref = out / "balancing_run" / "poses3d.npz"
        if ref.is_file():
            a, b = np.load(ref), np.load(base / "run" / "poses3d.npz")
            common = np.intersect1d(a["frames"], b["frames"])
            ja = a["joints"][np.searchsorted(a["frames"], common)]
            jb = b["joints"][np.searchsorted(b["frames"], common)]
            d = 1000 * np.linalg.norm(ja - jb, axis=-1)
            log(f"3D against the synchronised run on {len(common)} common frames: median {np.nanmedian(d):.1f} mm, "
                f"p90 {np.nanpercentile(d, 90):.1f} mm (frames seen by only two cameras after the cut included)")
    if len(rows) > 1:
        log(f"\n== sync summary: {sum(r[4] for r in rows)} of {len(rows)} seeds with every offset within one frame ==")
        for seed, late, found, errs, ok in rows:
            log(f"seed {seed}: true {list(late.values())} found {list(found.values())} errors "
                f"{list(errs.values())} {'ok' if ok else 'MISSED'}")
    # rigs in sync as recorded: every offset must come out 0
    in_sync = [("balancing", trial, root / QCA, out / "balancing_keypoints")]
    if (root / MULTI).is_dir():
        in_sync.append(("multiperson", root / MULTI, root / MULTI / "calibration" / "Calib.qca.txt",
                        out / "multiperson_keypoints"))
    for label, source, calib, kp in in_sync:
        detect_videos(source / "videos", kp, DetectConfig(progress=False), log=_quiet)
        res = synchronise(kp, DetectConfig().max_sync_offset, calib)
        zero = all(v == 0 for v in res.offsets.values())
        log(f"in sync as recorded, {label}: offsets {res.offsets}, confidence "
            f"{ {c: round(v, 3) for c, v in res.confidence.items()} }: {'all 0' if zero else 'NOT all 0'}")


def bench_multi(root: Path, out: Path, log) -> None:
    trial = root / MULTI
    t0 = time.perf_counter()
    result = run(PoseFromKeypointsConfig(multi_person=True, export=(), progress=False), dataset=trial,
                 out=out / "multi_run", log=_quiet)
    dt = time.perf_counter() - t0
    people = json.loads((out / "multi_run" / "people.json").read_text())
    det = json.loads((out / "multi_run" / "keypoints" / "detection.json").read_text())
    log(f"\n== multi-person: {trial.name} from videos + Calib.qca.txt, {people['frames']} frames ({dt:.0f} s) ==")
    log("people per frame found by the detector: " + "; ".join(
        f"{c} {s['people_per_frame']}" for c, s in det["cameras"].items()))
    for p in people["people"]:
        log(f"  {p['person']} ({p['role']}): followed in {p['frames']} of {people['frames']} frames "
            f"({p['share']:.0%}), frames {p['first_frame']}-{p['last_frame']}, median {p['cameras_per_frame_median']:g} cameras")
    picture(trial, out / "multi_run", out / "multiperson_cameras.jpg")
    log(f"picture: {out / 'multiperson_cameras.jpg'}")


def picture(trial: Path, run_dir: Path, path: Path, frame: int = 50) -> None:
    """Each camera's frame with every person's 2D joints (the triangulated joints projected), one colour each."""
    import cv2

    from toolkit.io import VideoReader
    from toolkit.skeleton import SKELETON_14

    rig = read_calibration(trial / "calibration" / "Calib.qca.txt")
    colours = [(230, 60, 60), (60, 160, 230), (60, 200, 90), (230, 180, 40), (200, 80, 200)]
    people = json.loads((run_dir / "people.json").read_text())["people"]
    panels = []
    for cam in rig.cameras:
        with VideoReader(trial / "videos" / f"{cam.name}.mp4") as r:
            img = np.ascontiguousarray(r.read(frame))
        for k, p in enumerate(people):
            d = np.load(run_dir / p["person"] / "poses3d.npz")
            t = int(np.searchsorted(d["frames"], frame))
            J = d["joints"][t]
            if not np.isfinite(J).any():
                continue
            uv = cam.project(J)
            col = colours[k % len(colours)]
            for a, b in SKELETON_14.bones:
                if np.isfinite(uv[[a, b]]).all():
                    cv2.line(img, tuple(int(v) for v in uv[a]), tuple(int(v) for v in uv[b]), col, 8)
            top = uv[np.isfinite(uv).all(1)]
            if len(top):
                x, y = top[:, 0].mean(), top[:, 1].min() - 30
                cv2.putText(img, f"{p['person']} ({p['role']})", (int(x) - 150, int(max(y, 40))),
                            cv2.FONT_HERSHEY_SIMPLEX, 1.6, col, 4)
        cv2.putText(img, cam.name, (30, 80), cv2.FONT_HERSHEY_SIMPLEX, 2.5, (255, 255, 255), 6)
        panels.append(cv2.resize(img, (img.shape[1] // 3, img.shape[0] // 3)))
    cv2.imwrite(str(path), cv2.cvtColor(cv2.hconcat(panels), cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 85])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--realdata", type=Path,
                    default=Path(os.environ.get("TOOLKIT_REALDATA", REPO.parent / "shared" / "realdata")))
    ap.add_argument("--out", type=Path, default=None, help="keep outputs here (default: a temporary folder)")
    ap.add_argument("--parts", default="trials,sync,multi")
    ap.add_argument("--seed", default="0",
                    help="which cameras start late in the sync part, and by how much: a seed or a list (0,1,2,3)")
    args = ap.parse_args(argv)
    if not (args.realdata / DEMO).is_dir():
        print(f"real data not found under {args.realdata}; skipping (set TOOLKIT_REALDATA).")
        return 0
    parts = set(args.parts.split(","))
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        if "trials" in parts:
            bench_trials(args.realdata, out, print)
        if "sync" in parts:
            bench_sync(args.realdata, out, [int(v) for v in args.seed.split(",")], print)
        if "multi" in parts and (args.realdata / MULTI).is_dir():
            bench_multi(args.realdata, out, print)
    return 0


if __name__ == "__main__":
    sys.exit(main())
