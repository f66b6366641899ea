#!/usr/bin/env python3
"""Stage 3 of the articulated-billboard pipeline: 3D joints optimised by the billboard position score.

Usage::

    python recipes/optimize_joints.py out/default --out out/default_stage3 --poses out/default_stage1
    python recipes/optimize_joints.py DATASET --out OUT --poses STAGE1_OUT --parts STAGE2_OUT

Per frame: the source images, the body-part labels and the seams (template or
ground-truth depth) give billboard fans; each joint is moved on an adaptive
grid under anthropometric constraints until the position score converges
(source 000 §3, docs/stage3_billboards.md).  Calibration offsets of stage 1
are kept and applied.

Inputs:
  --poses STAGE1_OUT  poses3d.npz (joints (T, 14, 3)) and offsets.npz (offsets (T, n_cams, 2)) of
                      pose_from_silhouettes.py.  Without it the dataset's ground-truth joints are the
                      start (synthetic datasets only), displaced by --noise-cm.
  --parts STAGE2_OUT  parts/<camera>/NNNNNN.png part labels (1-based ids, 0 background) and, if present,
                      depth/<camera>/NNNNNN.png (uint16 mm, the fitted template's) for the seams.
                      Without it the dataset's ground-truth part labels and depth are used (said so).
Writes into OUT:
  joints3d.npz   joints (T, 14, 3) optimised, initial (T, 14, 3), scores (T, 14) final joint scores,
                 n_evaluations (T,), seconds (T,), status (T,) text, names (14,)
  metrics.json   MPJPE before/after against ground truth when the dataset has it
  recording.rrd  billboards, candidates, rejections, score curves, seams (rerun viewer)
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

from toolkit.errors import InputError


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("dataset", type=Path, help="dataset folder (docs/dataset_layout.md)")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--poses", type=Path, default=None, help="stage-1 output folder (poses3d.npz, offsets.npz)")
    ap.add_argument("--parts", type=Path, default=None, help="stage-2 output folder (parts/, depth/)")
    ap.add_argument("--noise-cm", type=float, default=0.0,
                    help="without --poses: displace the ground-truth joints by this much (cm, RMS 3D)")
    ap.add_argument("--seed", type=int, default=0, help="seed of --noise-cm")
    ap.add_argument("--max-frames", type=int, default=None, help="process only the first N frames")
    ap.add_argument("--sweeps", type=int, default=None, help="most sweeps over the joints (default 4, source 000)")
    ap.add_argument("--no-seams", action="store_true", help="no seam correction")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    args = ap.parse_args(argv)

    import numpy as np

    from toolkit.anthropometry import AnthropometricConstraints
    from toolkit.calibration import stage_rig
    from toolkit.billboards import PositionScorer, build_billboards, detect_seams
    from toolkit.io import Dataset, atomic_save_npz, atomic_write_text, frame_filename, mm_to_depth, read_png
    from toolkit.optimize import OptimizeConfig, optimize_pose
    from toolkit.skeleton import SKELETON_14

    try:
        ds = Dataset.open(args.dataset)
        rig, names = ds.rig, ds.camera_names
        n = ds.frames_to_process(args.max_frames)
        gt = ds.gt_joints3d() if ds.has_groundtruth else None
        if args.poses is not None:
            p3_file = args.poses / "poses3d.npz"
            if not p3_file.is_file():
                raise InputError(str(p3_file), "the stage-1 3D joints (pose_from_silhouettes.py --out)", "no such file")
            p3 = np.load(p3_file)
            if "joints" not in p3:
                raise InputError(str(args.poses / "poses3d.npz"), "an array 'joints' (T, 14, 3)", f"{list(p3)}")
            init = np.asarray(p3["joints"], float)
            rig = stage_rig(ds, args.poses)  # the cameras stage 1 used (refined on field lines or measured)
            offs_file = args.poses / "offsets.npz"
            from toolkit.multiview import image_offsets
            offsets = image_offsets(np.load(offs_file)["offsets"]) if offs_file.exists() else \
                np.zeros((init.shape[0], len(rig), 2))
            source = f"stage 1 ({args.poses})"
        else:
            if gt is None:
                raise InputError("--poses", "a stage-1 output folder (the dataset has no ground truth)", "none")
            rng = np.random.default_rng(args.seed)
            init = gt + rng.normal(0.0, args.noise_cm / 100.0 / np.sqrt(3.0), gt.shape)
            offsets = np.zeros((gt.shape[0], len(rig), 2))
            source = f"ground truth + {args.noise_cm:g} cm noise"
        if init.shape[1:] != (14, 3) or init.shape[0] < n:
            raise InputError("initial joints", f"(>= {n}, 14, 3)", f"shape {init.shape}")
        offsets = np.nan_to_num(offsets)
        if args.parts is None and not ds.has_groundtruth:
            raise InputError("--parts", "a stage-2 output folder (the dataset has no ground-truth parts)", "none")
        print(f"start: {source}; part labels: "
              f"{'stage 2 (' + str(args.parts) + ')' if args.parts else 'ground truth (no --parts given)'}")
        config = OptimizeConfig() if args.sweeps is None else OptimizeConfig(max_sweeps=args.sweeps)
        cons = AnthropometricConstraints()
        observer = None
        args.out.mkdir(parents=True, exist_ok=True)
        if not args.no_recording:
            from toolkit.viz import RerunObserver
            observer = RerunObserver(application_id="optimize_joints", path=args.out / "recording.rrd",
                                     camera_names=names)
            observer.report("rig", rig=rig)
            observer.report("skeleton", skeleton=SKELETON_14)
        out = np.full((n, 14, 3), np.nan)
        scores = np.full((n, 14), np.nan)
        n_eval = np.zeros(n, int)
        secs = np.zeros(n)
        status = []
        outcome = Counter()  # how the search ended per joint, summed over frames (PoseResult.outcome_counts)
        t_all = time.perf_counter()
        for t in range(n):
            J0 = init[t]
            if not np.all(np.isfinite(J0)):
                status.append("no initial joints")
                print(f"frame {t}: no initial joints, skipped")
                continue
            images = {c: ds.frame(c, t) for c in names}
            labels, depth = {}, {}
            for c in names:
                if args.parts is not None:
                    labels[c] = read_png(args.parts / "parts" / c / frame_filename(t), channels=1, dtype=np.uint8)
                    dp = args.parts / "depth" / c / frame_filename(t)
                    if dp.exists():
                        depth[c] = mm_to_depth(read_png(dp, channels=1, dtype=np.uint16))
                else:
                    labels[c] = ds.gt_parts(c, t)
                    depth[c] = ds.gt_depth(c, t)
            seams = None
            if not args.no_seams and depth:
                seams = {c: detect_seams(labels[c], depth[c], camera=c, observer=observer) for c in depth}
            if observer is not None:
                observer.report("joints3d", name="optimize/initial", joints=J0, skeleton=SKELETON_14, frame=t)
            scorer = PositionScorer(images, labels, rig, offsets[t], seams)
            res = optimize_pose(scorer, J0, cons, config, observer=observer, frame=t)
            out[t], scores[t], n_eval[t], secs[t] = res.joints, res.scores[-1], res.n_evaluations, res.seconds
            status.append("converged" if res.converged else "max sweeps")
            if observer is not None:
                build_billboards(images, labels, res.joints, rig, offsets[t], seams, frame=t, observer=observer)
            counts = res.outcome_counts()
            outcome.update(counts)
            line = (f"frame {t}: {res.n_sweeps} sweeps, {res.n_evaluations} evaluations, {res.seconds:.1f} s; "
                    "joints " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
            if gt is not None:
                b = np.linalg.norm(J0 - gt[t], axis=1).mean() * 100
                a = np.linalg.norm(res.joints - gt[t], axis=1).mean() * 100
                line += f", MPJPE {b:.1f} -> {a:.1f} cm"
            print(line, flush=True)
        atomic_save_npz(args.out / "joints3d.npz", joints=out, initial=init[:n], scores=scores, n_evaluations=n_eval,
                        seconds=secs, status=np.array(status), names=np.array(SKELETON_14.joint_names))
        if gt is not None:
            ok = np.all(np.isfinite(out), axis=(1, 2))
            before = float(np.linalg.norm(init[:n][ok] - gt[:n][ok], axis=-1).mean()) if ok.any() else None
            after = float(np.linalg.norm(out[ok] - gt[:n][ok], axis=-1).mean()) if ok.any() else None
            metrics = {"start": source, "frames": int(ok.sum()), "mpjpe_before_m": before, "mpjpe_after_m": after,
                       "evaluations_per_frame": float(n_eval[ok].mean()) if ok.any() else None,
                       "seconds_per_frame": float(secs[ok].mean()) if ok.any() else None,
                       "part_labels": "stage 2" if args.parts else "ground truth",
                       "joint_outcomes": dict(outcome)}
            atomic_write_text(args.out / "metrics.json", json.dumps(metrics, indent=2) + "\n")
            if before is not None:
                print(f"MPJPE {before * 100:.1f} -> {after * 100:.1f} cm over {int(ok.sum())} frame(s)")
        if observer is not None:
            observer.close()
        ds.close()
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"{n} frame(s) in {time.perf_counter() - t_all:.1f} s; joints: {args.out / 'joints3d.npz'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
